"""Stationary-tag acceptance study: is each motion model under 10 m on every geometry, and why not?

Issue 3 asks that on the stationary-tag case (a moored tag, an anchored boat hydrophone 32 m
away, an AUV hydrophone driving away in 50 m steps) every motion model converges with a mean
error after convergence under 10 m. :func:`stationary_trials` runs each motion setting on
scenario seeds 0, 1, ... of :func:`hmmtrack.scenarios.stationary_tag` (one trial = one
scenario seed, so the geometry changes from trial to trial) and relates each trial's error to

* the geometry: the angle at the tag between the boat and the AUV's line of travel (90-180°
  by construction; near 180° the two hydrophones are collinear with the tag and the
  position across that line is poorly observed);
* the information limit: the Cramér–Rao bound on a fixed tag's position from that trial's
  scored (range, range-rate) observations with the filter's Σ_z
  (:func:`hmmtrack.analysis.crb.static_tag_crb`; ``sqrt(trace)``, m); the error of the best
  fixed-tag fit to the same observations (:func:`hmmtrack.analysis.crb.static_tag_fit`
  started at the truth): how far the data themselves, hydrophone GPS errors included, place
  the tag; and the mirror ambiguity: the fit started at the other intersection of the two
  range circles, its distance from the tag and the χ² it costs over all observations and
  over those after the first 300 s (once the AUV is far, the two are hard to tell apart);
* the filter's honesty: the share of estimates after convergence whose 95 % ellipse (the
  filter's own x-y covariance) holds the truth (:func:`hmmtrack.analysis.metrics.ellipse_coverage`;
  0.95 for a consistent filter) and the median NEES (1.39 for a consistent filter).

Settings (:func:`settings`): the three models with :mod:`hmmtrack.tracking.motion`'s
defaults (the HMM with its resting state), the baseline with the σ it had before this study,
the HMM without the resting state, without it but with more heading diffusion, and with
other resting rates; settings of one model share each trial's filter seed.

A prior that helps a fixed tag may cost a moving one, so :func:`moving_tags` runs the HMM
settings on the moving tags of the reproduction (swimmer and shark pursuit), each trial
seeded as the reproduction's HMM trial of the same index, so that the row without the
resting state is the reproduction's HMM before it.

``hmmtrack study stationary`` writes the tables (``reports/stationary_tag.md``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack import scenarios
from hmmtrack.analysis import crb, metrics
from hmmtrack.analysis.calibration import expected_measurements
from hmmtrack.experiments.configs import tracking_config
from hmmtrack.experiments.studies import PAPER_SCENARIOS, paper_scenarios
from hmmtrack.experiments.trials import MOTIONS, child_seed, experiment_seed
from hmmtrack.tracking import pipeline as tracking
from hmmtrack.tracking.config import TrackingConfig
from hmmtrack.tracking.motion import BaselineMotion, RestingState, motion_model
from hmmtrack.tracking.receivers import ReceiverTracks

#: the baseline's random-walk spread before this study (m/√s)
PREVIOUS_BASELINE_SIGMA = 1.0
#: a heading diffusion (rad/√s) that passes the stationary tag and loses the shark pursuit
STATIONARY_HMM_HEADING_DIFFUSION = 0.4
#: the HMM as it was before the resting state
HMM_WITHOUT_RESTING = "hmm without resting (before)"
#: resting states compared with the default (``hmmtrack.tracking.motion.HMM_RESTING``)
OTHER_RESTING = (
    RestingState(enter_per_hour=0.5, leave_per_hour=1.0, drift_speed=0.05),
    RestingState(enter_per_hour=1.0, leave_per_hour=4.0, drift_speed=0.1),
)
#: the moving-tag scenarios of the reproduction, and its particle count
MOVING_SCENARIOS = ("swimmer", "shark_pursuit")
MOVING_PARTICLES = 1000
#: per-scenario columns of a trial (:func:`geometry_row`)
GEOMETRY_COLUMNS = (
    "angle_deg",
    "crb_m",
    "crb_measured_noise_m",
    "static_fit_error_m",
    "mirror_m",
    "mirror_dchi2",
    "mirror_dchi2_late",
)
#: bands of the geometry angle (degrees) of :func:`failures_by_angle`
ANGLE_BANDS = (90, 110, 120, 130, 140, 150, 160, 170, 180)


def resting_label(resting: RestingState) -> str:
    """The label of an HMM setting with ``resting``'s rates (per hour) and drift (m/s)."""
    return (
        f"hmm resting {resting.enter_per_hour:g}/{resting.leave_per_hour:g} per h, "
        f"{resting.drift_speed:g} m/s"
    )


def hmm_settings() -> dict[str, object]:
    """The HMM settings compared: label → motion model."""
    return {
        "hmm": motion_model("hmm"),
        HMM_WITHOUT_RESTING: motion_model("hmm", resting=None),
        f"hmm D={STATIONARY_HMM_HEADING_DIFFUSION:g} without resting": motion_model(
            "hmm", heading_diffusion=STATIONARY_HMM_HEADING_DIFFUSION, resting=None
        ),
        **{resting_label(rates): motion_model("hmm", resting=rates) for rates in OTHER_RESTING},
    }


