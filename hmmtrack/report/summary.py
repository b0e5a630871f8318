"""``summary.md``: our results beside the paper's, the findings, and the figures.

:func:`write_summary` formats tables computed by :mod:`hmmtrack.experiments`; it runs and
draws nothing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from hmmtrack.experiments import (
    HMM_VARIANT,
    LOSS_BANDS,
    MOSTLY_OUTSIDE,
    MOTIONS,
    calibration_spread,
    dataset_spread,
    loss_bands,
    summarise_trials,
)
from hmmtrack.report.findings import DIVERGED_ERROR, check_findings, share_above
from hmmtrack.report.markdown import fmt, markdown_table, paper_number
from hmmtrack.report.paper import PAPER, dataset_name
from hmmtrack.scenarios.white_shark_hmm import load_white_shark_hmm


def _comparison_section(comparison: pd.DataFrame) -> str:
    summary = summarise_trials(comparison)
    rows = []
    for _, cell in summary.iterrows():
        scenario, motion = cell["scenario"], cell["motion"]
        paper_error = PAPER["error"].get(scenario, {}).get(motion, math.nan)
        paper_tc = PAPER["convergence"].get(scenario, {}).get(motion, math.nan)
        rows.append(
            [
                dataset_name(scenario),
                motion,
                fmt(cell["mean_error_after_convergence"]),
                paper_number(paper_error),
                fmt(cell["median_error_after_convergence"]),
                fmt(cell["rmse_after_convergence"]),
                fmt(cell["time_to_convergence"]),
                paper_number(paper_tc),
                f"{int(cell['n_converged'])}/{int(cell['n_trials'])}",
                _percent(cell.get("calibration", math.nan)),
                fmt(cell.get("region_scale", math.nan), 2),
                _percent(cell.get("false_converged", math.nan)),
                _percent(cell.get("mirror_share", math.nan)),
            ]
        )
    headers = [
        "dataset",
        "motion model",
        "mean error after conv. (m)",
        "paper (m)",
        "median (m)",
        "true RMSE after conv. (m)",
        "time to conv. (s)",
        "paper (s)",
        "converged",
        "truth in 95 % region",
        "region's scale",
        "false converged",
        "on the mirror",
    ]
    return (
        "## Motion-model comparison\n\n"
        'Per trial: the paper\'s "RMSE" (the *mean* position error from convergence to the '
        "end), the true root-mean-square error over the same span, and the time until "
        "√λ₁ < 10 m. Table: means over trials (time to convergence over converged trials; "
        "a trial that never converges is scored over its whole run, as the paper does). "
        "Honesty of the stated uncertainty: the share of seconds after convergence whose "
        "95 % ellipse (of the cloud's mean and covariance) holds the truth, 95 % for a "
        "calibrated filter; the region's scale, the median over trials of the factor by "
        "which those ellipses would have to be scaled to hold the truth in exactly 95 % of "
        "the seconds (1 calibrated, 0.5 twice as wide as the errors need, "
        "`hmmtrack.analysis.metrics.region_scale`); and the share of seconds declared "
        "converged while more than "
        "50 m off (`hmmtrack.analysis.metrics.uncertainty_metrics`; convergence by "
        "the estimates' `converged` column when the filter reports modes). On the mirror: "
        "the share of seconds after convergence nearer the mirror track (the truth "
        "reflected across the line of the two receivers, which has the same ranges and "
        "range-rates; `hmmtrack.analysis.mirror`) than the truth.\n\n"
        + markdown_table(headers, rows)
        + "\n"
    )


def _percent(share: float, decimals: int = 0) -> str:
    """A share as a percentage with ``decimals`` decimals (a whole one by default), or a dash
    when unknown."""
    return "–" if not math.isfinite(share) else f"{100 * share:.{decimals}f} %"


def _spread_section(comparison: pd.DataFrame) -> str:
    """Spread of the error after convergence between datasets and between filter runs."""
    spread = dataset_spread(comparison)
    if not (spread["n_datasets"] > 1).any():
        return ""
    rows = [
        [
            dataset_name(cell["scenario"]),
            cell["motion"],
            f"{int(cell['n_datasets'])} × {int(cell['runs_per_dataset'])}",
            fmt(cell["mean"]),
            fmt(cell["between_datasets"]),
            fmt(cell["between_runs"]),
            fmt(cell["worst_dataset"]),
            _percent(cell["share_above_100m"]),
        ]
        for _, cell in spread.iterrows()
    ]
    headers = [
        "dataset",
        "motion model",
        "datasets × runs",
        "mean error after conv. (m)",
        "sd between datasets (m)",
        "sd between runs (m)",
        "worst dataset (m)",
        "trials > 100 m",
    ]
    return (
        "## Spread between datasets and between filter runs\n\n"
        "Each scenario is drawn as several synthetic datasets and each dataset is tracked "
        "several times. The standard deviation of the datasets' mean errors says how much "
        "a conclusion depends on the one dataset the paper had; the root mean within-dataset "
        "variance says how much the filter's own randomness moves a result.\n\n"
        + markdown_table(headers, rows)
        + "\n"
    )


def _calibration_section(comparison: pd.DataFrame) -> str:
    """Each cell's share of seconds inside the 95 % region, made up of its datasets."""
    if "calibration" not in comparison.columns:
        return ""
    cells = calibration_spread(comparison)
    if not (cells["n_datasets"] > 1).any():
        return ""
    rows = [
        [
            dataset_name(cell["scenario"]),
            cell["motion"],
            str(int(cell["n_datasets"])),
            _percent(cell["share"], 1),
            _percent(cell["between_datasets"], 1),
            str(int(cell["all_inside"])),
            str(int(cell["mostly_outside"])),
        ]
        for _, cell in cells.iterrows()
    ]
    headers = [
        "dataset",
        "motion model",
        "datasets",
        "truth in 95 % region",
        "sd between datasets",
        "datasets all inside",
        f"datasets under {100 * MOSTLY_OUTSIDE:.0f} %",
    ]
    return (
        "## What the calibration figures rest on\n\n"
        "A run's seconds are not independent draws: a dataset's fixed errors (a moored "
        "receiver's single GPS fix, the geometry) move all of them together, so a dataset "
        "is mostly inside its regions or mostly not, and a cell's share rests on the few "
        f"datasets that are not. With {int(cells['n_datasets'].max())} datasets a calibrated "
        "cell's share moves by a point or more from one experiment seed to the next "
        '(reports/decisions.md, "Long Beach too wide under the gps option" and "The '
        "reproduction's design\"; `hmmtrack.experiments.calibration_spread`).\n\n"
        + markdown_table(headers, rows)
        + "\n"
    )


