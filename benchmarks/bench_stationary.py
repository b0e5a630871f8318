"""Stationary-tag acceptance study: is each motion model under 10 m on every geometry, and why not?

Issue 3 asks that on the stationary-tag case (a moored tag, an anchored boat hydrophone 32 m
away, an AUV hydrophone driving away in 50 m steps) every motion model converges with a mean
error after convergence under 10 m. This script runs each model on ``--seeds`` scenarios
(``hmmtrack.scenarios.stationary_tag(s)`` for s = 0, 1, ...: one trial = one scenario seed,
so the geometry changes from trial to trial) and relates each trial's error to

* the geometry: the angle at the tag between the boat and the AUV's line of travel (90-180°
  by construction; near 180° the two hydrophones are collinear with the tag and the
  position across that line is poorly observed);
* the information limit: the Cramér–Rao bound on a fixed tag's position from that trial's
  scored (range, range-rate) observations with the filter's Σ_z
  (:func:`hmmtrack.analysis.metrics.static_tag_crb`; ``sqrt(trace)``, m); the error of the best
  fixed-tag fit to the same observations (:func:`hmmtrack.analysis.metrics.static_tag_fit` started
  at
  the truth): how far the data themselves, hydrophone GPS errors included, place the tag;
  and the mirror ambiguity: the fit started at the other intersection of the two range
  circles, its distance from the tag and the χ² it costs over all observations and over
  those after the first 300 s (once the AUV is far, the two are hard to tell apart);
* the filter's honesty: the share of estimates after convergence whose 95 % ellipse (the
  filter's own x-y covariance) holds the truth (:func:`hmmtrack.analysis.metrics.ellipse_coverage`;
  0.95 for a consistent filter) and the median NEES (1.39 for a consistent filter).

Settings: the three models with :mod:`hmmtrack.tracking.pipeline`'s defaults (the HMM with its
resting state, ``tracking.HMM_RESTING``), the baseline with the σ it had before this study
(1 m/√s), the HMM without the resting state (as before), without it but with heading
diffusion 0.4 rad/√s (passes a fixed tag, loses the shark pursuit), and with other resting
rates; settings of one model share each trial's filter seed. Particle counts: 1,000 (the
experiments') and 5,000 (``TrackingConfig``'s default).

A prior that helps a fixed tag may cost a moving one, so the HMM settings also run on the
moving tags of the reproduction (``hmmtrack.experiments.paper_scenarios``: swimmer and shark
pursuit, ``--moving-trials`` trials at 1,000 particles, each trial seeded as the
reproduction's HMM trial of the same index, so that the row without the resting state is
the reproduction's HMM before it).

Writes ``reports/stationary_tag.md`` (summary, moving tags, diagnosis, per-trial table),
``reports/stationary_tag.png`` (error against the bound and against the geometry angle) and
``reports/stationary_tag_trials.csv`` (every stationary-tag trial).

Run: ``python benchmarks/bench_stationary.py`` (about 5 minutes on 2 shared cores;
``--seeds 20 --moving-trials 20`` for a quick look, ``--particles 1000`` for one particle
count, ``--out`` for another folder).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from hmmtrack import scenarios  # noqa: E402
from hmmtrack.analysis import metrics
from hmmtrack.analysis.calibration import expected_measurements  # noqa: E402
from hmmtrack.experiments import (  # noqa: E402
    MOTIONS,
    PAPER_SCENARIOS,
    child_seed,
    experiment_seed,
    paper_scenarios,
)
from hmmtrack.report.markdown import markdown_table  # noqa: E402
from hmmtrack.tracking import pipeline as tracking  # noqa: E402
from hmmtrack.tracking.config import TrackingConfig  # noqa: E402
from hmmtrack.tracking.motion import BaselineMotion  # noqa: E402
from hmmtrack.tracking.receivers import ReceiverTracks  # noqa: E402

#: the baseline's random-walk spread before this study (m/√s)
PREVIOUS_BASELINE_SIGMA = 1.0
#: a heading diffusion (rad/√s) that passes the stationary tag and loses the shark pursuit
STATIONARY_HMM_HEADING_DIFFUSION = 0.4
#: the HMM as it was before the resting state
HMM_WITHOUT_RESTING = "hmm without resting (before)"
#: resting states compared with the default (``tracking.HMM_RESTING``)
OTHER_RESTING = (
    tracking.RestingState(enter_per_hour=0.5, leave_per_hour=1.0, drift_speed=0.05),
    tracking.RestingState(enter_per_hour=1.0, leave_per_hour=4.0, drift_speed=0.1),
)
#: the moving-tag scenarios of the reproduction, and its particle count
MOVING_SCENARIOS = ("swimmer", "shark_pursuit")
MOVING_PARTICLES = 1000


def resting_label(resting: tracking.RestingState) -> str:
    return (
        f"hmm resting {resting.enter_per_hour:g}/{resting.leave_per_hour:g} per h, "
        f"{resting.drift_speed:g} m/s"
    )


def hmm_settings() -> dict[str, object]:
    """The HMM settings compared: label → motion model."""
    return {
        "hmm": tracking.motion_model("hmm"),
        HMM_WITHOUT_RESTING: tracking.motion_model("hmm", resting=None),
        f"hmm D={STATIONARY_HMM_HEADING_DIFFUSION:g} without resting": tracking.motion_model(
            "hmm", heading_diffusion=STATIONARY_HMM_HEADING_DIFFUSION, resting=None
        ),
        **{
            resting_label(rates): tracking.motion_model("hmm", resting=rates)
            for rates in OTHER_RESTING
        },
    }


def settings() -> dict[str, tuple[int, object]]:
    """Motion settings compared: label → (family, model). Settings of one family share the
    filter seed of a scenario, so that they differ by their parameters only."""
    return {
        "baseline": (0, tracking.motion_model("baseline")),
        f"baseline σ={PREVIOUS_BASELINE_SIGMA:g} (before)": (
            0,
            BaselineMotion(sigma=PREVIOUS_BASELINE_SIGMA),
        ),
        "velocity": (1, tracking.motion_model("velocity")),
        **{label: (2, motion) for label, motion in hmm_settings().items()},
    }


def scenario_config(scenario, n_particles: int) -> TrackingConfig:
    """The tracking configuration of the experiments (``hmmtrack.experiments``)."""
    return scenario.tracking_config(n_particles=n_particles)


def geometry_angle(scenario) -> float:
    """Angle (degrees) at the tag between the boat and the AUV's direction of travel."""
    truth = scenario.receivers_truth
    tag = scenario.truth[["x", "y"]].to_numpy(dtype=float)[0]
    boat = truth.loc[truth["receiver"] == "boat", ["x", "y"]].to_numpy(dtype=float)[0] - tag
    auv = truth.loc[truth["receiver"] == "auv", ["x", "y"]].to_numpy(dtype=float)
    travel = auv[-1] - auv[0]
    cosine = boat @ travel / (np.linalg.norm(boat) * np.linalg.norm(travel))
    return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))