def settings() -> dict[str, tuple[int, object]]:
    """Motion settings compared: label → (family, model). Settings of one family share the
    filter seed of a scenario, so that they differ by their parameters only."""
    return {
        "baseline": (0, motion_model("baseline")),
        f"baseline σ={PREVIOUS_BASELINE_SIGMA:g} (before)": (
            0,
            BaselineMotion(sigma=PREVIOUS_BASELINE_SIGMA),
        ),
        "velocity": (1, motion_model("velocity")),
        **{label: (2, motion) for label, motion in hmm_settings().items()},
    }


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
    """Geometry, bounds and the mirror ambiguity of one scenario (see the module docstring).

    Returns
    -------
    dict
        The :data:`GEOMETRY_COLUMNS`: angle (deg), √trace of the CRB with the filter's Σ_z and
        with Σ_z measured on the trial (m), the best fixed-tag fit's error (m), the mirror
        fit's distance from the tag (m) and the χ² it costs over all observations and over
        those after ``late_after`` s.
    """
    observations = tracking.build_observations(
        scenario.detections, receiver_tracks(scenario, config), config
    )
    scored = observations[observations["range_rate"].notna()]
    late = scored[scored["time"] > scenario.start + late_after]
    tag = scenario.truth[["x", "y"]].to_numpy(dtype=float)[0]
    sigma_z = config.measurement.covariance
    bound = crb.static_tag_crb(scored, *tag, sigma_z)
    fixed = pd.DataFrame({"time": [np.nan], "x": [tag[0]], "y": [tag[1]]})  # the moored tag
    residual = scored[["range", "range_rate"]].to_numpy() - expected_measurements(scored, fixed)
    crb_measured = crb.static_tag_crb(scored, *tag, np.cov(residual.T))
    fit, chi2 = crb.static_tag_fit(scored, tag, sigma_z)
    mirror, chi2_mirror = crb.static_tag_fit(scored, mirror_start(scenario, tag), sigma_z)
    _, chi2_late = crb.static_tag_fit(late, tag, sigma_z)
    _, chi2_late_mirror = crb.static_tag_fit(late, mirror_start(scenario, tag), sigma_z)
    return {
        "angle_deg": geometry_angle(scenario),
        "crb_m": float(np.sqrt(np.trace(bound))),
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
        scenario.receivers, velocity_window=config.measurement.velocity_window, outside="clamp"
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


def stationary_trials(n_seeds: int, particle_counts: Sequence[int]) -> pd.DataFrame:
    """One row per scenario seed, particle count and motion setting (:func:`settings`):
    ``seed``, the :data:`GEOMETRY_COLUMNS`, ``particles``, ``motion`` and
    :func:`filter_scores`."""
    compared = settings()
    rows = []
    for s in range(n_seeds):
        scenario = scenarios.stationary_tag(s)
        geometry = {"seed": s} | geometry_row(scenario, tracking_config(scenario, n_particles=1))
        for n in particle_counts:
            config = tracking_config(scenario, n_particles=n)
            for name, (family, motion) in compared.items():
                seed = np.random.SeedSequence(2026, spawn_key=(s, family))
                scores = filter_scores(scenario, config, motion, seed)
                rows.append(geometry | {"particles": n, "motion": name} | scores)
    return pd.DataFrame(rows)


def moving_tags(n_trials: int, seed: int = 0, n_particles: int = MOVING_PARTICLES) -> pd.DataFrame:
    """The HMM settings on the reproduction's moving tags: one row per scenario, setting and
    trial (``error``: mean error after convergence, m; ``converged``). Trial ``k`` of a
    scenario is seeded as the reproduction's HMM trial ``k``
    (``hmmtrack.experiments.compare_motion_models``) for every setting."""
    root = experiment_seed(seed)
    compared = hmm_settings()
    rows = []
    for name, scenario in paper_scenarios(seed, MOVING_SCENARIOS).items():
        cell = child_seed(root, 0, PAPER_SCENARIOS.index(name), MOTIONS.index("hmm"))
        config = tracking_config(scenario, n_particles=n_particles, shallower="clip")
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


def summary_table(table: pd.DataFrame) -> pd.DataFrame:
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


@dataclass(frozen=True)
class StationaryStudy:
    """What :func:`stationary_study` returns.

    Attributes
    ----------
    trials : pandas.DataFrame
        :func:`stationary_trials`.
    summary : pandas.DataFrame
        :func:`summary_table` of ``trials``.
    moving : pandas.DataFrame
        :func:`moving_tags`.
    moving_summary : pandas.DataFrame
        :func:`moving_summary` of ``moving``.
    moving_particles : int
        Particles of the moving-tag trials.
    """

    trials: pd.DataFrame
    summary: pd.DataFrame
    moving: pd.DataFrame
    moving_summary: pd.DataFrame
    moving_particles: int


def stationary_study(
    n_seeds: int,
    particle_counts: Sequence[int] = (1000, 5000),
    moving_trials: int = 100,
    moving_particles: int = MOVING_PARTICLES,
) -> StationaryStudy:
    """The stationary-tag trials and the HMM settings on the moving tags.

    Parameters
    ----------
    n_seeds : int
        Stationary-tag scenario seeds ``0 .. n_seeds - 1``.
    particle_counts : sequence of int
        Particle counts of the stationary-tag trials.
    moving_trials : int
        Trials per moving-tag scenario.
    moving_particles : int
        Particles of the moving-tag trials (the reproduction's: 1,000).
    """
    trials = stationary_trials(n_seeds, particle_counts)
    moving = moving_tags(moving_trials, n_particles=moving_particles)
    return StationaryStudy(
        trials=trials,
        summary=summary_table(trials),
        moving=moving,
        moving_summary=moving_summary(moving),
        moving_particles=moving_particles,
    )