def _loss_section(loss: pd.DataFrame) -> str:
    ours, paper = loss_bands(loss), PAPER["loss_bands"]
    rows = [
        [
            band,
            f"{int(ours.loc[band, 'n_converged'])}/{int(ours.loc[band, 'n_trials'])}",
            *(
                f"{fmt(ours.loc[band, c])} ({paper_number(paper.loc[band, c])})"
                for c in paper.columns
            ),
        ]
        for band in LOSS_BANDS
    ]
    fractions = np.unique(loss["loss_fraction"])
    per_fraction = len(loss) // max(len(fractions), 1)
    return (
        "## Measurement loss (shark pursuit, HMM model)\n\n"
        f"Detections thinned evenly at {len(fractions)} fractions from "
        f"{100 * fractions.min():.0f} % to {100 * fractions.max():.0f} % dropped, "
        f"{per_fraction} trials each. Ours (paper); statistics over converged trials.\n\n"
        + markdown_table(
            [
                "band dropped",
                "converged",
                "mean conv. (s)",
                "max conv. (s)",
                "mean error (m)",
                "max error (m)",
            ],
            rows,
        )
        + "\n"
    )


def _depth_section(depth) -> str:
    paper = PAPER["depth_percent_error"]
    ours = dict(zip(depth.ranges, depth.percent_error, strict=True))
    rows = [[f"{r:g}", f"{ours.get(r, math.nan):.2f}", paper_number(p)] for r, p in paper.items()]
    text = (
        "## Depth\n\n"
        f"Percent error of taking a slant range as horizontal, tag at {depth.depth:g} m:\n\n"
        + markdown_table(["range (m)", "ours (%)", "paper (%)"], rows)
        + "\n"
    )
    if depth.trials is not None and len(depth.trials):
        summary = summarise_trials(depth.trials, by=("depth_correction",))
        rows = [
            [
                "with" if c["depth_correction"] else "without",
                fmt(c["mean_error_after_convergence"]),
                fmt(c["rmse_after_convergence"]),
                fmt(c["time_to_convergence"]),
                f"{int(c['n_converged'])}/{int(c['n_trials'])}",
            ]
            for _, c in summary.iterrows()
        ]
        text += (
            f"\nDiving shark (max depth {depth.max_depth:.0f} m, depth-sensor tag), HMM "
            "model, with and without the depth correction (not in the paper, which only "
            "argues the correction):\n\n"
            + markdown_table(
                [
                    "depth correction",
                    "mean error after conv. (m)",
                    "true RMSE (m)",
                    "time to conv. (s)",
                    "converged",
                ],
                rows,
            )
            + "\n"
        )
    return text