def mirror_start(scenario, tag: np.ndarray) -> np.ndarray:
    """The tag reflected across the line from the boat to the AUV's last logged position:
    the other intersection of the two range circles at the end of the run."""
    logged = scenario.receivers
    boat = logged.loc[logged["receiver"] == "boat", ["x", "y"]].to_numpy(dtype=float)[0]
    auv = logged.loc[logged["receiver"] == "auv", ["x", "y"]].to_numpy(dtype=float)[-1]
    along = (auv - boat) / np.linalg.norm(auv - boat)
    offset = tag - boat
    return boat + 2.0 * (offset @ along) * along - offset


def geometry_row(scenario, config: TrackingConfig, late_after: float = 300.0) -> dict:
    """Geometry, bounds and the mirror ambiguity of one scenario (see the module docstring)."""
    observations = tracking.build_observations(
        scenario.detections, receiver_tracks(scenario, config), config
    )
    scored = observations[observations["range_rate"].notna()]
    late = scored[scored["time"] > scenario.start + late_after]
    tag = scenario.truth[["x", "y"]].to_numpy(dtype=float)[0]
    sigma_z = config.measurement_covariance
    crb = metrics.static_tag_crb(scored, *tag, sigma_z)
    fixed = pd.DataFrame({"time": [np.nan], "x": [tag[0]], "y": [tag[1]]})  # the moored tag
    residual = scored[["range", "range_rate"]].to_numpy() - expected_measurements(scored, fixed)
    crb_measured = metrics.static_tag_crb(scored, *tag, np.cov(residual.T))
    fit, chi2 = metrics.static_tag_fit(scored, tag, sigma_z)
    mirror, chi2_mirror = metrics.static_tag_fit(scored, mirror_start(scenario, tag), sigma_z)
    _, chi2_late = metrics.static_tag_fit(late, tag, sigma_z)
    _, chi2_late_mirror = metrics.static_tag_fit(late, mirror_start(scenario, tag), sigma_z)
    return {
        "angle_deg": geometry_angle(scenario),
        "crb_m": float(np.sqrt(np.trace(crb))),
        "crb_measured_noise_m": float(np.sqrt(np.trace(crb_measured))),
        "static_fit_error_m": float(np.hypot(*(fit - tag))),
        "mirror_m": float(np.hypot(*(mirror - tag))),
        "mirror_dchi2": chi2_mirror - chi2,
        "mirror_dchi2_late": chi2_late_mirror - chi2_late,
    }


