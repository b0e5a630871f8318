"""Irregular tracks: the continuous-time correlated random walk (CRW) of Johnson et al. (2008).

The model of R's ``crawl``, fitted to the fixes of one animal (or one segment) taken at
irregular times. On each axis (``x``, ``y``, independently, with the same parameters) the
velocity ``v`` (m/s) is an Ornstein-Uhlenbeck process and the position ``mu`` (m) its
integral::

    dv = -beta v dt + sigma dW,        dmu = v dt,

and a fix is the position plus a Gaussian error of standard deviation ``error_sd`` (m; 0 for
exact fixes). ``beta`` (1/s) is the rate at which velocity forgets itself (``1 / beta`` is
the velocity's correlation time) and ``sigma`` (m s^-3/2) its diffusion; the stationary
velocity variance per axis is ``sigma^2 / (2 beta)``. Over a time step ``dt`` the state
``(mu, v)`` of an axis moves linearly with Gaussian noise, in closed form
(:meth:`CorrelatedRandomWalk.transition`), so the fixes are a linear Gaussian state-space
model whose transition matrices change with every step: a Kalman filter gives the exact
likelihood at any times, a Kalman smoother the positions (with variances) at any other times,
and a simulation smoother draws whole tracks from their distribution given the fixes.

The filtering, smoothing and simulation smoothing are statsmodels' state-space machinery
(:class:`statsmodels.tsa.statespace.mlemodel.MLEModel` with time-varying system matrices,
one column per time node; missing fixes are NaN). Its exact diffuse initialisation handles
the first position, which the model leaves unknown; the velocity starts from its stationary
distribution. The log-likelihood reported here is the density of the fixes after the first
given the first fix (statsmodels' diffuse value plus ``log(2 pi)``, the constant it counts
for the first fix's two coordinates).

* :class:`CorrelatedRandomWalk` -- parameters, transition, likelihood, prediction, draws;
* :func:`fit_crw` -- maximum likelihood on one track's fixes;
* :func:`fit_tracks`, :func:`regularise`, :func:`impute` -- the same for every segment of a
  tracks table, on the regular grid of :func:`hmmtrack.tracks.regularise`; :func:`impute`
  draws the tracks of a multiple imputation (:mod:`hmmtrack.hmm.imputation` fits and pools).

Not for linear interpolation or gap splitting (:mod:`hmmtrack.tracks`) and not for fitting
the movement HMM itself (:mod:`hmmtrack.hmm.fit`).

Reference: Johnson, London, Lea & Durban (2008), Continuous-time correlated random walk model
for animal telemetry data, Ecology 89(5):1208-1215.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from statsmodels.tsa.statespace.initialization import Initialization
from statsmodels.tsa.statespace.mlemodel import MLEModel

from hmmtrack import tracks as track_maths

_SERIES_BELOW = 0.2  # beta * dt under which the position variance uses its Taylor series
_SERIES_TERMS = 16  # terms of that series: relative error below 1e-24 at beta * dt = 0.2
_SAME_TIME = 1e-6  # s: a grid time this close to a fix is the fix's time node


def _position_variance_factor(u: np.ndarray) -> np.ndarray:
    """``u - 2 (1 - exp(-u)) + (1 - exp(-2 u)) / 2`` for ``u = beta dt >= 0``.

    The closed form cancels to ``u^3 / 3`` for small ``u``; there the series
    ``sum_k (-1)^k (2 - 2^(k-1)) u^k / k!`` (k >= 3) is used instead.
    """
    closed = u + 2.0 * np.expm1(-u) - 0.5 * np.expm1(-2.0 * u)
    series = np.zeros_like(u)
    for k in range(3, 3 + _SERIES_TERMS):
        series = series + (-1) ** k * (2.0 - 2.0 ** (k - 1)) / math.factorial(k) * u**k
    return np.where(np.real(u) < _SERIES_BELOW, series, closed)


@dataclass(frozen=True)
class CRWPrediction:
    """Positions of a track at requested times given its fixes (Kalman smoother).

    Attributes
    ----------
    time : ndarray, shape (G,)
        Requested times (s).
    mean : ndarray, shape (G, 2)
        Expected position ``x``, ``y`` (m).
    variance : ndarray, shape (G, 2)
        Variance of the position on each axis (m^2); the axes are independent. The variance
        of a new *fix* at that time adds ``error_sd ** 2``.
    """

    time: np.ndarray
    mean: np.ndarray
    variance: np.ndarray


@dataclass(frozen=True)
class CorrelatedRandomWalk:
    """Continuous-time correlated random walk in the plane (Johnson et al. 2008).

    Parameters
    ----------
    sigma : float
        Diffusion of the velocity (m s^-3/2).
    beta : float
        Mean-reversion rate of the velocity (1/s).
    error_sd : float
        Standard deviation of a fix's error on each axis (m); 0 for exact fixes.
    log_likelihood : float
        Of the fixes the model was fitted to (NaN for a model not fitted).
    n_obs : int
        Observed fixes of that fit.
    """

    sigma: float
    beta: float
    error_sd: float = 0.0
    log_likelihood: float = float("nan")
    n_obs: int = 0

    def __post_init__(self) -> None:
        if not (self.sigma > 0 and self.beta > 0 and self.error_sd >= 0):
            raise ValueError(
                f"CorrelatedRandomWalk needs sigma > 0, beta > 0 and error_sd >= 0; got "
                f"sigma={self.sigma!r}, beta={self.beta!r}, error_sd={self.error_sd!r}"
            )

    @property
    def velocity_variance(self) -> float:
        """Stationary variance of the velocity on one axis, ``sigma^2 / (2 beta)`` (m^2/s^2)."""
        return self.sigma**2 / (2.0 * self.beta)

    def transition(self, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Transition matrices and noise covariances of one axis's state ``(position, velocity)``.

        Parameters
        ----------
        dt : ndarray, shape (n,)
            Time steps (s), ``>= 0``.

        Returns
        -------
        matrix : ndarray, shape (n, 2, 2)
            ``[[1, (1 - e) / beta], [0, e]]`` with ``e = exp(-beta dt)``.
        covariance : ndarray, shape (n, 2, 2)
            Covariance of the noise added over the step.
        """
        return _transition(np.asarray(dt, dtype=float), self.sigma, self.beta)

    def log_likelihood_of(self, time: np.ndarray, xy: np.ndarray) -> float:
        """Log density of the fixes after the first given the first (exact Kalman filter).

        Parameters
        ----------
        time : ndarray, shape (n,)
            Strictly increasing times (s).
        xy : ndarray, shape (n, 2)
            Fixes (m); a row with NaN is a missing fix. The first row must be observed.
        """
        time, xy = _track_arrays(time, xy)
        model = _StateSpace(xy, time, estimate_error=False, error_sd=self.error_sd)
        return float(model.loglike(np.array([self.sigma, self.beta]))) + _DIFFUSE_CONSTANT

    def predict(self, time: np.ndarray, xy: np.ndarray, at: np.ndarray) -> CRWPrediction:
        """Smoothed positions at the times ``at`` given the fixes ``(time, xy)``.

        Parameters
        ----------
        time : ndarray, shape (n,)
        xy : ndarray, shape (n, 2)
            As in :meth:`log_likelihood_of`.
        at : ndarray, shape (G,)
            Times (s) at or after the first fix, in any order.
        """
        nodes, model, where = self._nodes(time, xy, at)
        smoothed = model.smooth(np.array([self.sigma, self.beta]))
        mean = smoothed.smoothed_state[:2, where].T
        covariance = smoothed.smoothed_state_cov
        variance = np.stack([covariance[0, 0, where], covariance[1, 1, where]], axis=1)
        return CRWPrediction(np.asarray(at, dtype=float), mean, np.maximum(variance, 0.0))

    def sample_paths(
        self,
        rng: np.random.Generator,
        time: np.ndarray,
        xy: np.ndarray,
        at: np.ndarray,
        n_draws: int,
    ) -> np.ndarray:
        """Positions at the times ``at`` drawn from their distribution given the fixes.

        statsmodels' simulation smoother (Durbin & Koopman 2002) over the time nodes of the
        fixes and of ``at``, fed with normal variates from ``rng``.

        Returns
        -------
        ndarray, shape (n_draws, G, 2)
            Positions (m).
        """
        nodes, model, where = self._nodes(time, xy, at)
        model.update(np.array([self.sigma, self.beta]))
        simulator = model.simulation_smoother()
        draws = np.empty((int(n_draws), where.size, 2))
        for m in range(int(n_draws)):
            simulator.simulate(rng=rng)
            draws[m] = simulator.simulated_state[:2, where].T
        return draws

    def simulate(self, rng: np.random.Generator, time: np.ndarray) -> np.ndarray:
        """True positions at ``time``, starting at the origin with a stationary velocity.

        Parameters
        ----------
        rng : Generator
        time : ndarray, shape (n,)
            Increasing times (s).

        Returns
        -------
        ndarray, shape (n, 2)
            Positions (m), without fix error (add ``error_sd`` noise for fixes).
        """
        time = np.asarray(time, dtype=float)
        matrix, covariance = self.transition(np.diff(time))
        factor = np.linalg.cholesky(covariance)
        state = np.zeros((time.size, 2, 2))  # (time, axis, [position, velocity])
        state[0, :, 1] = rng.normal(0.0, math.sqrt(self.velocity_variance), 2)
        noise = rng.standard_normal((time.size - 1, 2, 2))
        for t in range(time.size - 1):
            state[t + 1] = state[t] @ matrix[t].T + noise[t] @ factor[t].T
        return state[:, :, 0]

    def to_dict(self) -> dict:
        """Plain dict of the parameters and fit statistics."""
        return {
            "sigma": self.sigma,
            "beta": self.beta,
            "error_sd": self.error_sd,
            "log_likelihood": self.log_likelihood,
            "n_obs": self.n_obs,
        }

    def _nodes(self, time, xy, at):
        """State-space model over the fix times and ``at`` merged; node of each ``at``."""
        time, xy = _track_arrays(time, xy)
        at = np.asarray(at, dtype=float)
        if at.size and at.min() < time[0] - _SAME_TIME:
            raise ValueError(f"times to predict start before the first fix ({time[0]} s)")
        candidates = np.unique(np.concatenate([time, at]))
        keep = np.r_[True, np.diff(candidates) > _SAME_TIME]
        nodes = candidates[keep]
        node_xy = np.full((nodes.size, 2), np.nan)
        node_xy[_nearest(nodes, time)] = xy
        model = _StateSpace(node_xy, nodes, estimate_error=False, error_sd=self.error_sd)
        return nodes, model, _nearest(nodes, at)


