"""The families by name: registries, rebuilding any family from a dict, EM starting values."""

from __future__ import annotations

import numpy as np

from hmmtrack.hmm.distributions.angles import VonMises, WrappedCauchy, _AngleFamily
from hmmtrack.hmm.distributions.base import PreparedSteps, _check_observations, prepare_steps
from hmmtrack.hmm.distributions.steps import (
    Exponential,
    Gamma,
    LogNormal,
    Weibull,
    _StepFamily,
)
from hmmtrack.hmm.distributions.values import (
    Bernoulli,
    Beta,
    Categorical,
    NegativeBinomial,
    Normal,
    Poisson,
    ZeroInflatedNegativeBinomial,
    ZeroInflatedPoisson,
    ZeroOneInflatedBeta,
    _ValueFamily,
)

STEP_FAMILIES: dict[str, type[_StepFamily]] = {
    cls.name: cls for cls in (Gamma, Weibull, LogNormal, Exponential)
}
ANGLE_FAMILIES: dict[str, type[_AngleFamily]] = {cls.name: cls for cls in (VonMises, WrappedCauchy)}
#: families of further data streams (a third stream and more): any of these or of the above
VALUE_FAMILIES: dict[str, type[_ValueFamily]] = {
    cls.name: cls
    for cls in (
        Normal,
        Beta,
        ZeroOneInflatedBeta,
        Poisson,
        ZeroInflatedPoisson,
        NegativeBinomial,
        ZeroInflatedNegativeBinomial,
        Bernoulli,
        Categorical,
    )
}


def from_dict(d: dict) -> _StepFamily | _AngleFamily | _ValueFamily:
    """Rebuild any family from its ``to_dict`` output, dispatching on ``d["family"]``."""
    if not isinstance(d, dict) or "family" not in d:
        raise ValueError(f"a distribution needs a dict with a 'family' key, got {d!r}")
    families = {**STEP_FAMILIES, **ANGLE_FAMILIES, **VALUE_FAMILIES}
    if d["family"] not in families:
        raise ValueError(f"unknown distribution family {d['family']!r}; known: {sorted(families)}")
    return families[d["family"]].from_dict(d)


def _family(name_or_class: str | type, registry: dict[str, type], kind: str) -> type:
    if isinstance(name_or_class, str):
        if name_or_class not in registry:
            raise ValueError(f"unknown {kind} family {name_or_class!r}; known: {sorted(registry)}")
        return registry[name_or_class]
    if name_or_class not in registry.values():
        raise ValueError(f"{name_or_class!r} is not a {kind} family; known: {sorted(registry)}")
    return name_or_class


def initial_guess(
    steps: np.ndarray | PreparedSteps,
    angles: np.ndarray,
    n_states: int,
    step_family: str | type = "gamma",
    angle_family: str | type = "vonmises",
    *,
    estimate_angle_mean: bool = True,
    zero_inflated: bool | None = None,
    rng: np.random.Generator | None = None,
) -> tuple[_StepFamily, _AngleFamily]:
    """Starting values for an EM fit from the data, states ordered by mean step.

    The positive steps are sorted and cut into ``n_states`` groups of equal size (with
    ``rng``: group sizes drawn from a flat Dirichlet, for multi-start). Each group's mean
    and sd give the step distribution (``from_moments``); the turning angles of the rows in
    each group give the mean direction and mean resultant length of the angle distribution.

    Parameters
    ----------
    steps : (T,) float or PreparedSteps
        Step lengths (>= 0, NaN missing), units of the data; prepared steps (see
        :func:`prepare_steps`) are sorted once for all the calls that share them.
    angles : (T,) float
        Turning angles (rad, NaN missing), same rows as ``steps``.
    n_states : int
        Number of states K >= 1.
    step_family, angle_family : str or class
        Names in ``STEP_FAMILIES`` / ``ANGLE_FAMILIES`` or the classes themselves.
    estimate_angle_mean : bool
        False fixes the angle means at 0.
    zero_inflated : bool or None
        Zero-inflation of steps; None switches it on when a step is exactly 0 (moveHMM).
    rng : numpy.random.Generator or None
        None gives the deterministic equal-count split.

    Returns
    -------
    (step distribution, angle distribution)
    """
    step_cls = _family(step_family, STEP_FAMILIES, "step")
    angle_cls = _family(angle_family, ANGLE_FAMILIES, "angle")
    prepared = prepare_steps(steps)
    steps = prepared.safe  # the steps on positive rows, which are the only ones used
    angles = _check_observations(angles, "initial_guess(angles)")
    if steps.shape != angles.shape:
        raise ValueError(f"initial_guess: steps {steps.shape} and angles {angles.shape} differ")
    if n_states < 1:
        raise ValueError(f"initial_guess: n_states must be >= 1, got {n_states}")
    order = prepared.positive_order
    if order.size < 2 * n_states:
        raise ValueError(
            f"initial_guess: {order.size} positive steps are too few for {n_states} states"
        )
    zero = prepared.zero
    if zero_inflated is None:
        zero_inflated = bool(zero.any())
    shares = np.full(n_states, 1.0 / n_states) if rng is None else rng.dirichlet(np.ones(n_states))
    # at least two rows per group so that every sd is defined
    sizes = 2 + np.floor(shares * (order.size - 2 * n_states)).astype(int)
    sizes[-1] = order.size - sizes[:-1].sum()
    groups = np.split(order, np.cumsum(sizes)[:-1])

    means = np.array([steps[g].mean() for g in groups])
    sds = np.array([max(steps[g].std(), 1e-3 * steps[g].mean()) for g in groups])
    zero_mass = None
    if zero_inflated:
        share = zero.sum() / max((~prepared.missing).sum(), 1)
        zero_mass = np.full(n_states, min(max(share, 1e-3), 0.5))
    step_dist = step_cls.from_moments(means, sds, zero_mass=zero_mass)

    direction, resultant = np.zeros(n_states), np.zeros(n_states)
    for k, g in enumerate(groups):
        a = angles[g]
        a = a[~np.isnan(a)]
        if a.size == 0:
            continue
        c, s = np.cos(a).mean(), np.sin(a).mean()
        direction[k] = np.arctan2(s, c) if estimate_angle_mean else 0.0
        resultant[k] = np.hypot(c, s) if estimate_angle_mean else max(c, 0.0)
    resultant = np.clip(resultant, 0.01, 0.95)
    angle_dist = angle_cls.from_mean_resultant(direction, resultant, estimate_angle_mean)
    return step_dist, angle_dist