def receiver_tracks(scenario, config) -> ReceiverTracks:
    """The hydrophones' tracks; a detection logged a few ms after the AUV's last GPS fix (the
    scenario ends its tracks at its end time, seeds 53 and 61) takes the last position."""
    return ReceiverTracks.from_frame(
        scenario.receivers, velocity_window=config.velocity_window, outside="clamp"
    )


def filter_scores(scenario, config, motion, seed) -> dict:
    """Metrics of one filter run: error, convergence, honesty, and where the particles end.

    ``mirror_share``: the particles' weight at the end that lies nearer the second
    intersection of the range circles (:func:`mirror_start`) than the tag.
    """
    tracks = receiver_tracks(scenario, config)
    run = tracking.track(
        scenario.detections, tracks, config, motion, seed=seed, snapshot_times=[scenario.end]
    )
    estimates = run.estimates
    scores = metrics.tracking_metrics(estimates, scenario.truth)
    conv = metrics.time_to_convergence(estimates["time"], estimates["sqrt_lambda1"])
    after = estimates.iloc[conv.index :]
    nees = metrics.normalised_estimation_error(after, scenario.truth)
    errors = metrics.position_error(estimates, scenario.truth)
    tag = scenario.truth[["x", "y"]].to_numpy(dtype=float)[0]
    mirror = mirror_start(scenario, tag)
    cloud = run.snapshots[scenario.end]
    points = cloud[["x", "y"]].to_numpy()
    nearer = np.hypot(*(points - mirror).T) < np.hypot(*(points - tag).T)
    return {
        "error": scores.mean_error_after_convergence,
        "converged": scores.converged,
        "convergence_s": scores.time_to_convergence,
        "error_at_convergence": float(errors[conv.index]),
        "error_last_600_s": float(errors[-600:].mean()),
        "spread": float(after["sqrt_lambda1"].median()),
        "coverage": metrics.ellipse_coverage(nees),
        "median_nees": float(np.median(nees)),
        "mirror_share": float(cloud["weight"].to_numpy()[nearer].sum()),
    }


