"""The particle filter that localises an acoustic tag: predict every second, correct on data.

:class:`ParticleFilter` runs the paper's Algorithms 1 and 2 with pluggable parts:

* a motion model (:mod:`hmmtrack.tracking.motion`) moves the particles every ``dt`` (1 s) seconds;
* a measurement model (:class:`hmmtrack.tracking.measurement.base.Measurement`, or any object
  with ``loglik(particles, obs, time) -> (N,)``) weighs them when observations arrive,
  through its optional hooks when it has them: fields of its own on the particles and a
  per-run state (``start``), a matrix form of the observations (``as_matrix``), a
  correction with steps of its own (``score``), a recovery from degenerate weights
  (``recover``);
* a correction policy (:mod:`hmmtrack.tracking.tempering`) applies the log-likelihood:
  :class:`~hmmtrack.tracking.tempering.Plain` by default, whose log weights are normalised by
  their log-sum-exp (no underflow: only weights that are all ``-inf``, every particle
  impossible, are degenerate -- they are recovered, never NaN), or
  :class:`~hmmtrack.tracking.tempering.Tempered`;
* a resampling scheme (:mod:`hmmtrack.tracking.resampling`) runs after every correction
  (``resample_when="always"``, the paper) or when the effective sample size falls below
  ``ess_threshold * N`` (``"ess"``).

Each second it reports an :class:`Estimate`: the weighted mean position, the x-y
covariance, ``sqrt_lambda1`` (square root of its largest eigenvalue, the paper's
convergence measure) and the effective sample size.

Online use: ``pf.step(t, observations)`` advances to time ``t`` and returns the estimate
there. Offline use: ``pf.iterate(observations, start, end)`` yields one estimate per second
and ``pf.run(...)`` collects them into a :class:`FilterResult` with optional particle
snapshots, the list of events (degenerate weights and how they were recovered,
observations outside the time window) and the tables of the collectors (``collect=``:
:mod:`hmmtrack.tracking.diagnostics`, :class:`hmmtrack.tracking.smoothing.Smoothed`), which
the filter calls at fixed points of a run.

Speed: between observations nothing but prediction happens, so the seconds up to the next
observation are predicted in one compiled call (``motion.advance``) that also returns the
per-second moments; with ``backend="numpy"`` every second is one call of
``motion.propagate`` instead (the reference path, and the one for motion models without a
compiled kernel). The compiled path draws from per-particle random streams, so one seed
gives one answer whatever the number of threads; by default the number of threads is chosen
by timing one thread against all (:class:`ThreadChoice`; a prediction with the correction
and resampling after it), because on a shared machine more threads are often slower. A
correction is two compiled calls: the log-likelihood, the normalisation, the moments and
the ESS in one (:func:`hmmtrack.tracking.compiled.weighing.weigh`, the log-likelihood in
its first pass when the measurement offers ``loglik_terms``, else a call before it), and
the resampling's inverse CDF merged with the gather into the spare particle arrays in one
pass per chunk (an inverse-CDF scheme's :data:`~hmmtrack.tracking.resampling.POINTS`
draw; after its serial cumulative sums), on the threads of the latest prediction from
:data:`PARALLEL_MIN_CORRECTION` particles;
:meth:`ParticleFilter.iterate` converts all observations once to the measurement model's
matrix form when the model offers one (``as_matrix``) instead of slicing a table at every
correction. After each resampling :attr:`ParticleFilter.last_ancestors` holds the ancestor
indices (for smoothers).

Observations are assigned to the nearest prediction time (``start + k dt``); with
``dt = 1 s`` the particles are at most 0.5 s away from the observation's time.

This module does not read files or build observations (:mod:`hmmtrack.tracking.pipeline` does).
"""

from __future__ import annotations

import itertools
import time as clock
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numba
import numpy as np
import pandas as pd

from hmmtrack.random import SeedLike, as_generator
from hmmtrack.tracking.compiled import streams as rs
from hmmtrack.tracking.compiled.chunks import default_threads
from hmmtrack.tracking.compiled.threads import ThreadChoice
from hmmtrack.tracking.compiled.weighing import weigh
from hmmtrack.tracking.measurement.base import Score
from hmmtrack.tracking.particles import Particles, as_bounds, sqrt_largest_eigenvalue
from hmmtrack.tracking.resampling import POINTS, RESAMPLERS, Inversion, Scratch, get_resampler
from hmmtrack.tracking.settings import (
    Settings,
    boolean,
    fraction,
    number,
    one_of,
    positive,
    positive_integer,
    setting,
)
from hmmtrack.tracking.tempering import Plain

__all__ = [
    "DEFAULT_FILTER",
    "ESTIMATE_COLUMNS",
    "Estimate",
    "FILTERS",
    "FilterResult",
    "FilterSettings",
    "ParticleFilter",
]


#: columns of the estimates table (docs/interfaces.md plus the effective sample size)
ESTIMATE_COLUMNS = ("time", "x", "y", "var_x", "var_y", "cov_xy", "sqrt_lambda1", "n_eff")
#: rows per table handed to an estimates sink (:meth:`ParticleFilter.run`): under 1 MB
ESTIMATE_ROWS = 10_000
#: below this many particle-steps per compiled call the default is one thread (too short
#: for more threads to pay); above it the filter times one and all threads and keeps the
#: faster (pass ``threads=`` to fix the number)
PARALLEL_MIN_WORK = 20_000
#: from this many particles corrections and resamplings run on the threads of the prediction
#: before them, so the timed choice of one thread or all (:class:`ThreadChoice`, which times
#: each prediction with the correction after it) decides them too; below it their chunked
#: passes are too short for thread hand-overs to pay, and they run on one thread
#: (reports/decisions.md, "Corrections on the timed threads from 10,000 particles")
PARALLEL_MIN_CORRECTION = 10_000
#: the named filters (the ``filter`` section's ``name``): the switches of
#: :class:`FilterSettings` each sets. ``paper``: the paper's filter (particles uniform in
#: the search box, the whole cloud resampled, no monitor); ``mode-keeping``: issue 13's
#: (particles drawn from the first corrections' likelihood, every mode kept by mixture
#: resampling, re-acquired after a long gap; reports/decisions.md, "Mode-keeping filter"
#: and "The long gap in the default filter"); ``acquired``: the paper's started from the
#: first corrections' likelihood (the ping measurement's: reports/decisions.md, "Finding a
#: random-interval tag on three moorings"). The lost-tag test (``monitor``) is in none: on
#: the shark pursuit it re-acquires onto the mirror as often as onto the tag
FILTERS = {
    "paper": {"acquisition": False, "mixture": False, "long_gap": False, "monitor": False},
    "mode-keeping": {"acquisition": True, "mixture": True, "long_gap": True, "monitor": False},
    "acquired": {"acquisition": True, "mixture": False, "long_gap": False, "monitor": False},
}
#: the filter whose switches are :class:`FilterSettings`' defaults, run by a configuration
#: that names none, for every measurement: it keeps both intersections of two rings where
#: the paper's lets resampling drift pick one (reports/decisions.md, "The library's default
#: filter"); callers that must run the paper's filter (the golden runs, the reproduction's
#: paper rows) name ``"paper"``
DEFAULT_FILTER = "mode-keeping"
BACKENDS = ("auto", "numba", "numpy")
#: the particle fields a motion model's ``initialise`` sets (besides the position and weight)
_MOTION_FIELDS = (
    "heading", "cos_heading", "sin_heading", "speed", "turn_rate", "state", "time_since_draw",
)  # fmt: skip
RESAMPLE_WHEN = ("always", "ess")