def _swimmer_errors(comparison: pd.DataFrame) -> str:
    """A sentence with this run's swimmer mean errors of the velocity and HMM models, or
    nothing when the run has no such trials."""
    rows = summarise_trials(comparison).set_index(["scenario", "motion"])
    if not {("swimmer", "velocity"), ("swimmer", "hmm")} <= set(rows.index):
        return ""
    error = rows["mean_error_after_convergence"]
    return (
        " On this run's swimmer the mean error after convergence is "
        f"{fmt(error['swimmer', 'velocity'])} m with the velocity model and "
        f"{fmt(error['swimmer', 'hmm'])} m with the HMM."
    )


def _differences_section(comparison: pd.DataFrame) -> str:
    """Why our numbers differ from the paper's: the causes we know, with our evidence."""
    shares = share_above(comparison)
    motions = [m for m in MOTIONS if m in set(comparison["motion"])]
    rows = [
        [dataset_name(name)] + [f"{100 * shares.get((name, m), math.nan):.0f} %" for m in motions]
        for name in pd.unique(comparison["scenario"])
    ]
    model = load_white_shark_hmm()
    speeds = model.step.expected_value() / model.dt
    known_start = "start_prior" in comparison and bool(comparison["start_prior"].any())
    start = (
        "Where a run starts decides which branch it follows: these runs start where the field "
        "team knew the tag to be at the start (the swimmer's and the shark pursuit's "
        "`start_region`, `--start-prior`), which holds the tag and not its mirror. The paper's "
        "uninformed start (`--filter paper --no-start-prior`) follows the mirror in about a "
        "third of the seconds on those two scenarios, at every experiment seed "
        "(`reports/decisions.md`, issue 13)."
        if known_start
        else "Where a run starts decides which branch it follows: these runs start anywhere "
        "in the search box, as the paper's do, so a share of them follow the mirror for the "
        "whole run; starting where the field team knew the tag to be (`--start-prior`) "
        "removes it (`reports/decisions.md`, issue 13)."
    )
    return (
        "## Where and why our numbers differ from the paper's\n\n"
        "- **Different data.** Our datasets imitate the paper's setups, not its recordings: "
        "geometry, noise, ping loss and the tag's path are ours, so the numbers can only "
        "agree in kind.\n"
        "- **Mirror solutions.** Two range circles meet at two points: the tag and its "
        "reflection across the line of the two receivers, which has the same ranges and "
        "range-rates at every instant (`hmmtrack.analysis.mirror`), so no measurement tells "
        "them apart. A trial that converges on the mirror point (or loses the tag) scores "
        "tens to hundreds of metres, so the histograms are multi-modal, as the paper's are, "
        "and the *means* above are governed by the share of such trials; the medians give "
        f"the typical trial. {start} Share of trials with an error after convergence above "
        f"{DIVERGED_ERROR:g} m:\n\n" + markdown_table(["dataset", *motions], rows) + "\n\n"
        "- **The white-shark HMM never stands still; the tracker adds a resting state.** The "
        f"bundled model (fitted to our synthetic tracks on a {model.dt:g} s grid) has mean "
        "speeds "
        + " and ".join(f"{v:.2f} m/s" for v in speeds)
        + " in its two states, so on its own its particles keep wandering around a "
        "stationary tag. Tracking adds a resting state to it "
        "(`hmmtrack.tracking.motion.HMM_RESTING`: "
        "a tag may be shed, its animal dead or resting), which takes the posterior on the "
        "stationary tag and costs the moving tags little (`reports/stationary_tag.md`). The "
        "paper's model, fitted to real sharks, may well be slower in its resident state.\n"
        f"- **HMM time step.** The model describes {model.dt:g} s steps and the filter "
        f"predicts every second; we run it in the `{HMM_VARIANT}` variant of "
        "`hmmtrack.tracking.motion.HMMMotion`: behaviour switches with the transition matrix's "
        f"root for 1 s, speed and turn rate are held for {model.dt:g} s (staggered across "
        "particles), and headings diffuse a little "
        "(`hmmtrack.tracking.motion.HMM_HEADING_DIFFUSION`) "
        "so that resampled copies do not move as one block. Under the `range-rate-gps` "
        "measurement the resting tag holds still and the held speeds take a log random walk "
        "(`hmmtrack.tracking.config.MEASUREMENT_MOTIONS`): that measurement's regions are "
        "narrow enough to show a cloud that keeps only a few distinct speeds. Redrawing the "
        f"{model.dt:g} s model every second (the `paper` variant, which divides turning "
        "angles by the time step and so under-disperses headings) drifts off a stationary "
        "tag and loses the shark on our analogue.\n"
        "- **The velocity model under `range-rate-gps`.** That measurement's regions showed "
        "the paper's speed walk too wide on the swimmer and along the AUV's line of sight on "
        "the stationary tag, so there the velocity model takes a smaller speed walk with "
        "sudden speed jumps and a still regime as sticky as the HMM's resting state "
        "(`hmmtrack.tracking.motion.VELOCITY_GPS`); the paper's `range-rate` measurement keeps "
        f"the paper's model.{_swimmer_errors(comparison)} The finding above on the swimmer "
        "compares the two dataset by dataset "
        '(reports/decisions.md, "A sticky still regime for the velocity model").\n'
        "- **Unstated settings.** The paper gives no particle count, random-walk or velocity "
        "noise levels or measurement covariance; we use the run's particle count above and "
        "the defaults of `hmmtrack.tracking.motion` and "
        "`hmmtrack.tracking.config.TrackingConfig`.\n"
    )