def study(n_seeds: int, particle_counts: tuple[int, ...]) -> pd.DataFrame:
    """One row per scenario seed, particle count and motion setting."""
    compared = settings()
    rows = []
    for s in range(n_seeds):
        scenario = scenarios.stationary_tag(s)
        geometry = {"seed": s} | geometry_row(scenario, scenario_config(scenario, 1))
        for n in particle_counts:
            config = scenario_config(scenario, n)
            for name, (family, motion) in compared.items():
                seed = np.random.SeedSequence(2026, spawn_key=(s, family))
                scores = filter_scores(scenario, config, motion, seed)
                rows.append(geometry | {"particles": n, "motion": name} | scores)
    return pd.DataFrame(rows)


def moving_tags(n_trials: int, seed: int = 0) -> pd.DataFrame:
    """The HMM settings on the reproduction's moving tags: one row per scenario, setting and
    trial (``error``: mean error after convergence, m; ``converged``). Trial ``k`` of a
    scenario is seeded as the reproduction's HMM trial ``k``
    (``hmmtrack.experiments.compare_motion_models``) for every setting."""
    root = experiment_seed(seed)
    compared = hmm_settings()
    rows = []
    for name, scenario in paper_scenarios(seed, MOVING_SCENARIOS).items():
        cell = child_seed(root, 0, PAPER_SCENARIOS.index(name), MOTIONS.index("hmm"))
        config = scenario.tracking_config(n_particles=MOVING_PARTICLES, shallower="clip")
        for k in range(n_trials):
            for label, motion in compared.items():
                run = tracking.track(
                    scenario.detections,
                    scenario.receivers,
                    config,
                    motion,
                    seed=child_seed(cell, k),
                )
                scores = metrics.tracking_metrics(run.estimates, scenario.truth)
                rows.append(
                    {
                        "scenario": name,
                        "motion": label,
                        "trial": k,
                        "error": scores.mean_error_after_convergence,
                        "converged": scores.converged,
                    }
                )
    return pd.DataFrame(rows)


def moving_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per moving scenario and HMM setting: mean, median, shares under 20 m and over 100 m."""
    groups = table.groupby(["scenario", "motion"], sort=False)["error"]
    return pd.DataFrame(
        {
            "trials": groups.size(),
            "mean_error_m": groups.mean(),
            "median_error_m": groups.median(),
            "under_20_m": groups.apply(lambda e: float((e < 20).mean())),
            "over_100_m": groups.apply(lambda e: float((e > 100).mean())),
        }
    )


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per motion setting: share under 10 m, mean / median / max error, honesty."""
    groups = table.groupby(["particles", "motion"], sort=False)
    return pd.DataFrame(
        {
            "trials": groups.size(),
            "converged": groups["converged"].mean(),
            "under_10_m": groups["error"].apply(lambda e: float((e < 10).mean())),
            "mean_error_m": groups["error"].mean(),
            "median_error_m": groups["error"].median(),
            "max_error_m": groups["error"].max(),
            "median_spread_m": groups["spread"].median(),
            "mean_coverage_95": groups["coverage"].mean(),
            "median_nees": groups["median_nees"].median(),
        }
    )


