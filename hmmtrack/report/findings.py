"""The paper's qualitative findings, each tested on our trial tables.

:func:`check_findings` returns one :class:`Finding` per claim, with the numbers the verdict
rests on:

* per dataset (the paper's "Results" subsections): Long Beach — the three models perform
  alike; Santa Elena Bay — the HMM model has the lowest error but converges slowest; shark
  pursuit — the HMM model has the lowest error and the baseline diverges. "Lowest" and
  "slowest" compare the models dataset by dataset (:func:`ranked_first`): two models' runs
  on one dataset share its detections, so a paired test separates a real difference from
  the spread between datasets, and a claim the trials cannot decide says so;
* measurement loss — the filter stays usable up to 80 % loss, and time to convergence and
  error grow with loss, sharply above 80 %;
* depth — the correction lowers the error on a diving shark (our addition).

:func:`share_above` counts trials whose error after convergence exceeds
:data:`DIVERGED_ERROR`: trials that converged on the mirror intersection of the range
circles or lost the tag, which is what the means are most sensitive to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from hmmtrack.experiments import LOSS_BANDS, MOTIONS, loss_bands, summarise_trials
from hmmtrack.report.markdown import fmt

__all__ = [
    "DIVERGED_ERROR",
    "Finding",
    "check_findings",
    "paired_lower_p_value",
    "ranked_first",
    "share_above",
]

#: an error after convergence above this is "diverged or mirrored" (m): ten times the
#: convergence threshold
DIVERGED_ERROR = 100.0
#: "perform alike": the largest model mean error within this factor of the smallest
ALIKE_FACTOR = 2.0
#: "drastic" growth above 80 % loss: the >80 % band mean at least this times the 20–80 % one
DRASTIC_FACTOR = 3.0
#: a difference between two sets of trials counts when a one-sided test gives p below this
SIGNIFICANCE = 0.05


def paired_lower_p_value(a: np.ndarray, b: np.ndarray) -> float:
    """One-sided Wilcoxon signed-rank p-value of "``a`` is below ``b``", pair by pair.

    A rank test, because the errors of a tracker are heavy-tailed (a trial on the mirror
    point is off by hundreds of metres) and a t-test would follow those few pairs.

    Parameters
    ----------
    a, b : numpy.ndarray, shape (n,)
        Per-trial errors (m) of the two settings; ``a[k]`` and ``b[k]`` are the same trial
        (same detections, same filter seed) with the two settings.

    Returns
    -------
    float
        p-value in [0, 1]; 1.0 with fewer than two pairs or no pair that differs.
    """
    if a.shape != b.shape:
        raise ValueError(f"paired samples must have one shape, got {a.shape} and {b.shape}")
    differences = a - b
    if differences.size < 2 or not np.any(differences != 0):
        return 1.0
    return float(stats.wilcoxon(a, b, alternative="less").pvalue)


@dataclass(frozen=True)
class Finding:
    """One of the paper's qualitative claims, tested on our results.

    Attributes
    ----------
    claim : str
        The claim, in the paper's words.
    holds : bool or None
        Whether our results support it; ``None`` when the trials do not decide it (a paired
        test finds the difference it rests on in neither direction).
    evidence : str
        The numbers the verdict rests on.
    """

    claim: str
    holds: bool | None
    evidence: str


def share_above(trials: pd.DataFrame, threshold: float = DIVERGED_ERROR) -> pd.Series:
    """Share (0–1) of trials per scenario and motion with error after convergence above
    ``threshold`` (m)."""
    above = trials["mean_error_after_convergence"] > threshold
    return above.groupby([trials["scenario"], trials["motion"]], sort=False).mean()


def _means(summary: pd.DataFrame, scenario: str, column: str) -> dict[str, float] | None:
    rows = summary[summary["scenario"] == scenario].set_index("motion")
    if not set(MOTIONS) <= set(rows.index):
        return None
    return {m: float(rows.loc[m, column]) for m in MOTIONS}


def _listing(values: dict[str, float], unit: str) -> str:
    return ", ".join(f"{m} {fmt(v)} {unit}" for m, v in values.items())


def _pairs(comparison: pd.DataFrame, scenario: str, column: str) -> tuple[pd.DataFrame, str]:
    """``column`` of ``scenario``'s trials, a column per motion model and a row per pair: per
    dataset (the mean of a model's runs on it) when the trials span several datasets, else
    per trial index. The runs on one dataset share its detections and errors, so they are
    not independent pairs. Also returns what a row is (``"datasets"`` or ``"trials"``)."""
    rows = comparison[comparison["scenario"] == scenario]
    several = "dataset" in rows and rows["dataset"].nunique() > 1
    by = "dataset" if several else "trial"
    table = rows.pivot_table(index=by, columns="motion", values=column, aggfunc="mean")
    return table, f"{by}s"


def ranked_first(
    comparison: pd.DataFrame, scenario: str, column: str, model: str, *, lowest: bool = True
) -> tuple[bool | None, str]:
    """Whether ``model`` has the lowest (or highest) ``column`` of the motion models.

    The claim holds when ``model``'s mean is the lowest and a one-sided paired test
    (:func:`paired_lower_p_value`, over datasets, or over trial indices on one dataset:
    pairs share their detections) puts it below every other model at p <
    :data:`SIGNIFICANCE`; it does not hold when another model's mean is lower and the paired
    test puts that model below ``model``; otherwise the trials do not decide it.

    Parameters
    ----------
    comparison : pandas.DataFrame
        Trials of :func:`hmmtrack.experiments.compare_motion_models`.
    scenario, column, model : str
        The scenario's rows, the per-trial figure compared (e.g.
        ``mean_error_after_convergence``, m) and the model the claim is about.
    lowest : bool
        ``False`` for "highest" (e.g. converges slowest).

    Returns
    -------
    holds : bool or None
        ``None`` when undecided.
    evidence : str
        The paired tests' p-values, a clause per other model.
    """
    pairs, unit = _pairs(comparison, scenario, column)
    sign, direction = (1.0, "lower") if lowest else (-1.0, "higher")
    means = sign * pairs.mean()
    below, above, clauses = [], [], []
    for other in (m for m in MOTIONS if m != model and m in pairs):
        both = pairs[[model, other]].dropna().to_numpy(dtype=float)
        p_model = paired_lower_p_value(sign * both[:, 0], sign * both[:, 1])
        p_other = paired_lower_p_value(sign * both[:, 1], sign * both[:, 0])
        below.append(means[model] < means[other] and p_model < SIGNIFICANCE)
        above.append(means[other] < means[model] and p_other < SIGNIFICANCE)
        clauses.append(
            f"{model} against {other} over {len(both)} {unit}: p = {p_model:.2g} "
            f"({model} {direction}), p = {p_other:.2g} ({other} {direction})"
        )
    holds = True if below and all(below) else False if any(above) else None
    return holds, "; ".join(clauses)


def _both(first: bool | None, second: bool | None) -> bool | None:
    """Both parts of a claim: false if either is, true if both are, else undecided."""
    if first is False or second is False:
        return False
    return True if first and second else None


def _dataset_findings(comparison: pd.DataFrame) -> list[Finding]:
    summary = summarise_trials(comparison)
    shares = share_above(comparison)
    findings = []
    errors = _means(summary, "stationary-tag", "mean_error_after_convergence")
    if errors is not None:
        findings.append(
            Finding(
                "Long Beach (stationary tag): the three motion models perform alike.",
                max(errors.values()) <= ALIKE_FACTOR * min(errors.values()),
                f"mean error after convergence: {_listing(errors, 'm')}",
            )
        )
    errors = _means(summary, "swimmer", "mean_error_after_convergence")
    times = _means(summary, "swimmer", "time_to_convergence")
    if errors is not None:
        lowest, lowest_tests = ranked_first(
            comparison, "swimmer", "mean_error_after_convergence", "hmm"
        )
        slowest, slowest_tests = ranked_first(
            comparison, "swimmer", "time_to_convergence", "hmm", lowest=False
        )
        findings.append(
            Finding(
                "Santa Elena Bay (swimmer): the HMM model has the lowest error but converges "
                "slowest.",
                _both(lowest, slowest),
                f"mean error after convergence: {_listing(errors, 'm')} ({lowest_tests}); mean "
                f"time to convergence: {_listing(times, 's')} ({slowest_tests})",
            )
        )
    errors = _means(summary, "shark-pursuit", "mean_error_after_convergence")
    if errors is not None:
        medians = _means(summary, "shark-pursuit", "median_error_after_convergence")
        lowest, tests = ranked_first(
            comparison, "shark-pursuit", "mean_error_after_convergence", "hmm"
        )
        findings.append(
            Finding(
                "Shark pursuit: the HMM motion model has the lowest error after convergence.",
                lowest,
                f"mean error after convergence: {_listing(errors, 'm')} (medians "
                f"{_listing(medians, 'm')}; {tests})",
            )
        )
        share = {m: float(shares.get(("shark-pursuit", m), np.nan)) for m in MOTIONS}
        findings.append(
            Finding(
                "Shark pursuit: the baseline (random-walk) model diverges almost always.",
                share["baseline"] >= 0.5 and max(errors, key=errors.get) == "baseline",
                f"share of trials with error after convergence above {DIVERGED_ERROR:g} m: "
                + ", ".join(f"{m} {100 * s:.0f} %" for m, s in share.items()),
            )
        )
    return findings


def _loss_findings(loss: pd.DataFrame) -> list[Finding]:
    bands = loss_bands(loss)
    low, mid, high = (bands.loc[b] for b in LOSS_BANDS)
    usable = (
        mid["n_trials"] > 0
        and mid["n_converged"] >= 0.9 * mid["n_trials"]
        and mid["error_mean"] < DIVERGED_ERROR
    )
    findings = [
        Finding(
            "The filter stays usable up to 80 % measurement loss.",
            bool(usable),
            f"20–80 % band: {int(mid['n_converged'])}/{int(mid['n_trials'])} trials converged, "
            f"mean error after convergence {fmt(mid['error_mean'])} m (max "
            f"{fmt(mid['error_max'])} m), mean time to convergence "
            f"{fmt(mid['convergence_mean'])} s",
        )
    ]
    for column, what, unit in (
        ("convergence_mean", "time to convergence", "s"),
        ("error_mean", "error after convergence", "m"),
    ):
        findings.append(
            Finding(
                f"The {what} grows with measurement loss, drastically above 80 %.",
                bool(low[column] <= mid[column] and high[column] >= DRASTIC_FACTOR * mid[column]),
                f"mean {what} by band dropped: "
                + ", ".join(f"{b} {fmt(bands.loc[b, column])} {unit}" for b in LOSS_BANDS),
            )
        )
    return findings


def check_findings(
    comparison: pd.DataFrame | None,
    loss: pd.DataFrame | None,
    depth_trials: pd.DataFrame | None = None,
) -> list[Finding]:
    """Test the paper's qualitative findings on our trials tables.

    Parameters
    ----------
    comparison : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.compare_motion_models` (scenario names of
        :mod:`hmmtrack.scenarios`: ``stationary-tag``, ``swimmer``, ``shark-pursuit``).
    loss : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.loss_sweep`.
    depth_trials : pandas.DataFrame or None
        Trials of :func:`hmmtrack.experiments.depth_analysis` (``depth_correction`` column).

    Returns
    -------
    list of Finding
        The claims listed in the module docstring that the given tables can test, in that
        order. Criteria: "alike" = largest mean error within :data:`ALIKE_FACTOR` of the
        smallest; "diverges" = at least half the baseline trials above
        :data:`DIVERGED_ERROR` and the baseline the worst model; "usable" = at least 90 % of
        the 20–80 % band converged with a mean error below :data:`DIVERGED_ERROR`;
        "drastically" = the >80 % band mean at least :data:`DRASTIC_FACTOR` times the
        20–80 % one, which is not below the <20 % one; "lowers" (depth) = a one-sided
        Wilcoxon signed-rank test of the paired per-trial errors
        (:func:`paired_lower_p_value`) gives p below :data:`SIGNIFICANCE`.
    """
    findings = []
    if comparison is not None and len(comparison):
        findings += _dataset_findings(comparison)
    if loss is not None and len(loss):
        findings += _loss_findings(loss)
    if depth_trials is not None and len(depth_trials):
        pairs = depth_trials.pivot_table(
            index="trial", columns="depth_correction", values="mean_error_after_convergence"
        ).dropna()
        if {True, False} <= set(pairs.columns):
            with_correction = pairs[True].to_numpy(dtype=float)
            without = pairs[False].to_numpy(dtype=float)
            p_value = paired_lower_p_value(with_correction, without)
            better = int(np.sum(with_correction < without))
            findings.append(
                Finding(
                    "Correcting ranges with the tag's depth lowers the error on a diving shark.",
                    bool(p_value < SIGNIFICANCE),
                    f"mean error after convergence: without correction {fmt(without.mean())} m, "
                    f"with correction {fmt(with_correction.mean())} m; lower with the "
                    f"correction in {better} of {without.size} paired trials (same detections, "
                    f"same filter seed), one-sided Wilcoxon signed-rank p = {p_value:.2g}",
                )
            )
    return findings