class Estimate(NamedTuple):
    """The filter's summary at one time.

    Attributes
    ----------
    time : float
        s (UTC epoch seconds).
    x, y : float
        Weighted mean position, m.
    var_x, var_y, cov_xy : float
        Weighted x-y covariance of the particles, m^2.
    sqrt_lambda1 : float
        Square root of the covariance's largest eigenvalue, m.
    n_eff : float
        Effective sample size of the weights (N right after resampling).
    """

    time: float
    x: float
    y: float
    var_x: float
    var_y: float
    cov_xy: float
    sqrt_lambda1: float
    n_eff: float


def _estimates(
    start: float, dt: float, origin, moments: np.ndarray, n_eff: float
) -> list[Estimate]:
    """Estimates at the times ``start + k dt`` (s), ``k = 1..K``, from weighted moments
    ``(K, 5)`` of positions relative to ``origin``: mean x, mean y, mean x^2, mean y^2, mean
    xy (plain floats throughout, the times too: made every second of a run)."""
    x0, y0, n_eff = float(origin[0]), float(origin[1]), float(n_eff)
    start, dt = float(start), float(dt)
    estimates = []
    for k, (mx, my, sxx, syy, sxy) in enumerate(moments.tolist(), 1):
        var_x, var_y, cov_xy = max(sxx - mx * mx, 0.0), max(syy - my * my, 0.0), sxy - mx * my
        sqrt_lambda1 = sqrt_largest_eigenvalue(var_x, var_y, cov_xy)
        estimates.append(
            Estimate(start + k * dt, x0 + mx, y0 + my, var_x, var_y, cov_xy, sqrt_lambda1, n_eff)
        )
    return estimates


def _estimate(time, mean_x, mean_y, var_x, var_y, cov_xy, n_eff) -> Estimate:
    """One :class:`Estimate` from the weighted mean and covariance (plain floats, no arrays:
    the correction's estimate is made 900 times in an hour's run)."""
    time, mean_x, mean_y, var_x, var_y, cov_xy, n_eff = map(
        float, (time, mean_x, mean_y, var_x, var_y, cov_xy, n_eff)
    )
    sqrt_lambda1 = sqrt_largest_eigenvalue(var_x, var_y, cov_xy)
    return Estimate(time, mean_x, mean_y, var_x, var_y, cov_xy, sqrt_lambda1, n_eff)


def _estimate_table(estimates: list[Estimate]) -> pd.DataFrame:
    """The table of ``estimates`` (one row each, :data:`ESTIMATE_COLUMNS`, float64): their
    floats read into one array (half the time of building the table from the tuples)."""
    width = len(ESTIMATE_COLUMNS)
    values = np.fromiter(
        (value for estimate in estimates for value in estimate),
        dtype=np.float64,
        count=len(estimates) * width,
    )
    return pd.DataFrame(values.reshape(-1, width), columns=list(ESTIMATE_COLUMNS))


def _weight_summary(x, y, log_weight, threads: int = 1):
    """Normalised weights (N,) and the weighted mean, covariance and ESS
    (:func:`hmmtrack.tracking.compiled.weighing.weigh` on ``threads`` threads).

    Returns ``(weights, log_total, mean_x, mean_y, var_x, var_y, cov_xy, n_eff)`` with
    ``log_total`` the log-sum-exp of ``log_weight`` (all ``-inf`` count as equal); the same
    numbers as ``np.average`` / ``np.cov(..., aweights=w, bias=True)`` and
    :func:`hmmtrack.tracking.resampling.effective_sample_size` (tested).
    """
    status, _, weights, log_total, summary = weigh(log_weight, None, x, y, threads)
    if status == 2:  # every particle impossible: all equally so (never NaN)
        _, _, weights, log_total, summary = weigh(np.zeros(log_weight.size), None, x, y, threads)
    return weights, log_total, *summary


def _weigh(log_weight, loglik, x, y, threads: int = 1, out=None, scored=None):
    """The correction's arithmetic: add ``loglik`` to the log weights, normalise them, and
    return the normalised weights, moments and ESS
    (:func:`hmmtrack.tracking.compiled.weighing.weigh` on ``threads`` threads, into the
    arrays ``out`` when given; with ``scored``, the log-likelihood computed into ``loglik``
    first).

    Returns ``(status, log_weight, weights, mean_x, mean_y, var_x, var_y, cov_xy, n_eff)``
    where ``status`` is 0 (done), 1 (``loglik`` has NaN or ``+inf``) or 2 (every particle
    impossible); the rest is meaningful only when ``status == 0``. Equal to
    :func:`hmmtrack.tracking.resampling.log_normalise` and :func:`_weight_summary` (tested).
    """
    status, updated, weights, _, summary = weigh(log_weight, loglik, x, y, threads, out, scored)
    if status:
        return status, None, None, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    return 0, updated, weights, *summary


def _weighted_moments(p: Particles, weights: np.ndarray, origin) -> np.ndarray:
    """Weighted moments (5,) of positions relative to ``origin`` (as the compiled kernels)."""
    dx = p.x - origin[0]
    dy = p.y - origin[1]
    return np.array(
        [weights @ dx, weights @ dy, weights @ (dx * dx), weights @ (dy * dy), weights @ (dx * dy)]
    )


def _loglik_terms(measurement):
    """The measurement's ``loglik_terms`` hook (the arguments of its compiled per-chunk
    log-likelihood, :func:`hmmtrack.tracking.compiled.weighing.chunk_loglik`), unless it has
    none or its class overrides ``loglik`` below the class that defines the hook (a subclass
    that scores differently is scored by its ``loglik``)."""
    if getattr(measurement, "loglik_terms", None) is None:
        return None
    mro = type(measurement).__mro__
    owner = {name: next(c for c in mro if name in vars(c)) for name in ("loglik", "loglik_terms")}
    return measurement.loglik_terms if owner["loglik"] is owner["loglik_terms"] else None


