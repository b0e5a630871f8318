"""The paper's qualitative findings, each tested on our trial tables.

:func:`check_findings` returns one :class:`Finding` per claim (shark pursuit: the HMM model
has the lowest error and the baseline diverges; the filter stays usable up to 80 % loss and
degrades sharply above; the depth correction helps a diving shark) with the numbers the
verdict rests on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from hmmtrack.experiments import LOSS_BANDS, MOTIONS, loss_bands, summarise_trials
from hmmtrack.report.markdown import fmt

#: an error after convergence above this is "diverged" (m): ten convergence thresholds
DIVERGED_ERROR = 100.0


@dataclass(frozen=True)
class Finding:
    """One of the paper's qualitative claims, tested on our results.

    Attributes
    ----------
    claim : str
        The claim, in the paper's words.
    holds : bool or None
        Whether our results support it; ``None`` when the data to test it are missing.
    evidence : str
        The numbers the verdict rests on.
    """

    claim: str
    holds: bool | None
    evidence: str


def _cell(summary: pd.DataFrame, scenario: str, motion: str) -> pd.Series | None:
    rows = summary[(summary["scenario"] == scenario) & (summary["motion"] == motion)]
    return None if rows.empty else rows.iloc[0]


def check_findings(
    comparison: pd.DataFrame | None,
    loss: pd.DataFrame | None,
    depth_trials: pd.DataFrame | None = None,
) -> list[Finding]:
    """Test the paper's qualitative findings on our trials tables.

    Parameters
    ----------
    comparison : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.compare_motion_models`.
    loss : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.loss_sweep`.
    depth_trials : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.depth_analysis` (``depth_correction`` column).

    Returns
    -------
    list of Finding
        Shark pursuit: the HMM model has the lowest error; the baseline diverges (mean error
        after convergence above :data:`DIVERGED_ERROR`); loss: usable up to 80 % (the
        20–80 % band converges in at least 90 % of trials with a mean error below
        :data:`DIVERGED_ERROR`) and robust below 20 %; depth: the correction lowers the
        error on a diving shark.
    """
    findings = []
    summary = None if comparison is None else summarise_trials(comparison)
    cells = {} if summary is None else {m: _cell(summary, "shark-pursuit", m) for m in MOTIONS}
    if all(c is not None for c in cells.values()) and cells:
        errors = {m: float(c["mean_error_after_convergence"]) for m, c in cells.items()}
        evidence = ", ".join(f"{m} {fmt(e)} m" for m, e in errors.items())
        findings.append(
            Finding(
                "Shark pursuit: the HMM motion model has the lowest error after convergence.",
                min(errors, key=errors.get) == "hmm",
                f"mean error after convergence: {evidence}",
            )
        )
        shark = comparison[comparison["scenario"] == "shark-pursuit"]
        share = {
            m: float(np.mean(g["mean_error_after_convergence"] > DIVERGED_ERROR))
            for m, g in shark.groupby("motion")
        }
        findings.append(
            Finding(
                "Shark pursuit: the baseline (random-walk) model diverges.",
                errors["baseline"] > DIVERGED_ERROR and errors["baseline"] > 5 * errors["hmm"],
                f"baseline mean error {fmt(errors['baseline'])} m vs HMM {fmt(errors['hmm'])} m; "
                "share of trials with error above "
                f"{DIVERGED_ERROR:g} m: "
                + ", ".join(f"{m} {100 * share.get(m, math.nan):.0f} %" for m in MOTIONS),
            )
        )
    else:
        findings.append(
            Finding(
                "Shark pursuit: HMM lowest error, baseline diverges.",
                None,
                "no shark-pursuit trials of all three models",
            )
        )
    if loss is not None and len(loss):
        bands = loss_bands(loss)
        mid = bands.loc[LOSS_BANDS[1]]
        usable = (
            mid["n_trials"] > 0
            and mid["n_converged"] >= 0.9 * mid["n_trials"]
            and mid["error_mean"] < DIVERGED_ERROR
        )
        findings.append(
            Finding(
                "The filter stays usable up to 80 % measurement loss.",
                bool(usable),
                f"20–80 % band: {int(mid['n_converged'])}/{int(mid['n_trials'])} trials converged, "
                f"mean error after convergence {fmt(mid['error_mean'])} m "
                f"(max {fmt(mid['error_max'])} m), mean time to convergence "
                f"{fmt(mid['convergence_mean'])} s",
            )
        )
        low, high = bands.loc[LOSS_BANDS[0]], bands.loc[LOSS_BANDS[2]]
        findings.append(
            Finding(
                "Below 20 % loss the filter is robust; above 80 % error and convergence time grow "
                "drastically.",
                bool(
                    low["error_mean"] <= mid["error_mean"]
                    and high["error_mean"] > mid["error_mean"]
                    and high["convergence_mean"] > low["convergence_mean"]
                ),
                "mean error after convergence by band: "
                + ", ".join(f"{b} {fmt(bands.loc[b, 'error_mean'])} m" for b in LOSS_BANDS)
                + "; mean time to convergence: "
                + ", ".join(f"{b} {fmt(bands.loc[b, 'convergence_mean'])} s" for b in LOSS_BANDS),
            )
        )
    if depth_trials is not None and len(depth_trials):
        by = depth_trials.groupby("depth_correction")["mean_error_after_convergence"].mean()
        if {True, False} <= set(by.index):
            findings.append(
                Finding(
                    "Correcting ranges with the tag's depth removes the error a deep dive causes.",
                    bool(by[True] < by[False]),
                    f"diving shark, mean error after convergence: without correction "
                    f"{fmt(by[False])} m, with correction {fmt(by[True])} m",
                )
            )
    return findings
