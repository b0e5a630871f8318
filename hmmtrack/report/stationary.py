"""The stationary-tag report (``reports/stationary_tag.md``): accuracy, information limit, honesty.

:func:`write_stationary` runs :func:`hmmtrack.experiments.stationary.stationary_study`,
writes every trial (``stationary_tag_trials.csv``), the figure
(:func:`hmmtrack.plots.studies.stationary_errors`, ``stationary_tag.png``) and the report.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

from hmmtrack.experiments.stationary import (
    GEOMETRY_COLUMNS,
    HMM_WITHOUT_RESTING,
    MOVING_PARTICLES,
    PREVIOUS_BASELINE_SIGMA,
    STATIONARY_HMM_HEADING_DIFFUSION,
    StationaryStudy,
    failures_by_angle,
    settings,
    stationary_study,
)
from hmmtrack.io.outputs import atomic_files
from hmmtrack.plots.studies import stationary_errors
from hmmtrack.report.markdown import indexed_markdown
from hmmtrack.report.studies import provenance, run_timed
from hmmtrack.tracking.motion import BASELINE_SIGMA, HMM_HEADING_DIFFUSION, HMM_RESTING

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
    "σ = 0.3 m/√s (`hmmtrack.tracking.motion.BASELINE_SIGMA`) keeps the early information: "
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
    "`hmmtrack.tracking.motion.HMM_RESTING`): entered at 0.5 per hour from either swimming "
    "state, left at 2 "
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


def findings(table: pd.DataFrame) -> list[str]:
    """The failing trials of the default settings at the largest particle count, in words:
    their bound, static fit, angles, mirror evidence, error at convergence and coverage."""
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


def stationary_markdown(study: StationaryStudy, written_by: str) -> str:
    """The report's Markdown: ``written_by`` (the provenance line), the summary, the moving
    tags, the failing trials, the diagnosis and the per-trial table."""
    table, totals, moving = study.trials, study.summary, study.moving
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
    resting = HMM_RESTING
    lines = [
        "# Stationary tag: accuracy, information limit and honesty of the filter",
        "",
        f"{written_by} on a shared machine; every trial in "
        "`stationary_tag_trials.csv`. One trial = one scenario seed of "
        "`hmmtrack.scenarios.stationary_tag` (new geometry, GPS noise, ping jitter) and one "
        "filter seed; settings of one motion model share the filter seed. Defaults: "
        f"`hmmtrack.tracking.motion` (baseline σ = {BASELINE_SIGMA:g} m/√s; HMM heading "
        f"diffusion {HMM_HEADING_DIFFUSION:g} rad/√s and a resting state entered at "
        f"{resting.enter_per_hour:g} per hour, left at {resting.leave_per_hour:g} per hour, "
        f"drifting at {resting.drift_speed:g} m/s, `hmmtrack.tracking.motion.HMM_RESTING`); "
        "also shown: the "
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
        indexed_markdown(totals),
        "",
        "![error against bound and geometry](stationary_tag.png)",
        "",
        "## Moving tags (HMM settings)",
        "",
        f"The reproduction's swimmer and shark pursuit (experiment seed 0), "
        f"{moving['trial'].nunique()} trials at {study.moving_particles} particles, trial k seeded "
        "as the reproduction's HMM trial k for every setting (the row without the resting "
        "state is the reproduction's HMM before it). Errors are bimodal (the tag, or the "
        "mirror intersection tens of metres away), so the means follow the share of mirror "
        "trials: a share of p over n trials varies by about √(p(1-p)/n) (±0.05 at 100 "
        "trials) from one set of random draws to another, and adding a state changes every "
        "draw.",
        "",
        indexed_markdown(study.moving_summary),
        "",
        f"## Failing trials at {largest['particles'].max()} particles",
        "",
        *findings(table),
        "",
        "Trials ≥ 10 m / trials, by the angle at the tag between the boat and the AUV's line:",
        "",
        indexed_markdown(failures_by_angle(table)),
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
        indexed_markdown(per_trial),
        "",
    ]
    return "\n".join(lines)


def write_stationary(
    out: Path | str,
    *,
    seeds: int = 100,
    particles: tuple[int, ...] = (1000, 5000),
    moving_trials: int = 100,
    moving_particles: int = MOVING_PARTICLES,
) -> Path:
    """Run the stationary-tag study and write its report, figure and trial table into ``out``.

    Parameters
    ----------
    out : path
        Folder (created if missing).
    seeds : int
        Stationary-tag scenario seeds ``0 .. seeds - 1``.
    particles : tuple of int
        Particle counts of the stationary-tag trials.
    moving_trials : int
        Trials per moving-tag scenario.
    moving_particles : int
        Particles of the moving-tag trials.

    Returns
    -------
    pathlib.Path
        ``out/stationary_tag.md``.
    """
    out = Path(out)
    study, seconds, load = run_timed(
        stationary_study, seeds, particles, moving_trials, moving_particles
    )
    command = (
        f"hmmtrack study stationary --seeds {seeds} --particles "
        f"{' '.join(map(str, particles))} --moving-trials {moving_trials}"
        + (
            ""
            if moving_particles == MOVING_PARTICLES
            else f" --moving-particles {moving_particles}"
        )
    )
    out.mkdir(parents=True, exist_ok=True)
    path = out / "stationary_tag.md"
    files = (path, out / "stationary_tag_trials.csv", out / "stationary_tag.png")
    with atomic_files(*files) as (markdown, trials, figure):
        study.trials.to_csv(trials, index=False)
        left, _ = stationary_errors(study.trials)
        left.figure.tight_layout()
        left.figure.savefig(figure, dpi=110)
        plt.close(left.figure)
        markdown.write_text(stationary_markdown(study, provenance(command, seconds, load)))
    return path