def _as_numbers(column: pd.Series) -> np.ndarray:
    """A column's values as float64, NaN where they are not numbers (``pd.to_numeric``'s
    coercion, which only columns of other than NumPy's numeric dtypes need: most of a short
    run's checking time otherwise)."""
    if not (isinstance(column.dtype, np.dtype) and column.dtype.kind in "fiub"):
        column = pd.to_numeric(column, errors="coerce")
    return column.to_numpy(dtype=np.float64)


def _n_rows(obs) -> int:
    """Number of observations in a DataFrame or a mapping of equal-length columns."""
    if isinstance(obs, pd.DataFrame):
        return len(obs)
    return len(np.atleast_1d(next(iter(obs.values())))) if len(obs) else 0


@dataclass
class FilterResult:
    """What :meth:`ParticleFilter.run` returns.

    Attributes
    ----------
    estimates : pandas.DataFrame or None
        One row per second, columns :data:`ESTIMATE_COLUMNS`; ``None`` when the run handed
        them to a sink (``run(..., estimates_to=...)``) instead of keeping them.
    snapshots : dict of float to pandas.DataFrame
        Particles (x, y, heading, speed, turn_rate, state, weight) at each requested time,
        taken after the correction and before resampling.
    events : pandas.DataFrame
        Columns ``time``, ``kind``, ``detail``: degenerate weights and their recovery,
        observations outside the time window, the measurement's events.
    collected : dict of str to pandas.DataFrame
        The collectors' tables by name (``smoothed``, ``ambiguity``, ``clock``, ...).
    """

    estimates: pd.DataFrame | None
    snapshots: dict[float, pd.DataFrame] = field(default_factory=dict)
    events: pd.DataFrame = field(
        default_factory=lambda: pd.DataFrame(columns=["time", "kind", "detail"])
    )
    collected: dict[str, pd.DataFrame] = field(default_factory=dict)