def write_summary(
    path: str | Path,
    *,
    comparison: pd.DataFrame | None = None,
    loss: pd.DataFrame | None = None,
    depth=None,
    figures: Mapping[str, str] | None = None,
    run: Mapping[str, object] | None = None,
) -> Path:
    """Write the reproduction summary as Markdown.

    Parameters
    ----------
    path : str or Path
        Output file (``reports/summary.md``); its folder is created.
    comparison, loss : pandas.DataFrame, optional
        Trials tables of :func:`hmmtrack.experiments.compare_motion_models` and
        :func:`hmmtrack.experiments.loss_sweep`.
    depth : hmmtrack.experiments.DepthAnalysis, optional
    figures : mapping of caption to file name, optional
        PNGs beside the summary, embedded in this order.
    run : mapping, optional
        Run parameters (seed, trials, particles, executor, wall time...), listed verbatim.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    parts = [
        "# hmmtrack: reproduction of the paper's results\n",
        "**The datasets are synthetic analogues, not the paper's data.** The Long Beach, "
        "Santa Elena Bay and white-shark field data are not public; `hmmtrack.scenarios` "
        "simulates datasets shaped like them (a stationary tag with one hydrophone on an AUV "
        "stepping away; a swimmer-carried tag between two drifting boats; a 150-min shark "
        "pursuit by two hydrophones with distance-dependent ping loss) and the white-shark "
        "HMM is fitted to synthetic tracks. Agreement is expected in kind, not digit for "
        "digit.\n",
    ]
    if run:
        parts.append("Run: " + "; ".join(f"{k} = {v}" for k, v in run.items()) + ".\n")
    findings = check_findings(comparison, loss, None if depth is None else depth.trials)
    verdict = {True: "holds", False: "does not hold", None: "undecided by the trials"}
    parts.append(
        "## The paper's findings on our analogues\n\n"
        + "\n".join(f"- **{verdict[f.holds]}** — {f.claim} ({f.evidence})" for f in findings)
        + "\n"
    )
    if comparison is not None and len(comparison):
        parts.append(_comparison_section(comparison))
        if spread := _spread_section(comparison):
            parts.append(spread)
        if calibration := _calibration_section(comparison):
            parts.append(calibration)
        parts.append(_differences_section(comparison))
    if loss is not None and len(loss):
        parts.append(_loss_section(loss))
    if depth is not None:
        parts.append(_depth_section(depth))
    if figures:
        parts.append(
            "## Figures\n\n"
            + "\n\n".join(
                f"**{caption}**\n\n![{caption}]({name})" for caption, name in figures.items()
            )
            + "\n"
        )
    path.write_text("\n".join(parts))
    return path