_DIFFUSE_CONSTANT = math.log(2.0 * math.pi)  # statsmodels' -0.5 log(2 pi) x 2 for the first fix


def _nearest(nodes: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Index of the node at or just before each time (within ``_SAME_TIME``), shape (n,)."""
    return np.searchsorted(nodes, np.asarray(times) + _SAME_TIME, side="right") - 1


def _transition(dt: np.ndarray, sigma, beta) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`CorrelatedRandomWalk.transition` for (possibly complex) ``sigma``, ``beta``."""
    u = beta * dt
    decay = np.exp(-u)
    n = dt.size
    dtype = np.result_type(u, float)
    matrix = np.zeros((n, 2, 2), dtype=dtype)
    matrix[:, 0, 0] = 1.0
    matrix[:, 0, 1] = -np.expm1(-u) / beta
    matrix[:, 1, 1] = decay
    covariance = np.empty((n, 2, 2), dtype=dtype)
    covariance[:, 0, 0] = sigma**2 / beta**3 * _position_variance_factor(u)
    covariance[:, 0, 1] = covariance[:, 1, 0] = sigma**2 / (2.0 * beta**2) * np.expm1(-u) ** 2
    covariance[:, 1, 1] = -(sigma**2) / (2.0 * beta) * np.expm1(-2.0 * u)
    return matrix, covariance


def _track_arrays(time, xy) -> tuple[np.ndarray, np.ndarray]:
    time = np.asarray(time, dtype=float)
    xy = np.asarray(xy, dtype=float)
    if xy.shape != (time.size, 2):
        raise ValueError(f"xy must have shape ({time.size}, 2) to match time, got {xy.shape}")
    if time.size < 2 or np.any(np.diff(time) <= 0) or not np.isfinite(time).all():
        raise ValueError("a CRW needs at least two finite, strictly increasing times")
    if np.isnan(xy[0]).any():
        raise ValueError("the first fix of a track must be observed (x and y not NaN)")
    return time, xy


class _StateSpace(MLEModel):
    """The CRW of one track as a statsmodels state-space model.

    State ``[x, y, v_x, v_y]``; node ``t``'s transition moves the state from node ``t`` to
    node ``t + 1``. Parameters are ``[sigma, beta]`` and, when ``estimate_error``,
    ``error_sd``; the optimiser works on their logs.
    """

    def __init__(self, xy: np.ndarray, time: np.ndarray, *, estimate_error: bool, error_sd=0.0):
        super().__init__(xy, k_states=4, k_posdef=4)
        self.dt = np.r_[np.diff(time), 1.0]  # the last node's transition is never used
        self.estimate_error = estimate_error
        self.error_sd = float(error_sd)
        self["design"] = np.eye(2, 4)
        self["selection"] = np.eye(4)

    @property
    def param_names(self) -> list[str]:
        return ["sigma", "beta", "error_sd"] if self.estimate_error else ["sigma", "beta"]

    def transform_params(self, unconstrained):
        return np.exp(unconstrained)

    def untransform_params(self, constrained):
        return np.log(constrained)

    def update(self, params, **kwargs):
        params = super().update(params, **kwargs)
        sigma, beta = params[0], params[1]
        error_sd = params[2] if self.estimate_error else self.error_sd
        matrix, covariance = _transition(self.dt, sigma, beta)
        eye = np.eye(2)
        # axes independent: each 2 x 2 (position, velocity) block becomes [[a I, b I], [c I, d I]]
        self["transition"] = np.einsum("nij,kl->ikjln", matrix, eye).reshape(4, 4, -1)
        self["state_cov"] = np.einsum("nij,kl->ikjln", covariance, eye).reshape(4, 4, -1)
        self["obs_cov"] = np.eye(2) * error_sd**2
        initialization = Initialization(4)
        initialization.set((0, 2), "diffuse")
        velocity_variance = np.real(sigma**2 / (2.0 * beta))
        initialization.set(
            (2, 4), "known", constant=np.zeros(2), stationary_cov=np.eye(2) * velocity_variance
        )
        self.ssm.initialize(initialization)


def _starting_values(time: np.ndarray, xy: np.ndarray, estimate_error: bool) -> np.ndarray:
    """Rough ``[sigma, beta(, error_sd)]`` from the fixes' apparent velocities.

    ``beta = 1 / median time step`` (velocity correlation over about one step) and ``sigma``
    from the mean squared apparent velocity per axis; the error a tenth of the median
    distance between consecutive fixes.
    """
    observed = ~np.isnan(xy).any(axis=1)
    t, p = time[observed], xy[observed]
    dt = np.diff(t)
    velocity = np.diff(p, axis=0) / dt[:, None]
    beta = 1.0 / np.median(dt)
    variance = max(float(np.mean(velocity**2)), 1e-12)
    start = [math.sqrt(2.0 * beta * variance), beta]
    if estimate_error:
        start.append(max(0.1 * float(np.median(np.hypot(*np.diff(p, axis=0).T))), 1e-6))
    return np.array(start)


def fit_crw(
    time: np.ndarray,
    xy: np.ndarray,
    *,
    error_sd: float | None = None,
    start: tuple[float, ...] | None = None,
    max_iter: int = 500,
) -> CorrelatedRandomWalk:
    """Fit a CRW to one track's fixes by maximum likelihood (exact Kalman filter).

    Parameters
    ----------
    time : ndarray, shape (n,)
        Strictly increasing times (s), irregular spacing allowed.
    xy : ndarray, shape (n, 2)
        Fixes (m); NaN rows are missing fixes; the first row must be observed.
    error_sd : float or None
        Known fix error sd (m; 0 for exact fixes), or None to estimate it.
    start : tuple of float, optional
        Starting ``(sigma, beta)`` or ``(sigma, beta, error_sd)``; by default from the
        fixes' apparent velocities.
    max_iter : int
        Iterations of the L-BFGS optimiser (on the log parameters).

    Returns
    -------
    CorrelatedRandomWalk
        With ``log_likelihood`` (fixes after the first given the first) and ``n_obs``.
    """
    time, xy = _track_arrays(time, xy)
    estimate_error = error_sd is None
    model = _StateSpace(xy, time, estimate_error=estimate_error, error_sd=error_sd or 0.0)
    start = np.asarray(start, dtype=float) if start is not None else None
    if start is None:
        start = _starting_values(time, xy, estimate_error)
    result = model.fit(start, method="lbfgs", maxiter=max_iter, disp=False, cov_type="none")
    params = np.asarray(result.params, dtype=float)
    return CorrelatedRandomWalk(
        sigma=float(params[0]),
        beta=float(params[1]),
        error_sd=float(params[2]) if estimate_error else float(error_sd),
        log_likelihood=float(result.llf) + _DIFFUSE_CONSTANT,
        n_obs=int((~np.isnan(xy).any(axis=1)).sum()),
    )


# ---------------------------------------------------------------------------------------------
# Tracks tables: one CRW per segment, predictions and draws on the regular grid
# ---------------------------------------------------------------------------------------------


def _segment_labels(tracks: pd.DataFrame) -> pd.Series:
    return tracks["segment"] if "segment" in tracks.columns else tracks["id"].astype(str)


def _segment_fixes(tracks: pd.DataFrame):
    """``(segment, time (n,), xy (n, 2))`` per segment, from its first observed fix on."""
    labels = _segment_labels(tracks)
    for name in pd.unique(labels):
        rows = tracks[(labels == name).to_numpy()]
        time = rows["time"].to_numpy(dtype=float)
        xy = rows[["x", "y"]].to_numpy(dtype=float)
        observed = np.flatnonzero(~np.isnan(xy).any(axis=1))
        if observed.size < 2:
            raise ValueError(f"segment {name!r} has fewer than two observed fixes")
        yield name, time[observed[0] :], xy[observed[0] :]


def fit_tracks(tracks: pd.DataFrame, *, error_sd: float | None = None) -> dict:
    """One CRW per segment of a tracks table (``crawl`` fits each animal on its own).

    Parameters
    ----------
    tracks : DataFrame
        Tracks table (``id``, ``time`` s, ``x``, ``y`` m, optional ``segment``).
    error_sd : float or None
        As in :func:`fit_crw`.

    Returns
    -------
    dict
        ``{segment: CorrelatedRandomWalk}`` in order of first appearance.
    """
    track_maths.validate_tracks(tracks, min_fixes=2)
    return {name: fit_crw(time, xy, error_sd=error_sd) for name, time, xy in _segment_fixes(tracks)}


def _grid(tracks: pd.DataFrame, step: float, models: dict | None, error_sd: float | None):
    """The regular grid table of :func:`hmmtrack.tracks.regularise` and the models."""
    if models is None:
        models = fit_tracks(tracks, error_sd=error_sd)
    grid = track_maths.regularise(tracks, step)
    return grid, models, grid["segment"].to_numpy()


def regularise(
    tracks: pd.DataFrame,
    step: float,
    *,
    models: dict | None = None,
    error_sd: float | None = None,
) -> pd.DataFrame:
    """Positions on a regular time grid predicted by each segment's CRW, with uncertainty.

    Parameters
    ----------
    tracks : DataFrame
        Tracks table (``id``, ``time`` s, ``x``, ``y`` m, optional ``segment``); irregular
        times and missing fixes (NaN) allowed.
    step : float
        Grid step (s); the grid of each segment is that of
        :func:`hmmtrack.tracks.regularise` (first fix, then every ``step`` s).
    models : dict, optional
        ``{segment: CorrelatedRandomWalk}``; fitted with :func:`fit_tracks` when absent.
    error_sd : float or None
        Passed to :func:`fit_tracks` when the models are fitted here.

    Returns
    -------
    DataFrame
        The table of :func:`hmmtrack.tracks.regularise` (extra columns interpolated there)
        with ``x``, ``y`` the smoothed positions (m) and ``sd_x``, ``sd_y`` their standard
        deviations (m). ``attrs["crw"]`` holds each segment's ``CorrelatedRandomWalk.to_dict``.
    """
    grid, models, segment = _grid(tracks, step, models, error_sd)
    sd = np.full((len(grid), 2), np.nan)
    mean = np.full((len(grid), 2), np.nan)
    for name, time, xy in _segment_fixes(tracks):
        rows = np.flatnonzero(segment == name)
        prediction = models[name].predict(time, xy, grid["time"].to_numpy()[rows])
        mean[rows], sd[rows] = prediction.mean, np.sqrt(prediction.variance)
    grid["x"], grid["y"], grid["sd_x"], grid["sd_y"] = mean[:, 0], mean[:, 1], sd[:, 0], sd[:, 1]
    grid.attrs["crw"] = {name: model.to_dict() for name, model in models.items()}
    return grid


def impute(
    tracks: pd.DataFrame,
    step: float,
    n_draws: int,
    rng: np.random.Generator,
    *,
    models: dict | None = None,
    error_sd: float | None = None,
) -> list[pd.DataFrame]:
    """Tracks on a regular time grid drawn from each segment's CRW given its fixes.

    The tracks of a multiple imputation (crawl's ``crwSimulator`` / momentuHMM's
    ``MIfitHMM``): each draw is a whole track from the smoothing distribution, so that
    models fitted to the draws carry the uncertainty of the positions between fixes.

    Parameters
    ----------
    tracks, step, models, error_sd
        As in :func:`regularise`.
    n_draws : int
        Number of imputed tracks ``M``.
    rng : Generator

    Returns
    -------
    list of DataFrame, length ``n_draws``
        Tables like :func:`hmmtrack.tracks.regularise`'s with drawn ``x``, ``y`` (m), ready
        for :func:`hmmtrack.tracks.prepare`.
    """
    grid, models, segment = _grid(tracks, step, models, error_sd)
    draws = np.full((int(n_draws), len(grid), 2), np.nan)
    for name, time, xy in _segment_fixes(tracks):
        rows = np.flatnonzero(segment == name)
        at = grid["time"].to_numpy()[rows]
        draws[:, rows] = models[name].sample_paths(rng, time, xy, at, n_draws)
    return [grid.assign(x=d[:, 0], y=d[:, 1]) for d in draws]