class ParticleFilter:
    """Particle filter with pluggable motion, measurement and resampling.

    Parameters
    ----------
    motion
        Motion model with ``initialise(rng, particles)``, ``propagate(rng, particles, dt)``
        and, for the compiled path, ``compiled`` and ``advance(...)``
        (:mod:`hmmtrack.tracking.motion`).
    measurement
        Object with ``loglik(particles, obs, time) -> (N,)``; an optional attribute
        ``columns`` lists the observation columns it needs (checked up front), and the
        optional hooks of :class:`hmmtrack.tracking.measurement.base.Measurement` are used
        when present.
    n_particles : int
        Number of particles ``N``.
    bounds : (xmin, xmax, ymin, ymax)
        Search box for the uniform initialisation (m).
    resampling : str
        Scheme name from :data:`hmmtrack.tracking.resampling.RESAMPLERS` (default multinomial, the
        paper's).
    resample_when : {"always", "ess"}
        Resample after every correction (the paper), or only when the effective sample
        size falls below ``ess_threshold * N``.
    ess_threshold : float
        Fraction of ``N`` in ``(0, 1]`` used by ``resample_when="ess"``.
    rng : int, SeedSequence, Generator or None
        Seed of every random draw of the filter (initialisation, prediction, resampling).
    dt : float
        Prediction step, s (the paper: 1 s).
    backend : {"auto", "numba", "numpy"}
        ``"auto"`` uses the motion model's compiled kernel when it has one.
    threads : int or None
        Threads for compiled prediction; ``None`` uses one thread for small calls (fewer
        than :data:`PARALLEL_MIN_WORK` particle-steps) and otherwise whichever of one
        thread and ``numba.get_num_threads()`` (when the filter is made) was faster per
        particle-step in the latest side-by-side trial (:class:`ThreadChoice`), each
        prediction timed with the correction and resampling that follow it; corrections
        and resamplings of at least :data:`PARALLEL_MIN_CORRECTION` particles run on the
        threads of the latest prediction. Results do not depend on it.
    correction : Plain, Tempered or None
        Correction policy (:mod:`hmmtrack.tracking.tempering`); ``None``: :class:`Plain`.
    collect : sequence of collectors
        Called at fixed points of a run (:mod:`hmmtrack.tracking.diagnostics`); their
        tables are :attr:`FilterResult.collected`.
    mixture : Mixture or None
        Mode-preserving resampling (:class:`hmmtrack.tracking.mixture.Mixture`: each
        component of the cloud resampled on its own, with the ``resampling`` scheme);
        ``None``: the whole cloud at once (the paper).
    acquisition : Acquisition or None
        Draw the initial particles of :meth:`iterate` from the likelihood of the first
        corrections (:class:`hmmtrack.tracking.acquisition.Acquisition`); ``None``:
        uniformly in the bounds (the paper).
    monitor : Monitor or None
        Test every correction for a long gap since the previous one and (with its ``loss``
        rule) for a lost tag, and re-acquire (:class:`hmmtrack.tracking.monitor.Monitor`);
        ``None``: no test.

    Notes
    -----
    A resampling gathers the new particles into the arrays of the particles from before the
    previous resampling (no fresh arrays): :attr:`particles` held from outside stay valid
    until the next resampling but one; keep a :meth:`Particles.copy` for longer. Likewise a
    correction writes the log weights and weights into reused arrays: those of one
    correction stay valid through the next.

    Attributes
    ----------
    scratch : hmmtrack.tracking.resampling.Scratch
        The resampling's reused work arrays and thread count, shared with the mixture's
        per-component resampling.
    """

    def __init__(
        self,
        motion,
        measurement,
        n_particles: int,
        bounds,
        resampling: str = "multinomial",
        resample_when: str = "always",
        ess_threshold: float = 0.5,
        rng: SeedLike = None,
        dt: float = 1.0,
        backend: str = "auto",
        threads: int | None = None,
        correction=None,
        collect: Sequence = (),
        mixture=None,
        acquisition=None,
        monitor=None,
    ) -> None:
        if int(n_particles) != n_particles or n_particles < 1:
            raise ValueError(f"n_particles must be a positive integer, got {n_particles!r}")
        if resample_when not in RESAMPLE_WHEN:
            raise ValueError(f"resample_when must be one of {RESAMPLE_WHEN}, got {resample_when!r}")
        if not 0.0 < ess_threshold <= 1.0:
            raise ValueError(f"ess_threshold must be in (0, 1], got {ess_threshold}")
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt}")
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        compiled = bool(getattr(motion, "compiled", False))
        if backend == "numba" and not compiled:
            raise ValueError(f"{type(motion).__name__} has no compiled kernel; use backend='numpy'")
        self.motion = motion
        self.measurement = measurement
        self.n_particles = int(n_particles)
        self.bounds = as_bounds(bounds)
        self.resampling = resampling
        # an inverse-CDF scheme's draw alone (its points, merged in the pass that gathers
        # the new particles: see resample), else the scheme
        self._resample = POINTS.get(resampling) or get_resampler(resampling)
        # the resampling's work arrays, reused (see resample)
        self.scratch = Scratch()
        self.resample_when = resample_when
        self.ess_threshold = float(ess_threshold)
        self.rng = as_generator(rng)
        self.dt = float(dt)
        self.compiled = compiled and backend != "numpy"
        self.threads = threads
        self.correction = Plain() if correction is None else correction
        self.collect = tuple(collect)
        self.mixture = mixture
        self.acquisition = acquisition
        self.monitor = monitor
        self._every_step = any(c.every_step for c in self.collect)
        self._start = getattr(measurement, "start", None)
        self._as_matrix = getattr(measurement, "as_matrix", None)
        self._score = getattr(measurement, "score", None)
        # the measurement's arguments of its compiled per-chunk log-likelihood, when it has
        # one and the correction is the plain one: the log-likelihood is then computed in
        # the weighing's first pass (one parallel region and one pass over the particles
        # less; the same values)
        fused = self._score is None and type(self.correction) is Plain
        self._loglik_terms = _loglik_terms(measurement) if fused else None
        # numba's thread count of this thread (``numba.set_num_threads``: 1 in the worker
        # processes of hmmtrack.experiments.executors, which run one trial per core)
        self._thread_choice = ThreadChoice(numba.get_num_threads())
        # threads of the latest compiled prediction (else ``threads`` or one): the
        # corrections' too from PARALLEL_MIN_CORRECTION particles (see correction_threads)
        self._threads_in_use = 1 if threads is None else threads
        # (threads, start, particle-steps) of the timed prediction under way: the thread
        # choice is told the cost of each prediction with the correction and resampling that
        # follow it, when the next prediction starts
        self._cycle: tuple[int, float, int] | None = None
        self.particles: Particles | None = None
        self.time: float | None = None
        self.events: list[dict] = []
        self._streams: np.ndarray | None = None
        # the particles before the latest resampling: the arrays the next one gathers into
        # (Particles.take's ``out``), so that a resampling allocates no particle arrays
        self._spare: Particles | None = None
        self._equal: np.ndarray | None = None  # see _equal_weights
        # two pairs of arrays that corrections write their log weights and weights into
        # (see _buffers): a correction allocates no arrays of N entries
        self._correction_arrays: tuple | None = None
        # the array a fused correction writes its log-likelihood into (see _scored_correction)
        self._loglik: np.ndarray | None = None
        #: ancestor indices (N,) of the last resampling (None before any); read by smoothers
        self.last_ancestors: np.ndarray | None = None
        #: with a mixture, its components' weight, mean and covariance (K, 6) after the last
        #: resampling (:meth:`hmmtrack.tracking.mixture.Mixture.finish`); read by
        #: :class:`hmmtrack.tracking.mixture.Modes`
        self.component_moments: np.ndarray | None = None
        #: the measurement's state of this run (its ``start`` hook's; None without one)
        self.measurement_state = None
        # (log weights, normalised weights, ESS, a point inside the cloud) after the last
        # correction or resampling, reused while the particles carry that very log-weight
        # array (the filter and its correction policies replace log weights, never edit them
        # in place)
        self._weighed: tuple[np.ndarray, np.ndarray, float, tuple[float, float]] | None = None
        # whether the particles at self.time may still change (see _settle)
        self._unsettled = False

    # ------------------------------------------------------------------ state

    def initialise(self, time: float) -> Estimate:
        """Algorithm 1 at ``time``: particles uniform in the bounds, equal weights; the
        motion model's ``initialise`` sets their motion fields (at rest for the baseline
        and velocity models, drawn from the fitted model for the HMM); the measurement's
        ``start`` hook creates its fields and its run state; the correction policy and the
        collectors start."""
        self.particles = Particles.uniform(self.rng, self.n_particles, self.bounds)
        self.motion.initialise(self.rng, self.particles)
        self._streams = rs.new_streams(self.rng, self.n_particles)
        self._spare = None
        self._cycle = None
        self.time = float(time)
        self.events = []
        self.last_ancestors = None
        self.component_moments = None
        self._weighed = None
        estimate = self.estimate()
        if self._start is not None:
            self.measurement_state = self._start(self.particles, self.time, self.dt)
        if self.mixture is not None:
            self.mixture.initialised(self)
        if self.monitor is not None:
            self.monitor.start(self)
        self.correction.initialised(self)
        for collector in self.collect:
            collector.start(self)
        self._unsettled = True
        return estimate

    def estimate(self) -> Estimate:
        """Weighted estimate of the current particles at the current time."""
        p = self._require_particles()
        summary = _weight_summary(p.x, p.y, p.log_weight, self.correction_threads())
        return _estimate(self.time, *summary[2:])

    def _require_particles(self) -> Particles:
        if self.particles is None:
            raise RuntimeError("the filter has no particles yet: call initialise(time) or step()")
        return self.particles

    # ------------------------------------------------------------------ predict

    def predict(self, n_steps: int) -> list[Estimate]:
        """Move the particles ``n_steps`` prediction steps; the estimate after each step.

        One step at a time when a collector asks for every step (``every_step``)."""
        self._require_particles()
        if n_steps <= 0:
            return []
        if not self._every_step:
            self._unsettled = True
            return self._predict(n_steps)
        estimates = []
        for _ in range(n_steps):
            self._settle()
            estimates += self._predict(1)
            self._unsettled = True
        return estimates

    def _predict(self, n_steps: int) -> list[Estimate]:
        p = self.particles
        weights, n_eff, origin = self.weights()
        if self.compiled:
            moments = self._advance(p, n_steps, weights, origin)
        else:
            moments = np.empty((n_steps, 5))
            for k in range(n_steps):
                self.motion.propagate(self.rng, p, self.dt)
                moments[k] = _weighted_moments(p, weights, origin)
        start = self.time
        self.time = start + n_steps * self.dt
        return _estimates(start, self.dt, origin, moments, n_eff)

    def weights(self) -> tuple[np.ndarray, float, tuple[float, float]]:
        """Normalised weights (N,), their ESS and the weighted mean position (m) -- from the
        last correction or resampling when the log weights are still those."""
        p = self.particles
        if self._weighed is not None and self._weighed[0] is p.log_weight:
            return self._weighed[1:]
        weights, _, mean_x, mean_y, _, _, _, n_eff = _weight_summary(
            p.x, p.y, p.log_weight, self.correction_threads()
        )
        return weights, n_eff, (mean_x, mean_y)

    def _advance(self, p: Particles, n_steps: int, weights: np.ndarray, origin) -> np.ndarray:
        work = p.n * n_steps
        started = clock.perf_counter()
        if self._cycle is not None:  # the previous cycle ends here, before the next choice
            last_threads, last_started, last_work = self._cycle
            self._thread_choice.record(last_threads, (started - last_started) / last_work)
        threads = self.threads
        if threads is None:
            threads = 1 if work < PARALLEL_MIN_WORK else self._thread_choice.pick()
        threads = min(threads, numba.config.NUMBA_NUM_THREADS)
        self._threads_in_use = threads
        timed = self.threads is None and work >= PARALLEL_MIN_WORK
        self._cycle = (threads, started, work) if timed else None
        return self.motion.advance(
            p, self._streams, n_steps, self.dt, weights, origin, threads=threads
        )

    def correction_threads(self) -> int:
        """Threads of corrections and resamplings: the latest prediction's from
        :data:`PARALLEL_MIN_CORRECTION` particles, else one."""
        return self._threads_in_use if self.n_particles >= PARALLEL_MIN_CORRECTION else 1

    # ------------------------------------------------------------------ correct

    def correct(self, obs) -> Estimate:
        """Weigh the particles by the observations ``obs`` made now; the weighted estimate.

        Resampling is not done here (see :meth:`resample_if_due`). Degenerate weights (every
        particle impossible) are recovered as described in :meth:`_recover`.
        """
        self._require_particles()
        rows = obs if self._as_matrix is None else self._as_matrix(obs)
        return self._correct(rows, lambda: obs)

    def _correct(self, rows, table) -> Estimate:
        """One correction with ``rows`` (the measurement's form of the observations);
        ``table()`` returns them as a table (only built when needed: for an error message
        or a recovery).

        The measurement scores (its ``score`` hook, else ``loglik``), the correction policy
        applies the log-likelihood, the measurement commits (``Score.commit``) and moves the
        particles (``Score.move``, the estimate then taken again), the collectors record.
        On more than one thread, the correction runs the measurement's chunked kernels on
        its threads too
        (:func:`~hmmtrack.tracking.compiled.chunks.default_threads`); on one, they run on
        their own default (the range-rate log-likelihood on one thread, the ping
        measurement's on all of numba's)."""
        threads = self.correction_threads()
        if threads == 1:  # the kernels keep their own default (no block to enter and leave)
            return self._scored_correction(rows, table)
        with default_threads(threads):
            return self._scored_correction(rows, table)

    def _scored_correction(self, rows, table) -> Estimate:
        """:meth:`_correct`'s steps; with a measurement that offers ``loglik_terms`` and the
        plain correction, the log-likelihood is computed in the weighing's first pass
        (:func:`hmmtrack.tracking.compiled.weighing.weigh`'s ``scored``)."""
        p = self.particles
        measurement = self.measurement
        time = self.time
        if self._loglik_terms is not None:
            prior = None if self.monitor is None else self.monitor.before(self)
            if self._loglik is None or self._loglik.size != p.n:
                self._loglik = np.empty(p.n)
            loglik = self._loglik
            estimate = self.weigh(loglik, table, self._loglik_terms(p, rows, time))
        else:
            if self._score is None:
                score = Score(
                    measurement.loglik(p, rows, time=time),
                    rescore=lambda particles, weights: measurement.loglik(
                        particles, rows, time=time
                    ),
                )
            else:
                score = self._score(p, rows, time, self.measurement_state, self.weights()[0])
            for kind, detail in score.events:
                self._record(kind, detail)
            prior = None if self.monitor is None else self.monitor.before(self)
            estimate = self.correction.correct(self, score, table)
            if score.commit is not None:
                score.commit(self.particles)
            if score.move is not None:
                score.move(self.particles, self.rng)
                estimate = self.estimate()
            loglik = score.loglik
        if self.monitor is not None and self.monitor.corrected(self, loglik, prior, rows):
            estimate = self.estimate()
        for collector in self.collect:
            collector.corrected(self)
        return estimate

    def weigh(self, loglik, rows, scored=None) -> Estimate:
        """Add ``loglik`` (N,) to the log weights and normalise (one compiled call); recover
        from degenerate weights. ``rows()`` returns the observations (only built when
        needed: for an error message or a recovery). With ``scored``, the measurement's
        ``loglik_terms``, the log-likelihood is computed in the same call, into ``loglik``
        (a float64 array (N,))."""
        p = self.particles
        loglik = np.asarray(loglik, dtype=np.float64)
        if loglik.shape != (p.n,):
            raise ValueError(
                f"{type(self.measurement).__name__}.loglik returned shape {loglik.shape}, "
                f"expected ({p.n},), at time {self.time} for observations:\n{rows()}"
            )
        status, log_weight, weights, *moments, n_eff = _weigh(
            p.log_weight, loglik, p.x, p.y, self.correction_threads(), self._buffers(p), scored
        )
        if status == 1:
            raise ValueError(
                f"{type(self.measurement).__name__}.loglik returned NaN/+inf values "
                f"at time {self.time} for observations:\n{rows()}"
            )
        if status == 2:
            self._recover(rows())
            return self.estimate()
        p.log_weight = log_weight
        self._weighed = (log_weight, weights, n_eff, (moments[0], moments[1]))
        return _estimate(self.time, *moments, n_eff)

    def _buffers(self, p: Particles) -> tuple[np.ndarray, np.ndarray]:
        """Arrays (N,) for :meth:`weigh`'s log weights and weights, reused: of two pairs,
        the log-weight array that ``p`` does not hold and the weight array that
        :meth:`weights` does not return (so that both are read intact during the call, and
        the weights of the previous correction stay valid through this one)."""
        n = p.n
        if self._correction_arrays is None or self._correction_arrays[0][0].size != n:
            self._correction_arrays = tuple((np.empty(n), np.empty(n)) for _ in range(2))
        (log_a, weights_a), (log_b, weights_b) = self._correction_arrays
        kept = None if self._weighed is None else self._weighed[1]
        return (log_b if p.log_weight is log_a else log_a), (
            weights_b if kept is weights_a else weights_a
        )

    def _recover(self, obs) -> None:
        """Re-initialise after degenerate weights; warn and record the event.

        First as the measurement's ``recover`` hook places them (the range-rate
        measurement: on a range ring); if it has none or cannot, uniformly in the bounds
        with equal weights (the motion fields re-drawn, other fields kept).
        """
        p = self.particles
        recover = getattr(self.measurement, "recover", None)
        action = None if recover is None else recover(p, obs, self.time, self.rng)
        if action is None:
            action = "reinitialised uniformly in the bounds"
            fresh = Particles.uniform(self.rng, p.n, self.bounds)
            for name in ("x", "y", "heading", "cos_heading", "sin_heading", "speed", "turn_rate"):
                setattr(p, name, getattr(fresh, name))
            p.log_weight = np.full(p.n, -np.log(p.n))
        self._record("degenerate_weights", action)

    def alarm(self, kind: str, detail: str) -> None:
        """Record an event of a monitor (:meth:`_record`)."""
        self._record(kind, detail)

    def restarted(self, detail: str) -> None:
        """The particles were re-placed now (a re-acquisition): record a ``reacquired``
        event, start the measurement's run state afresh (its ``start`` hook) and put every
        particle in one mixture component."""
        p = self.particles
        if self._start is not None:
            self.measurement_state = self._start(p, self.time, self.dt)
        if self.mixture is not None:
            self.mixture.initialised(self)
        self._record("reacquired", detail)

    def _record(self, kind: str, detail: str) -> None:
        """Warn (``RuntimeWarning``) and append the event to :attr:`events`."""
        warnings.warn(f"t={self.time}: {kind}: {detail}", RuntimeWarning, stacklevel=3)
        self.events.append({"time": self.time, "kind": kind, "detail": detail})

    def keep_weights(self, weights: np.ndarray) -> None:
        """Keep ``weights`` (N,), the normalised weights of the particles' current log
        weights, as :meth:`weights` returns them, with their effective sample size
        ``1 / Σ w²`` and weighted mean position (m).

        For correction policies that replace the log weights themselves
        (:class:`hmmtrack.tracking.tempering.Tempered`); moving the particles afterwards
        leaves the weights valid and the mean a point inside the cloud.
        """
        p = self.particles
        self._weighed = (
            p.log_weight,
            weights,
            1.0 / (weights @ weights),
            (float(weights @ p.x), float(weights @ p.y)),
        )

    def resample_if_due(self) -> bool:
        """Resample per ``resample_when``; return whether it happened. The particles at
        this time are settled first (the collectors see them corrected, not resampled)."""
        p = self._require_particles()
        self._settle()
        if self.resample_when == "ess" and self.weights()[1] >= self.ess_threshold * p.n:
            return False
        self.resample()
        return True

    def resample(self) -> None:
        """Resample by the normalised weights (:meth:`weights`): equal weights after it
        (with a mixture: equal within each component) and :attr:`last_ancestors` set; the
        collectors are told the ancestors."""
        p = self.particles
        weights, _, origin = self.weights()
        if self.mixture is None:
            self.scratch.threads = self.correction_threads()
            drawn = self._resample(self.rng, weights, p.n, self.scratch)
            if isinstance(drawn, Inversion):  # merged in the pass that gathers the particles
                ancestors = np.empty(p.n, dtype=np.int64)
                self._take(p, ancestors, self.scratch.prepare(drawn))
            else:
                ancestors = drawn
                self._take(p, ancestors)
            # equal weights now; the old weighted mean still lies inside the cloud
            self._weighed = (self.particles.log_weight, self._equal_weights(), float(p.n), origin)
        else:  # each component's merge in the pass that gathers its new particles
            drawn = self.mixture.draw(self, weights)
            ancestors = drawn.ancestors
            self._take(p, ancestors, drawn.locate)
            log_weight, weights, n_eff, mean, self.component_moments = self.mixture.finish(
                drawn, self.particles, self.scratch
            )
            self.particles.log_weight = log_weight
            self._weighed = (log_weight, weights, n_eff, mean)
        self.last_ancestors = ancestors
        for collector in self.collect:
            collector.resampled(self, ancestors)

    def _take(self, p: Particles, ancestors: np.ndarray, locate=None) -> None:
        """The particles become ``p``'s ``ancestors`` with equal weights, gathered into the
        spare arrays (those of the particles before the previous resampling, which nothing
        holds on to) on the correction's threads; ``p``'s arrays become the spare ones.
        With ``locate`` (an inverse CDF ready to merge), each chunk's ancestors are found
        into ``ancestors`` in the pass that gathers it (:meth:`Particles.take`)."""
        threads = self.correction_threads()
        self.particles = p.take(ancestors, True, self._spare, threads, locate)
        self._spare = p

    def _equal_weights(self) -> np.ndarray:
        """The equal normalised weights ``1 / N`` (N,), one read-only array per filter."""
        n = self.particles.n
        if self._equal is None or self._equal.size != n:
            self._equal = np.full(n, 1.0 / n)
            self._equal.flags.writeable = False
        return self._equal

    def _settle(self) -> None:
        """The particles at :attr:`time` are final (about to move or be resampled, or the
        run ends): tell the collectors, once per time."""
        if self._unsettled:
            self._unsettled = False
            for collector in self.collect:
                collector.settled(self)

    # ------------------------------------------------------------------ online

    def step(self, time: float, observations=None) -> Estimate:
        """Advance to ``time`` and correct with ``observations`` made there (online use).

        The first call initialises the filter at ``time``. Later times must lie on the
        prediction grid ``t0 + k dt`` at or after the current time. A filter with an
        :attr:`acquisition` is refused: it draws the first particles from corrections an
        online filter has not seen yet (``acquisition=False``, or the ``"paper"`` filter).

        Parameters
        ----------
        time : float
            s.
        observations : DataFrame or mapping of columns, optional
            Observations made at ``time`` (any number of rows, including none).

        Returns
        -------
        Estimate
            After the correction, before resampling.
        """
        if self.particles is None:
            if self.acquisition is not None:
                raise ValueError(
                    "an online filter (step) cannot draw its first particles from corrections "
                    "it has not seen: build it without acquisition (acquisition=False, e.g. "
                    "the 'paper' filter)"
                )
            estimate = self.initialise(time)
        else:
            n_steps = round((time - self.time) / self.dt)
            if n_steps < 0 or abs(time - (self.time + n_steps * self.dt)) > 1e-6 * self.dt:
                raise ValueError(
                    f"step time {time} is not on the prediction grid {self.time} + k*{self.dt}"
                    " with k >= 0"
                )
            predicted = self.predict(n_steps)
            estimate = predicted[-1] if predicted else self.estimate()
        if observations is not None and _n_rows(observations) > 0:
            estimate = self.correct(observations)
            self.resample_if_due()
        return estimate

    # ------------------------------------------------------------------ offline

    def iterate(
        self,
        observations: pd.DataFrame,
        start: float | None = None,
        end: float | None = None,
        snapshot_times: Sequence[float] = (),
        snapshots: dict | None = None,
    ) -> Iterator[Estimate]:
        """Run from ``start`` to ``end``, yielding one estimate per prediction step.

        Parameters
        ----------
        observations : pandas.DataFrame
            Column ``time`` (s) and the measurement model's columns; any order.
        start, end : float, optional
            Time window (s); default: the observations' first time rounded down and last
            time rounded up to whole seconds. Observations outside it are left out with a
            warning and an event.
        snapshot_times : sequence of float
            Times (s) at which to copy the particles into ``snapshots`` (rounded to the
            prediction grid).
        snapshots : dict, optional
            Receives ``{time: particles table}`` for ``snapshot_times``.
        """
        obs = self._checked_observations(observations)
        times = obs["time"].to_numpy()
        if start is None:
            start = float(np.floor(times.min())) if times.size else 0.0
        if end is None:
            end = float(np.ceil(times.max())) if times.size else start
        if end < start:
            raise ValueError(f"end ({end}) is before start ({start})")
        n_ticks = int(np.floor((end - start) / self.dt + 1e-9))
        ticks = np.rint((times - start) / self.dt).astype(np.int64)
        inside = (ticks >= 0) & (ticks <= n_ticks)
        self.initialise(start)
        outside = obs.index[~inside]
        if outside.size:
            obs, ticks = obs[inside], ticks[inside]
        if ticks.size > 1 and not (ticks[1:] >= ticks[:-1]).all():  # else no table to copy
            order = np.argsort(ticks, kind="stable")
            obs, ticks = obs.iloc[order], ticks[order]
        # the measurement's own matrix form of all observations, converted once (a pandas
        # slice per correction costs more than the correction)
        matrix = obs if self._as_matrix is None else self._as_matrix(obs)
        deferred = None if self.acquisition is None else self._acquire(start, ticks, matrix)
        if outside.size:
            self._record(
                "observations_outside_window",
                f"{outside.size} observation(s) (rows {outside[:10].tolist()}"
                f"{'...' if outside.size > 10 else ''}) outside [{start}, {end}] left out",
            )
        snap_ticks = self._snapshot_ticks(snapshot_times, start, n_ticks)
        stops = np.union1d(np.union1d(ticks, snap_ticks), [0, n_ticks])
        # each stop's observations are rows lo:hi (one search for all stops, plain ints)
        rows = zip(
            stops.tolist(),
            np.searchsorted(ticks, stops).tolist(),
            np.searchsorted(ticks, stops + 1).tolist(),
            strict=True,
        )
        snap_ticks = set(snap_ticks.tolist())
        current = 0
        for stop, lo, hi in rows:
            predicted = self.predict(stop - current)
            yield from predicted[:-1]
            estimate = predicted[-1] if predicted else self.estimate()
            if deferred is not None and stop == deferred[0]:
                self._start_at_acquisition(deferred[1])
            if hi > lo:
                estimate = self._correct(matrix[lo:hi], lambda lo=lo, hi=hi: obs.iloc[lo:hi])
            if stop in snap_ticks and snapshots is not None:
                snapshots[self.time] = self.particles.to_frame()
            if hi > lo:
                self.resample_if_due()
            yield estimate
            current = stop

    def _acquire(self, start: float, ticks: np.ndarray, rows) -> tuple[int, list] | None:
        """Run the acquisition on the first corrections that inform the measurement
        (:meth:`Acquisition.first <hmmtrack.tracking.acquisition.Acquisition.first>`) and
        record an ``acquired`` event (no warning). ``ticks`` (M,), ascending, are the
        prediction steps of ``rows``, the observations in the measurement's form in the same
        order (sliced per correction, as :meth:`iterate` slices them).

        When corrections that say nothing of the position come first (pings heard by one
        receiver), the tag may move far before the first one that does: the acquisition is
        then deferred to that correction's step, returned with the corrections chosen
        (:meth:`_start_at_acquisition`), and the particles stay uniform until it."""
        steps = np.unique(ticks)

        def corrections():
            for tick in steps.tolist():
                lo, hi = np.searchsorted(ticks, [tick, tick + 1]).tolist()
                yield start + tick * self.dt, rows[lo:hi]

        chosen = self.acquisition.first(corrections(), self.measurement)
        if not chosen:
            return None
        tick = round((chosen[0][0] - start) / self.dt)
        if tick > steps[0]:
            return tick, chosen
        detail = self.acquisition.place(self, chosen)
        self.events.append({"time": self.time, "kind": "acquired", "detail": detail})
        return None

    def _start_at_acquisition(self, chosen) -> None:
        """The deferred acquisition (:meth:`_acquire`), at the first correction that informs
        the measurement: the particles start afresh there -- motion fields as
        :meth:`initialise` draws them, positions and weights from the ``chosen``
        corrections' likelihood, the measurement's run state and the mixture restarted --
        and an ``acquired`` event is recorded (no warning)."""
        p = self.particles
        fresh = Particles.uniform(self.rng, p.n, self.bounds)
        self.motion.initialise(self.rng, fresh)
        for name in _MOTION_FIELDS:
            setattr(p, name, getattr(fresh, name))
        p.extra.update(fresh.extra)
        detail = self.acquisition.place(self, chosen)
        if self._start is not None:
            self.measurement_state = self._start(p, self.time, self.dt)
        if self.mixture is not None:
            self.mixture.initialised(self)
        if self.monitor is not None:
            self.monitor.start(self)
        self.events.append({"time": self.time, "kind": "acquired", "detail": detail})

    def _snapshot_ticks(self, snapshot_times, start: float, n_ticks: int) -> np.ndarray:
        snap = np.asarray(snapshot_times, dtype=np.float64)
        snap_ticks = np.rint((snap - start) / self.dt).astype(np.int64)
        outside = (snap_ticks < 0) | (snap_ticks > n_ticks)
        if outside.any():
            raise ValueError(
                f"snapshot_times {snap[outside].tolist()} are outside the run "
                f"[{start}, {start + n_ticks * self.dt}]"
            )
        return np.unique(snap_ticks)

    def _checked_observations(self, observations: pd.DataFrame) -> pd.DataFrame:
        """Observations with every needed column present and finite, or a clear error."""
        needed = ("time", *getattr(self.measurement, "columns", ()))
        missing = [c for c in needed if c not in observations.columns]
        if missing:
            raise ValueError(
                f"observations lack column(s) {missing}; expected {list(needed)} "
                f"(docs/interfaces.md), got {list(observations.columns)}"
            )
        bad = ~np.isfinite(np.column_stack([_as_numbers(observations[c]) for c in needed]))
        if bad.any():
            rows, cols = np.nonzero(bad)
            raise ValueError(
                f"observations have missing or non-numeric values in column(s) "
                f"{sorted({needed[c] for c in cols})} at row(s) "
                f"{observations.index[np.unique(rows)][:10].tolist()}; expected finite numbers"
            )
        return observations

    def run(
        self,
        observations: pd.DataFrame,
        start: float | None = None,
        end: float | None = None,
        snapshot_times: Sequence[float] = (),
        estimates_to: Callable[[pd.DataFrame], None] | None = None,
    ) -> FilterResult:
        """Run :meth:`iterate` to the end; estimates, snapshots, events and the collectors'
        tables together.

        ``estimates_to``: a sink called with the estimates as they are made, in tables of
        :data:`ESTIMATE_ROWS` rows (:data:`ESTIMATE_COLUMNS`; the last one shorter), e.g. a
        CSV writer, so that a long run's memory is bounded by the particles rather than its
        span; the result's ``estimates`` are then ``None``.
        """
        snapshots: dict[float, pd.DataFrame] = {}
        estimates = self.iterate(observations, start, end, snapshot_times, snapshots)
        if estimates_to is None:
            rows = list(estimates)
        else:
            rows = None
            while chunk := list(itertools.islice(estimates, ESTIMATE_ROWS)):
                estimates_to(_estimate_table(chunk))
        self._settle()
        collected: dict[str, pd.DataFrame] = {}
        for collector in self.collect:
            collected.update(collector.result())
        return FilterResult(
            estimates=None if rows is None else _estimate_table(rows),
            snapshots=snapshots,
            events=pd.DataFrame(self.events, columns=["time", "kind", "detail"]),
            collected=collected,
        )


