"""Metrics of a tracking run against the truth: the paper's position error and convergence.

* position error at each estimate time, the truth interpolated linearly to those times;
* time to convergence: the first time the particles' spread √λ₁ (square root of the
  largest eigenvalue of their x-y covariance) falls below a threshold (10 m in the
  paper), counted from the first estimate, and 0 when it never does — the paper's
  convention, which is ambiguous, so :class:`Convergence` also says whether it converged;
* the error after convergence in two forms that must not be confused: the paper's
  "RMSE", which its formula defines as the *mean* of the errors after convergence
  (:func:`mean_error_after_convergence`), and the true root-mean-square error
  (:func:`rmse_after_convergence`). Always mean ≤ RMS;
* the filter's honesty: the normalised estimation error squared (NEES) of each estimate
  against its own x-y covariance (:func:`normalised_estimation_error`, χ² with 2 degrees of
  freedom for a consistent filter) and the share of estimates whose 95 % ellipse covers the
  truth (:func:`ellipse_coverage`), and how far the ellipses would have to be scaled to
  hold it at their level (:func:`region_scale`); after convergence, the calibration (share
  of seconds whose 95 % region holds the truth), that scale, and the share of falsely
  "converged" seconds (:func:`uncertainty_metrics`).

Convergence is judged by the estimates' ``converged`` column when they have one (the
mode-keeping filter's: √λ₁ below the threshold *and* one mode holding almost all the
weight, :func:`hmmtrack.tracking.mixture.with_modes`), else by √λ₁ alone as in the paper
(:func:`convergence_flags`).

It is not for running filters or Monte Carlo trials (``hmmtrack.experiments`` does that),
for information limits (:mod:`hmmtrack.analysis.crb`) nor for plotting.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from hmmtrack.tracking.mixture import CONVERGENCE_THRESHOLD


@dataclass(frozen=True)
class Convergence:
    """When a run converged.

    Attributes
    ----------
    time_to_convergence : float
        Seconds from the first estimate to the first one with √λ₁ below the threshold;
        0.0 when it never converged (the paper's convention).
    converged : bool
        Whether √λ₁ ever fell below the threshold.
    index : int
        Position of the first converged estimate; 0 when it never converged, so that
        "after convergence" then means the whole run, as in the paper.
    """

    time_to_convergence: float
    converged: bool
    index: int


@dataclass(frozen=True)
class TrackingMetrics:
    """The paper's summary of one run (see :func:`tracking_metrics`)."""

    time_to_convergence: float
    converged: bool
    mean_error_after_convergence: float
    rmse_after_convergence: float
    n_estimates_after_convergence: int

    def to_dict(self) -> dict:
        return asdict(self)


#: error (m) above which a second declared converged is a false convergence (issue 13)
FALSE_CONVERGENCE_ERROR = 50.0


@dataclass(frozen=True)
class Uncertainty:
    """How honest a run's stated uncertainty was (see :func:`uncertainty_metrics`).

    Attributes
    ----------
    calibration : float
        Share of the seconds from the first convergence to the end whose 95 % region holds
        the truth; NaN when the run never converged. A calibrated filter gives 0.95.
    false_converged : float
        Share of all seconds declared converged while the error exceeded
        :data:`FALSE_CONVERGENCE_ERROR`.
    seconds_after_convergence : int
        Estimates from the first convergence to the end (0 if never converged).
    region_scale : float
        Over the same seconds, the factor by which every region would have to be scaled
        about its centre to hold the truth in exactly the ``level`` share of them
        (:func:`region_scale`): 1 for a calibrated filter, below 1 for regions wider than
        the errors need (a calibration above ``level`` says only that, this says by how
        much), above 1 for overconfident ones; NaN when the run never converged.
    """

    calibration: float
    false_converged: float
    seconds_after_convergence: int
    region_scale: float = math.nan

    def to_dict(self) -> dict:
        return asdict(self)


def finite_columns(table: pd.DataFrame, name: str, columns: tuple[str, ...]) -> list[np.ndarray]:
    """The ``columns`` of ``table`` as float arrays, each of shape (n,).

    Raises a ``ValueError`` naming the ``name`` table when a column is missing or holds a
    non-finite value, so that a bad input fails here and not as a NaN error later.
    """
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise ValueError(f"{name} table lacks column(s) {missing}; expected {list(columns)}")
    arrays = [table[c].to_numpy(dtype=float) for c in columns]
    for column, values in zip(columns, arrays, strict=True):
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise ValueError(
                f"{name} table has non-finite {column!r} in row(s) {bad[:10].tolist()}"
            )
    return arrays


def truth_at(truth: pd.DataFrame, times) -> tuple[np.ndarray, np.ndarray]:
    """True position at ``times``, interpolated linearly between truth rows.

    Parameters
    ----------
    truth : pandas.DataFrame
        ``time`` (s), ``x``, ``y`` (m). A single row is a stationary tag, valid at any time
        (its ``time`` may be missing).
    times : array_like, shape (n,)
        Times (s), inside the truth's time span unless the truth has one row.

    Returns
    -------
    x, y : numpy.ndarray, shape (n,)
        Interpolated positions (m).
    """
    x_true, y_true = finite_columns(truth, "truth", ("x", "y"))
    times = np.asarray(times, dtype=float)
    if x_true.size == 1:
        return np.full(times.shape, x_true[0]), np.full(times.shape, y_true[0])
    (t_true,) = finite_columns(truth, "truth", ("time",))
    order = np.argsort(t_true, kind="stable")
    t_true, x_true, y_true = t_true[order], x_true[order], y_true[order]
    outside = np.flatnonzero((times < t_true[0]) | (times > t_true[-1]))
    if outside.size:
        raise ValueError(
            f"{outside.size} time(s) lie outside the truth's span [{t_true[0]}, {t_true[-1]}] s "
            f"(first at position {outside[0]}); restrict the estimates to that span"
        )
    return np.interp(times, t_true, x_true), np.interp(times, t_true, y_true)


def position_error(estimates: pd.DataFrame, truth: pd.DataFrame) -> np.ndarray:
    """The paper's position estimate error at each estimate time.

    Parameters
    ----------
    estimates : pandas.DataFrame
        Estimates table (``time`` s, ``x``, ``y`` m).
    truth : pandas.DataFrame
        Truth table (``time`` s, ``x``, ``y`` m), see :func:`truth_at`.

    Returns
    -------
    numpy.ndarray, shape (n_estimates,)
        ``sqrt((x_t − x̂_t)² + (y_t − ŷ_t)²)`` (m).
    """
    times, x_hat, y_hat = finite_columns(estimates, "estimates", ("time", "x", "y"))
    x, y = truth_at(truth, times)
    return np.hypot(x - x_hat, y - y_hat)


def time_to_convergence(
    times, sqrt_lambda1, threshold: float = CONVERGENCE_THRESHOLD
) -> Convergence:
    """First time the particles' spread √λ₁ falls below ``threshold``.

    Parameters
    ----------
    times : array_like, shape (n,)
        Estimate times, increasing (s).
    sqrt_lambda1 : array_like, shape (n,)
        √λ₁ at those times (m).
    threshold : float
        Convergence threshold (m); 10 m in the paper.

    Returns
    -------
    Convergence
        Time from ``times[0]`` (s, 0 if never), whether it converged, and the index.
    """
    spread = np.asarray(sqrt_lambda1, dtype=float)
    bad = np.flatnonzero(~np.isfinite(spread))
    if bad.size:
        raise ValueError(f"sqrt_lambda1 is not finite at position(s) {bad[:10].tolist()}")
    return first_convergence(times, spread < threshold)


def convergence_flags(
    estimates: pd.DataFrame, threshold: float = CONVERGENCE_THRESHOLD
) -> np.ndarray:
    """Whether each estimate is declared converged, shape (n,), bool.

    The estimates' ``converged`` column when present (the mode-keeping filter's, which also
    asks one mode to hold almost all the weight), else ``sqrt_lambda1 < threshold`` (the
    paper's test).
    """
    if "converged" in estimates.columns:
        return estimates["converged"].to_numpy(dtype=bool)
    (spread,) = finite_columns(estimates, "estimates", ("sqrt_lambda1",))
    return spread < threshold


def first_convergence(times, flags) -> Convergence:
    """The :class:`Convergence` of the first estimate flagged converged.

    Parameters
    ----------
    times : array_like, shape (n,)
        Estimate times, increasing (s).
    flags : array_like, shape (n,), bool
        Converged or not at each (:func:`convergence_flags`).
    """
    times = np.asarray(times, dtype=float)
    flags = np.asarray(flags, dtype=bool)
    if times.shape != flags.shape or times.ndim != 1 or times.size == 0:
        raise ValueError(
            f"times and convergence flags (or sqrt_lambda1) must be non-empty and of one "
            f"shape; got {times.shape} and {flags.shape}"
        )
    below = np.flatnonzero(flags)
    if below.size == 0:
        return Convergence(time_to_convergence=0.0, converged=False, index=0)
    index = int(below[0])
    return Convergence(float(times[index] - times[0]), converged=True, index=index)


def _after(errors, convergence: Convergence) -> np.ndarray:
    errors = np.asarray(errors, dtype=float)
    after = errors[convergence.index :]
    if after.size == 0:
        raise ValueError(
            f"no errors after convergence index {convergence.index} ({errors.size} errors)"
        )
    return after


def mean_error_after_convergence(errors, convergence: Convergence) -> float:
    """The paper's "RMSE": the *mean* position error from convergence to the end.

    Parameters
    ----------
    errors : array_like, shape (n,)
        Position errors at each estimate (m), see :func:`position_error`.
    convergence : Convergence
        From :func:`time_to_convergence` on the same estimates.

    Returns
    -------
    float
        ``mean(errors[t_c:])`` (m); the whole run when it never converged (t_c = 0).
    """
    return float(np.mean(_after(errors, convergence)))


def rmse_after_convergence(errors, convergence: Convergence) -> float:
    """True root-mean-square position error from convergence to the end.

    Parameters
    ----------
    errors : array_like, shape (n,)
        Position errors at each estimate (m).
    convergence : Convergence
        From :func:`time_to_convergence` on the same estimates.

    Returns
    -------
    float
        ``sqrt(mean(errors[t_c:]²))`` (m), never below :func:`mean_error_after_convergence`.
    """
    return float(np.sqrt(np.mean(_after(errors, convergence) ** 2)))


def tracking_metrics(
    estimates: pd.DataFrame, truth: pd.DataFrame, threshold: float = CONVERGENCE_THRESHOLD
) -> TrackingMetrics:
    """All of the paper's metrics of one run.

    Parameters
    ----------
    estimates : pandas.DataFrame
        Estimates table with ``time``, ``x``, ``y``, ``sqrt_lambda1`` and optionally
        ``converged`` (:func:`convergence_flags`).
    truth : pandas.DataFrame
        Truth table (``time``, ``x``, ``y``).
    threshold : float
        Convergence threshold on √λ₁ (m).

    Returns
    -------
    TrackingMetrics
    """
    errors = position_error(estimates, truth)
    (times, _) = finite_columns(estimates, "estimates", ("time", "sqrt_lambda1"))
    convergence = first_convergence(times, convergence_flags(estimates, threshold))
    return TrackingMetrics(
        time_to_convergence=convergence.time_to_convergence,
        converged=convergence.converged,
        mean_error_after_convergence=mean_error_after_convergence(errors, convergence),
        rmse_after_convergence=rmse_after_convergence(errors, convergence),
        n_estimates_after_convergence=errors.size - convergence.index,
    )


def ellipse_scale(level: float = 0.95) -> float:
    """Squared Mahalanobis radius of the ``level`` ellipse of a 2-D Gaussian.

    Parameters
    ----------
    level : float
        Probability in (0, 1) the ellipse holds.

    Returns
    -------
    float
        ``−2 ln(1 − level)``, the ``level`` quantile of χ² with 2 degrees of freedom
        (5.991 for 95 %).
    """
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must lie in (0, 1), got {level!r}")
    return float(-2.0 * np.log1p(-level))


def normalised_estimation_error(
    estimates: pd.DataFrame, truth: pd.DataFrame, degenerate: str = "raise"
) -> np.ndarray:
    """NEES of each estimate: its error measured in its own x-y covariance.

    Parameters
    ----------
    estimates : pandas.DataFrame
        Estimates table: ``time`` (s), ``x``, ``y`` (m), ``var_x``, ``var_y``, ``cov_xy`` (m²).
    truth : pandas.DataFrame
        Truth table, see :func:`truth_at`.
    degenerate : {"raise", "inf"}
        What a covariance that is not positive definite gives (a cloud collapsed onto a
        point or a line): an error, or NEES ``inf`` (its region holds no truth).

    Returns
    -------
    numpy.ndarray, shape (n_estimates,)
        ``eᵀ P⁻¹ e`` with ``e`` the position error (m) and ``P`` the estimate's covariance
        (m²); dimensionless. A consistent filter gives χ² with 2 degrees of freedom (mean 2);
        much larger means the filter is overconfident.

    Raises
    ------
    ValueError
        When a covariance is not positive definite (rows named).
    """
    times, x_hat, y_hat, var_x, var_y, cov = finite_columns(
        estimates, "estimates", ("time", "x", "y", "var_x", "var_y", "cov_xy")
    )
    det = var_x * var_y - cov**2
    definite = (var_x > 0) & (det > 0)
    bad = np.flatnonzero(~definite)
    if bad.size and degenerate != "inf":
        raise ValueError(
            f"estimates table has a covariance that is not positive definite in row(s) "
            f"{bad[:10].tolist()} (var_x, var_y, cov_xy); NEES needs P > 0"
        )
    x, y = truth_at(truth, times)
    ex, ey = x_hat - x, y_hat - y
    with np.errstate(divide="ignore", invalid="ignore"):
        nees = (var_y * ex**2 - 2.0 * cov * ex * ey + var_x * ey**2) / det
    return np.where(definite, nees, np.inf)


def _checked_nees(nees) -> np.ndarray:
    """``nees`` as a float array (n,), refused unless 1-D, non-empty and without NaN."""
    nees = np.asarray(nees, dtype=float)
    if nees.ndim != 1 or nees.size == 0 or np.isnan(nees).any():
        raise ValueError(f"nees must be a non-empty 1-D array without NaN, got shape {nees.shape}")
    return nees


def ellipse_coverage(nees, level: float = 0.95) -> float:
    """Share of estimates whose ``level`` ellipse holds the truth.

    Parameters
    ----------
    nees : array_like, shape (n,)
        NEES values (:func:`normalised_estimation_error`), n ≥ 1.
    level : float
        Probability of the ellipse (0.95: the 95 % ellipse).

    Returns
    -------
    float
        Fraction of ``nees`` ≤ :func:`ellipse_scale` (``level``); equal to ``level`` on
        average for a consistent filter, below it for an overconfident one.
    """
    return float(np.mean(_checked_nees(nees) <= ellipse_scale(level)))


def region_scale(nees, level: float = 0.95) -> float:
    """Factor by which the ``level`` ellipses would have to be scaled to be calibrated.

    Scaling an ellipse's axes by ``s`` about its centre divides every NEES by ``s²``, so the
    scaled ellipses hold the truth in the ``level`` share of the estimates when ``s²`` is
    the ``level`` quantile of the NEES over :func:`ellipse_scale` (``level``).

    Parameters
    ----------
    nees : array_like, shape (n,)
        NEES values (:func:`normalised_estimation_error`), n ≥ 1; ``inf`` for a degenerate
        covariance.
    level : float
        Probability of the ellipse (0.95).

    Returns
    -------
    float
        ``sqrt(quantile(nees, level) / ellipse_scale(level))`` (the quantile: the smallest
        value with at least ``level`` of the NEES at or below it), dimensionless: 1 for a
        consistent filter, 0.5 for ellipses twice as wide as the errors need, 2 for ellipses
        half as wide; ``inf`` when more than ``1 − level`` of the covariances are degenerate.
    """
    quantile = np.quantile(_checked_nees(nees), level, method="inverted_cdf")
    return float(np.sqrt(quantile / ellipse_scale(level)))


def uncertainty_metrics(
    estimates: pd.DataFrame,
    truth: pd.DataFrame,
    level: float = 0.95,
    threshold: float = CONVERGENCE_THRESHOLD,
) -> Uncertainty:
    """Calibration and false convergence of one run (issue 13's honesty targets).

    The ``level`` region of an estimate is the ellipse of the Gaussian with the cloud's
    weighted mean and x-y covariance (the estimate's ``x``, ``y``, ``var_x``, ``var_y``,
    ``cov_xy``; :func:`normalised_estimation_error`). After convergence one mode holds
    almost all the weight (with the ``converged`` column) and √λ₁ is under 10 m, so this is
    the region of the heaviest component widened by the rest; before it, a multi-modal
    cloud's Gaussian would overstate coverage, and those seconds are not counted. A cloud
    collapsed onto a point (covariance not positive definite) holds no truth.

    Over those seconds this ellipse stands for the mixture's 95 % region: on the paper's
    three datasets the highest-density region of the Gaussian mixture of the filter's
    components (weights, means, covariances) held the truth in a share of the seconds
    within 0.1 percentage points of the ellipse's, and that of the particles themselves
    within 2.2 points (``reports/decisions.md``, "Calibration after convergence"), so the
    estimates table needs no per-component columns for it.

    Parameters
    ----------
    estimates : pandas.DataFrame
        Estimates table (``time``, ``x``, ``y``, ``var_x``, ``var_y``, ``cov_xy``,
        ``sqrt_lambda1``, optionally ``converged``).
    truth : pandas.DataFrame
        Truth table, see :func:`truth_at`.
    level : float
        Probability of the region (0.95).
    threshold : float
        Convergence threshold on √λ₁ (m) when there is no ``converged`` column.

    Returns
    -------
    Uncertainty
    """
    flags = convergence_flags(estimates, threshold)
    errors = position_error(estimates, truth)
    false_converged = float(np.mean(flags & (errors > FALSE_CONVERGENCE_ERROR)))
    (times,) = finite_columns(estimates, "estimates", ("time",))
    convergence = first_convergence(times, flags)
    if not convergence.converged:
        return Uncertainty(math.nan, false_converged, 0)
    after = estimates.iloc[convergence.index :]
    nees = normalised_estimation_error(after, truth, degenerate="inf")
    return Uncertainty(
        ellipse_coverage(nees, level), false_converged, nees.size, region_scale(nees, level)
    )