def plot(table: pd.DataFrame, path: Path) -> None:
    """Error after convergence against the Cramér–Rao bound and against the geometry angle,
    at the largest particle count."""
    table = table[table["particles"] == table["particles"].max()]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.4))
    for name, rows in table.groupby("motion", sort=False):
        default = name in ("baseline", "velocity", "hmm")
        style = {"s": 16 if default else 10, "alpha": 0.85 if default else 0.45}
        marker = "o" if default else "x"
        left.scatter(rows["crb_m"], rows["error"], marker=marker, label=name, **style)
        right.scatter(rows["angle_deg"], rows["error"], marker=marker, label=name, **style)
    for ax in (left, right):
        ax.axhline(10.0, color="k", lw=0.8, ls="--")
        ax.set_ylabel("mean error after convergence (m)")
        ax.set_yscale("log")
    lim = [0.3, table["error"].max() * 1.2]
    left.plot(lim, lim, color="grey", lw=0.8, label="error = bound")
    left.set_xscale("log")
    left.set_xlabel("Cramér–Rao bound, √trace, filter's Σ_z (m)")
    right.set_xlabel("angle at the tag between boat and AUV line (degrees)")
    left.legend(fontsize=7)
    fig.suptitle(
        f"Stationary tag, {table['seed'].nunique()} scenario seeds, "
        f"{table['particles'].max()} particles",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def to_markdown(frame: pd.DataFrame) -> str:
    """A pipe table of ``frame`` (index first), floats with 2 decimals."""

    def cell(value) -> str:
        if isinstance(value, tuple):
            return " ".join(map(str, value))
        return f"{value:.2f}" if isinstance(value, float) else str(value)

    values = frame.astype(object).to_numpy()  # integer columns stay integers
    rows = [[cell(i), *map(cell, row)] for i, row in zip(frame.index, values, strict=True)]
    names = frame.index.names if frame.index.nlevels > 1 else [frame.index.name]
    return markdown_table([" ".join(str(n or "") for n in names), *map(str, frame.columns)], rows)


#: bands of the geometry angle (degrees) of the failure table
ANGLE_BANDS = (90, 110, 120, 130, 140, 150, 160, 170, 180)


def failures_by_angle(table: pd.DataFrame) -> pd.DataFrame:
    """Per motion setting: trials ≥ 10 m / trials, per band of the geometry angle."""
    table = table[table["particles"] == table["particles"].max()]
    band = pd.cut(table["angle_deg"], ANGLE_BANDS, include_lowest=True)
    counts = table.assign(band=band, bad=table["error"] >= 10.0).groupby(
        ["motion", "band"], sort=False, observed=False
    )["bad"]
    cells = (counts.sum().astype(int).astype(str) + "/" + counts.size().astype(str)).unstack()
    cells.columns = [f"{c.left:.0f}-{c.right:.0f}°" for c in cells.columns]
    return cells.loc[list(settings())]


def findings(table: pd.DataFrame) -> list[str]:
    """Numbers of the bound analysis at the largest particle count (default settings)."""
    table = table[table["particles"] == table["particles"].max()]
    lines = []
    for name in ("baseline", "velocity", "hmm", HMM_WITHOUT_RESTING):
        rows = table[table["motion"] == name]
        bad = rows[rows["error"] >= 10.0]
        good = rows[(rows["error"] < 10.0) & (rows["angle_deg"] < 165.0)]
        if bad.empty:
            lines.append(f"- {name}: every trial under 10 m (max {rows['error'].max():.1f} m).")
            continue
        lines.append(
            f"- {name}: {len(bad)} of {len(rows)} trials ≥ 10 m (max {bad['error'].max():.1f} m); "
            f"their Cramér–Rao bound is at most {bad['crb_m'].max():.1f} m and their best static "
            f"fit at most {bad['static_fit_error_m'].max():.1f} m off; angles "
            f"{bad['angle_deg'].min():.0f}-{bad['angle_deg'].max():.0f}°; median Δχ² of the "
            f"mirror in the late data {bad['mirror_dchi2_late'].median():.1f} (passing trials: "
            f"{rows.loc[rows['error'] < 10, 'mirror_dchi2_late'].median():.1f}); median "
            f"share of the final particle weight nearer the second intersection than the tag "
            f"{bad['mirror_share'].median():.2f} (passing trials with the boat under 165°: "
            f"{good['mirror_share'].median():.2f}); median error when convergence is "
            f"declared {bad['error_at_convergence'].median():.1f} m (passing: "
            f"{rows.loc[rows['error'] < 10, 'error_at_convergence'].median():.1f} m) and over "
            f"the last 600 s {bad['error_last_600_s'].median():.1f} m (passing: "
            f"{rows.loc[rows['error'] < 10, 'error_last_600_s'].median():.1f} m); 95 % ellipse "
            f"coverage {bad['coverage'].mean():.2f} (passing: "
            f"{rows.loc[rows['error'] < 10, 'coverage'].mean():.2f})."
        )
    return lines


def report(
    table: pd.DataFrame, totals: pd.DataFrame, moving: pd.DataFrame, args, elapsed: float, load
) -> str:
    """The markdown report."""
    largest = table[table["particles"] == table["particles"].max()]
    wide = largest.pivot(index="seed", columns="motion", values="error")
    cover = largest.pivot(index="seed", columns="motion", values="coverage")
    share = largest.pivot(index="seed", columns="motion", values="mirror_share")
    geometry = largest.drop_duplicates("seed").set_index("seed")
    per_trial = pd.concat(
        [
            geometry[list(GEOMETRY_COLUMNS)],
            wide[list(settings())].add_prefix("error "),
            cover[["baseline", "velocity", "hmm", HMM_WITHOUT_RESTING]].add_prefix("coverage "),
            share[["hmm", HMM_WITHOUT_RESTING]].add_prefix("mirror share "),
        ],
        axis=1,
    )
    counts = " ".join(map(str, args.particles))
    resting = tracking.HMM_RESTING
    lines = [
        "# Stationary tag: accuracy, information limit and honesty of the filter",
        "",
        f"Written by `python benchmarks/bench_stationary.py --seeds {args.seeds} --particles "
        f"{counts} --moving-trials {args.moving_trials}` in {elapsed:.0f} s (load averages "
        f"{load[0]:.2f} / {load[1]:.2f} / "
        f"{load[2]:.2f} before, shared 2-core machine); every trial in "
        "`stationary_tag_trials.csv`. One trial = one scenario seed of "
        "`hmmtrack.scenarios.stationary_tag` (new geometry, GPS noise, ping jitter) and one "
        "filter seed; settings of one motion model share the filter seed. Defaults: "
        f"`hmmtrack.tracking.pipeline` (baseline σ = {tracking.BASELINE_SIGMA:g} m/√s; HMM heading "
        f"diffusion {tracking.HMM_HEADING_DIFFUSION:g} rad/√s and a resting state entered at "
        f"{resting.enter_per_hour:g} per hour, left at {resting.leave_per_hour:g} per hour, "
        f"drifting at {resting.drift_speed:g} m/s, `tracking.HMM_RESTING`); also shown: the "
        f"baseline before this study (σ = {PREVIOUS_BASELINE_SIGMA:g}), the HMM without the "
        "resting state (before), without it but with heading diffusion "
        f"{STATIONARY_HMM_HEADING_DIFFUSION:g}, and with other resting rates.",
        "",
        "## Summary per particle count and motion setting",
        "",
        "under_10_m: share of trials whose mean error after convergence is under 10 m; "
        "spread: median √λ₁ after convergence; coverage: share of estimates after "
        "convergence whose 95 % ellipse holds the truth (0.95 if the filter is consistent); "
        "median_nees: median NEES after convergence, median over trials (1.39 if consistent).",
        "",
        to_markdown(totals),
        "",
        "![error against bound and geometry](stationary_tag.png)",
        "",
        "## Moving tags (HMM settings)",
        "",
        f"The reproduction's swimmer and shark pursuit (experiment seed 0), "
        f"{moving['trial'].nunique()} trials at {MOVING_PARTICLES} particles, trial k seeded "
        "as the reproduction's HMM trial k for every setting (the row without the resting "
        "state is the reproduction's HMM before it). Errors are bimodal (the tag, or the "
        "mirror intersection tens of metres away), so the means follow the share of mirror "
        "trials: a share of p over n trials varies by about √(p(1-p)/n) (±0.05 at 100 "
        "trials) from one set of random draws to another, and adding a state changes every "
        "draw.",
        "",
        to_markdown(moving_summary(moving)),
        "",
        f"## Failing trials at {largest['particles'].max()} particles",
        "",
        *findings(table),
        "",
        "Trials ≥ 10 m / trials, by the angle at the tag between the boat and the AUV's line:",
        "",
        to_markdown(failures_by_angle(table)),
        "",
        *DIAGNOSIS,
        "",
        "## Per-trial table",
        "",
        f"At {largest['particles'].max()} particles. angle: at the tag, between the boat and "
        "the AUV's line (°); crb: √trace of the Cramér–Rao bound with the filter's Σ_z (m), "
        "and with Σ_z measured on that trial; static fit: error of the best fixed-tag "
        "least-squares fit to all observations (m); mirror: distance from the tag to the "
        "least-squares fit started at the other intersection of the range circles (equal to "
        "static fit when that start slides back to the tag), and the χ² it costs over all "
        "observations and over those after the first 300 s (filter's Σ_z); error: mean error "
        "after convergence (m); coverage: as above; mirror share: the HMM's particle weight at "
        "the end nearer the second intersection than the tag (about 0.5 whatever happens "
        "when the two nearly coincide, near 180°).",
        "",
        to_markdown(per_trial),
        "",
    ]
    return "\n".join(lines)


#: what the tables show (the numbers above are recomputed by every run; this reading of them
#: is the study's, checked on 100 seeds at 1,000 and 5,000 particles)
DIAGNOSIS = (
    "## Diagnosis",
    "",
    "- **Not an information limit.** The failing trials have a Cramér–Rao bound of about 1 m "
    "(filter's Σ_z; a few tenths of a metre with the measured noise) and their own data "
    "place the tag within a few metres (best fixed-tag fit, which includes the bias of the "
    "boat's single GPS fix). Only near 180° (boat, tag and AUV line collinear) does the bound "
    "grow (to 5-17 m), and there every model does well, because the second intersection of "
    "the range circles is then too close to matter.",
    "- **Geometry band 130-160°.** Failures concentrate where the second intersection of "
    "the two range circles lies 20-50 m from the tag and the detections after the first "
    "300 s barely tell it apart (small mirror Δχ² late). Only the first minutes, with the "
    "AUV close, resolve it. A prior that lets the tag wander tens of metres in a few minutes "
    "forgets them: the cloud spreads along the boat's range circle towards the second "
    "intersection and its weighted mean falls between the two, inside the circle (checked "
    "on particle snapshots: particles on the 32 m circle, their mean 3-5 m inside it; in "
    "the failing trials a third to a half of the final weight lies nearer the second "
    "intersection, in the passing ones almost none).",
    "- **Mostly not premature convergence.** When convergence is declared (√λ₁ first below "
    "10 m) the failing trials are somewhat further off than the passing ones but under "
    "10 m; most of their error comes later (error over the last 600 s above: 13-16 m "
    "against 2-4 m), as the early information is forgotten.",
    "- **Baseline: fixed.** σ = 1 m/√s let the cloud wander (median spread 7.6 m); "
    "σ = 0.3 m/√s (`hmmtrack.tracking.pipeline.BASELINE_SIGMA`) keeps the early information: "
    "98 % of "
    "the trials under 10 m at 5,000 particles, 93 % at 1,000, against about 70 % before. "
    "The baseline stays lost on the moving tags, as in the paper.",
    "- **Velocity: robust.** Its speed settles near 0 under the range-rates, so it keeps "
    "the early information: every trial under 10 m. It is sometimes overconfident "
    "(coverage below 0.5 on some trials): its spread (about 2 m) is smaller than the bias "
    "the boat's GPS error puts in the data (best fit a few metres off), which Σ_z does "
    "not model.",
    "- **HMM without a resting state: the prior's limit.** The white-shark model always "
    "swims (0.36 or 1.05 m/s for 60 s at a time), so its posterior for a fixed tag is "
    "10-25 m wide and, in the geometry band, covers both intersections: about 60 % of the "
    "trials under 10 m, errors up to about 30 m at 5,000 particles (60 m at 1,000, when the "
    "cloud settles on the second intersection), but coverage near 1 (wide, not "
    "overconfident). More heading diffusion makes the cloud less ballistic and fixes the "
    "fixed tag (0.4 rad/√s: 90 %) but costs the shark pursuit (table above: fewer trials "
    "under 20 m, median error about 70 m against 10 m).",
    "- **HMM with a resting state: fixed at 5,000 particles.** A tag can be at rest (shed, "
    "dead animal, resting on the bottom) although the fitted animal always swims, so "
    "tracking adds a third behavioural state (`MovementHMM.with_resting_state`, "
    "`tracking.HMM_RESTING`): entered at 0.5 per hour from either swimming state, left at 2 "
    "per hour into them (20 % of the particles under the prior), steps of 3 m per 60 s in "
    "any direction (0.05 m/s). On the fixed tag the resting particles near the tag outweigh "
    "the swimmers and keep the early information, as the slow baseline does: 98 % of the "
    "trials under 10 m at 5,000 particles (62 % without), spread about 2.5 m, coverage "
    "0.96; 84 % at 1,000 (64 % without; baseline 93 %, velocity 100 %). The price is "
    "honesty on the failures: the cloud is now tight, and when it settles on the second "
    "intersection (6 of 100 trials at 1,000 particles, 1 at 5,000: mean error 26-60 m, "
    "nearly all the final weight nearer the mirror) its 95 % ellipse misses the tag "
    "(coverage near 0), where the wide swimming-only cloud kept coverage near 1. The "
    "drift matters: with steps of exactly 0 (checked at 0.5 / 1 per hour with a relaxed "
    "`zero_mass` = 1, not kept) resampled copies of one resting particle pile up on a "
    "single point (spread 0.6 m, 95 % ellipse coverage 0.21, NEES undefined) and 96 % / "
    "69 % of the trials are under 10 m at 5,000 / 1,000 particles. On the moving tags the "
    "resting particles fall behind and are resampled away: at 0.5 / 2 per hour the shares "
    "under 20 m and over 100 m stay within the trial-to-trial noise of the HMM without it "
    "(table above; over 200 trials at 1,000 particles 0.66 against 0.70 under 20 m on the "
    "swimmer, 0.51 against 0.53 on the shark pursuit; at 5,000 particles, 100 swimmer "
    "trials: 0.96 against 0.95 under 20 m, 2 against 0 over 100 m; 40 shark-pursuit "
    "trials: 0.60 against 0.65), though every resting setting measured lies a little "
    "below; a larger resting share (0.5 / 1 per hour: 33 %) costs the swimmer about 0.1 "
    "of its trials under 20 m. Faster turnover with more drift (1 / 4 per hour, 0.1 m/s) is "
    "more honest on the fixed tag (fewer confidently wrong trials) and does better at "
    "1,000 particles, but lies a little lower on the moving tags.",
)

#: per-scenario columns of the per-trial table
GEOMETRY_COLUMNS = (
    "angle_deg",
    "crb_m",
    "crb_measured_noise_m",
    "static_fit_error_m",
    "mirror_m",
    "mirror_dchi2",
    "mirror_dchi2_late",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100, help="scenario seeds 0..n-1")
    parser.add_argument("--particles", type=int, nargs="+", default=[1000, 5000])
    parser.add_argument(
        "--moving-trials", type=int, default=100, help="trials per moving-tag scenario"
    )
    parser.add_argument("--out", type=Path, default=Path(__file__).parents[1] / "reports")
    args = parser.parse_args()
    load = os.getloadavg()
    clock = time.perf_counter()
    table = study(args.seeds, tuple(args.particles))
    moving = moving_tags(args.moving_trials)
    elapsed = time.perf_counter() - clock
    totals = summary(table)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(totals.round(3))
        print(moving_summary(moving).round(3))
    print(f"{elapsed:.1f} s, load before {load}, after {os.getloadavg()}")
    args.out.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out / "stationary_tag_trials.csv", index=False)
    plot(table, args.out / "stationary_tag.png")
    (args.out / "stationary_tag.md").write_text(report(table, totals, moving, args, elapsed, load))


if __name__ == "__main__":
    main()