def _switch(help_text: str, key: str | None = None):
    """A yes/no setting of the filter section: by default as :data:`DEFAULT_FILTER` sets
    ``key`` (off when it does not), and as the named filter of the run sets it."""
    named = None
    if key is not None:
        named = "the --filter's: " + ", ".join(
            f"{'on' if switches[key] else 'off'} for {name}" for name, switches in FILTERS.items()
        )
    return setting(
        FILTERS[DEFAULT_FILTER].get(key, False),
        help=help_text,
        check=boolean,
        default_text=named,
    )


def _tempering_ess(name: str, value) -> float:
    result = number(name, value)
    if not 0 < result < 1:
        raise ValueError(f"{name} must lie in (0, 1), got {value!r}")
    return result


@dataclass(frozen=True)
class FilterSettings(Settings):
    """The ``filter`` section of a tracking configuration: the :class:`ParticleFilter`'s
    own settings (reasons for the defaults in reports/decisions.md, "Tracking defaults").

    Parameters
    ----------
    n_particles : int
        Number of particles.
    prediction_step : float
        Time between predictions and between estimates (s); 1 s as the paper.
    resampling : str
        Scheme of :data:`hmmtrack.tracking.resampling.RESAMPLERS`; ``"systematic"`` (less
        resampling noise than the paper's ``"multinomial"``).
    resample_when : {"always", "ess"}
        After every correction (the paper) or below ``ess_threshold * n_particles``
        effective particles.
    ess_threshold : float
        Fraction in ``(0, 1]`` for ``resample_when="ess"``.
    tempering_ess : float or None
        Temper a correction (:class:`hmmtrack.tracking.tempering.Tempered`) that would leave
        fewer than this fraction of the particles, in ``(0, 1)``; ``None``: the
        measurement's own policy (its ``default_correction``).
    mixture : bool
        Keep every mode of the posterior: resample each component of the particle cloud on
        its own (:class:`hmmtrack.tracking.mixture.Mixture`) and report the components
        (``TrackingResult.modes``); ``False`` resamples the whole cloud.
    acquisition : bool
        Draw the initial particles from the likelihood of the first corrections on a grid
        over the search box (:class:`hmmtrack.tracking.acquisition.Acquisition`);
        ``False`` (the paper's): uniformly in the box.
    long_gap : bool
        After a correction more than :data:`hmmtrack.tracking.monitor.MAX_GAP` seconds
        after the previous one, record a ``long_gap`` event and re-acquire the tag from
        that correction alone; after a shorter silence that the tag may have outswum
        (``Monitor.outswim_gap``, 667 s), do so (event ``outswum``) when a grid explains
        the correction better than the particles or the correction leaves the cloud no
        spread (:class:`hmmtrack.tracking.monitor.Monitor`'s long-gap rule); ``False`` (the
        paper's): the cloud carried across the gap is corrected as usual.
    monitor : bool
        Test each correction's predictive likelihood; when the tag is lost, record an event
        and re-acquire (:class:`hmmtrack.tracking.monitor.Monitor`'s lost-tag test);
        ``False``: no test. The defaults of these four are those of :data:`DEFAULT_FILTER`
        (:data:`FILTERS`): mixture, acquisition and the long-gap rule on, the lost-tag test
        off.
    modes : bool
        Report the cloud's modes (``TrackingResult.modes``) and put the two heaviest beside
        each estimate, with ``converged`` declared only when one mode holds almost all the
        weight (:func:`hmmtrack.tracking.mixture.with_modes`); always on with ``mixture``.
    mirror_split : bool
        With ``mixture``, split a component that straddles the line through the two
        receivers heard last along that line at each resampling (the mixture's mirror
        split, :class:`hmmtrack.tracking.mirror.MirrorLine`), and report components less
        than :data:`hmmtrack.tracking.mixture.ONE_MODE_DISTANCE` apart as one mode. Off in
        every named filter: on fresh synthetic shark pursuits it did not lower the lost runs
        (reports/decisions.md, "The mirror split").
    """

    n_particles: int = setting(
        5000,
        help="number of particles",
        check=positive_integer,
        option="particles",
        parse=int,
        metavar="N",
    )
    prediction_step: float = setting(
        1.0,
        help="time between predictions and between estimates (s)",
        check=positive,
        parse=float,
        metavar="SECONDS",
    )
    resampling: str = setting(
        "systematic",
        help="resampling scheme (multinomial is the paper's)",
        check=one_of(*sorted(RESAMPLERS)),
        choices=tuple(sorted(RESAMPLERS)),
    )
    resample_when: str = setting(
        "always",
        help="resample after every correction (always, the paper) or on low ESS (ess)",
        check=one_of(*RESAMPLE_WHEN),
        choices=RESAMPLE_WHEN,
    )
    ess_threshold: float = setting(
        0.5,
        help="resample below this fraction of the particles, in (0, 1]",
        check=fraction,
        requires=("resample_when", "ess"),
        parse=float,
        metavar="FRACTION",
    )
    tempering_ess: float | None = setting(
        None,
        help=(
            "temper a correction that would leave fewer than this fraction of the particles, "
            "in (0, 1)"
        ),
        check=_tempering_ess,
        parse=float,
        metavar="FRACTION",
        default_text="the measurement's: none for range-rate, 0.3 for arrival-time, 0.6 for ping",
    )
    mixture: bool = _switch(
        "keep every mode: resample each component of the particle cloud on its own",
        "mixture",
    )
    acquisition: bool = _switch(
        "draw the initial particles from the likelihood of the first corrections",
        "acquisition",
    )
    long_gap: bool = _switch(
        "after a long silence (30 min), or one over 11 min that the tag outswam, record an "
        "event and re-acquire from the detections",
        "long_gap",
    )
    monitor: bool = _switch(
        "notice a lost tag from the predictive likelihood and re-acquire",
        "monitor",
    )
    modes: bool = _switch(
        "report the cloud's modes beside each estimate (always on with the mixture)"
    )
    mirror_split: bool = _switch(
        "with the mixture, split a component that straddles the line through the two "
        "receivers heard last along that line, and report parts less than 20 m apart as one "
        "mode (measured on the synthetic shark pursuit, not better: reports/decisions.md, "
        "'The mirror split')"
    )
