"""Tables of trials: the tidy per-trial table, per-cell means, and the paper's loss bands.

Pure functions on :class:`pandas.DataFrame`; they run nothing.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import pandas as pd

from hmmtrack.experiments.trials import MOTIONS, TRIAL_COLUMNS, TrialResult

#: the paper's measurement-loss bands, and the fractions of detections dropped between them;
#: a fraction on an edge belongs to the middle band, as in "between 20 % and 80 %"
LOSS_BANDS = ("<20 %", "20–80 %", ">80 %")
LOSS_BAND_EDGES = (0.2, 0.8)


def trials_table(results: Iterable[TrialResult]) -> pd.DataFrame:
    """Tidy table of trials: one row per trial, columns :data:`TRIAL_COLUMNS`.

    Rows are sorted by scenario order of appearance, dataset, motion, loss fraction, depth
    correction and trial, so the table does not depend on the order trials finished in.
    """
    table = pd.DataFrame([r.row() for r in results], columns=list(TRIAL_COLUMNS))
    table = table.astype(
        {
            "trial": int,
            "dataset": int,
            "n_particles": int,
            "converged": bool,
            "depth_correction": bool,
        }
    )
    keys = ["scenario", "dataset", "motion", "loss_fraction", "depth_correction", "trial"]
    order = {name: i for i, name in enumerate(pd.unique(table["scenario"]))}
    motion_order = {name: i for i, name in enumerate(MOTIONS)}
    return table.sort_values(
        keys,
        key=lambda col: (
            col.map(order)
            if col.name == "scenario"
            else col.map(lambda m: motion_order.get(m, len(MOTIONS)))
            if col.name == "motion"
            else col
        ),
        kind="stable",
    ).reset_index(drop=True)


def summarise_trials(
    table: pd.DataFrame, by: Sequence[str] = ("scenario", "motion")
) -> pd.DataFrame:
    """Per-group means of a trials table, as the paper reports them.

    Parameters
    ----------
    table : pandas.DataFrame
        A trials table (:func:`trials_table`).
    by : sequence of str
        Grouping columns.

    Returns
    -------
    pandas.DataFrame
        One row per group: ``n_trials``, ``n_converged``,
        ``mean_error_after_convergence`` (mean over trials of the paper's "RMSE", m),
        ``median_error_after_convergence`` (m), ``rmse_after_convergence`` (mean over
        trials, m), ``time_to_convergence`` (mean over converged trials, s; NaN when none
        converged) and ``max_time_to_convergence`` (s); with the trials' ``calibration``,
        ``false_converged`` and ``mirror_share`` columns, their means (over the trials
        where they are defined), and with ``region_scale`` its median (a lost trial's
        scale is in the hundreds and would swamp a mean).
    """
    groups = table.groupby(list(by), sort=False)
    converged_times = table["time_to_convergence"].where(table["converged"])
    summary = pd.DataFrame(
        {
            "n_trials": groups.size(),
            "n_converged": groups["converged"].sum().astype(int),
            "mean_error_after_convergence": groups["mean_error_after_convergence"].mean(),
            "median_error_after_convergence": groups["mean_error_after_convergence"].median(),
            "rmse_after_convergence": groups["rmse_after_convergence"].mean(),
            "time_to_convergence": converged_times.groupby(
                [table[c] for c in by], sort=False
            ).mean(),
            "max_time_to_convergence": converged_times.groupby(
                [table[c] for c in by], sort=False
            ).max(),
        }
    )
    for column in ("calibration", "false_converged", "mirror_share"):
        if column in table.columns:
            summary[column] = groups[column].mean()
    if "region_scale" in table.columns:
        summary["region_scale"] = groups["region_scale"].median()
    return summary.reset_index()


def dataset_spread(
    table: pd.DataFrame,
    column: str = "mean_error_after_convergence",
    by: Sequence[str] = ("scenario", "motion"),
) -> pd.DataFrame:
    """How much of a trials table's spread comes from the datasets, how much from the filter.

    Parameters
    ----------
    table : pandas.DataFrame
        A trials table with a ``dataset`` column (:func:`trials_table`).
    column : str
        The per-trial figure (default the paper's error after convergence, m).
    by : sequence of str
        Grouping columns.

    Returns
    -------
    pandas.DataFrame
        One row per group: ``n_datasets``, ``runs_per_dataset`` (the smallest),
        ``mean`` (over all trials), ``between_datasets`` (standard deviation of the
        datasets' means; NaN with one dataset), ``between_runs`` (root mean of the
        datasets' within-dataset variances; NaN with one run per dataset),
        ``worst_dataset`` (the largest dataset mean) and ``share_above_100m`` (share of
        trials whose figure exceeds 100 m).
    """
    keys = [*by, "dataset"]
    per_dataset = table.groupby(keys, sort=False)[column].agg(["mean", "var", "size"])
    groups = per_dataset.groupby(level=list(range(len(by))), sort=False)
    trials = table.groupby(list(by), sort=False)[column]
    spread = pd.DataFrame(
        {
            "n_datasets": groups.size(),
            "runs_per_dataset": groups["size"].min(),
            "mean": trials.mean(),
            "between_datasets": groups["mean"].std(ddof=1),
            "between_runs": np.sqrt(groups["var"].mean()),
            "worst_dataset": groups["mean"].max(),
            "share_above_100m": trials.apply(lambda v: float(np.mean(v > 100.0))),
        }
    )
    return spread.reset_index()


#: a dataset whose mean share of seconds inside the 95 % region is below this is "mostly
#: outside" (:func:`calibration_spread`)
MOSTLY_OUTSIDE = 0.8


def calibration_spread(table: pd.DataFrame) -> pd.DataFrame:
    """How each cell's share of seconds inside the 95 % region is made up of its datasets.

    The seconds of one run are not independent draws: a dataset's fixed errors (e.g. a
    moored receiver's single GPS fix) move all of them together, so a dataset is nearly all
    inside its regions or not, and a cell's share rests on its few datasets that are not.

    Parameters
    ----------
    table : pandas.DataFrame
        A trials table with ``scenario``, ``motion``, ``dataset`` and ``calibration`` (the
        share, 0-1, of a trial's seconds after convergence inside its 95 % region).

    Returns
    -------
    pandas.DataFrame
        One row per scenario and motion: ``n_datasets``, ``share`` (mean over trials),
        ``between_datasets`` (standard deviation of the datasets' means), ``all_inside``
        (datasets whose every trial had every second inside) and ``mostly_outside``
        (datasets whose mean share is below :data:`MOSTLY_OUTSIDE`).
    """
    spread = dataset_spread(table, column="calibration")
    per_dataset = table.groupby(["scenario", "motion", "dataset"], sort=False)["calibration"]
    shares = per_dataset.agg(["min", "mean"])
    counts = (
        pd.DataFrame(
            {
                "all_inside": shares["min"] >= 1.0,
                "mostly_outside": shares["mean"] < MOSTLY_OUTSIDE,
            }
        )
        .groupby(level=["scenario", "motion"], sort=False)
        .sum()
        .reset_index()
    )
    return (
        spread[["scenario", "motion", "n_datasets", "mean", "between_datasets"]]
        .rename(columns={"mean": "share"})
        .merge(counts, on=["scenario", "motion"], how="left")
    )


def loss_bands(table: pd.DataFrame) -> pd.DataFrame:
    """The paper's measurement-loss summary: mean and max per band of fractions dropped.

    Parameters
    ----------
    table : pandas.DataFrame
        Trials table with ``loss_fraction`` (0–1), ``converged``, ``time_to_convergence``
        (s) and ``mean_error_after_convergence`` (m), e.g. from :func:`loss_sweep`.

    Returns
    -------
    pandas.DataFrame
        Indexed by band label (:data:`LOSS_BANDS`): ``n_trials``, ``n_converged``,
        ``convergence_mean`` / ``convergence_max`` (s, over converged trials),
        ``error_mean`` / ``error_max`` (m, over converged trials). A band with no
        converged trial has NaN statistics and says so through ``n_converged = 0``.

    Raises
    ------
    ValueError
        If a loss fraction lies outside [0, 1] (naming the rows).
    """
    fraction = table["loss_fraction"].to_numpy(dtype=float)
    bad = np.flatnonzero(~((fraction >= 0) & (fraction <= 1)))
    if bad.size:
        raise ValueError(f"loss_fraction outside [0, 1] in row(s) {bad[:10].tolist()}")
    low, high = LOSS_BAND_EDGES
    labels = np.select([fraction < low, fraction <= high], LOSS_BANDS[:2], LOSS_BANDS[2])
    rows = {}
    for label in LOSS_BANDS:
        band = table[labels == label]
        ok = band[band["converged"].to_numpy(dtype=bool)]
        rows[label] = {
            "n_trials": len(band),
            "n_converged": len(ok),
            "convergence_mean": ok["time_to_convergence"].mean(),
            "convergence_max": ok["time_to_convergence"].max(),
            "error_mean": ok["mean_error_after_convergence"].mean(),
            "error_max": ok["mean_error_after_convergence"].max(),
        }
    return pd.DataFrame.from_dict(rows, orient="index")
