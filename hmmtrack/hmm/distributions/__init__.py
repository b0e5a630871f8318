"""State-dependent emission distributions of movement HMMs: step lengths and turning angles.

Each family is a small frozen dataclass holding one array of shape ``(K,)`` per parameter
(one entry per behavioural state) and implementing the :class:`StateDistribution` protocol
of ``docs/interfaces.md``: log-densities and CDFs ``(T,) -> (T, K)``, a weighted maximum
likelihood per state (the EM M-step), sampling, a JSON dict, and an unconstrained working
scale with its closed-form score.

Step families (``Gamma`` in moveHMM's mean/sd parametrisation, ``Weibull``, ``LogNormal``,
``Exponential``) share one zero-inflation mechanism: an optional ``zero_mass`` (K,) puts a
point mass at a step of exactly 0 and scales the density for ``x > 0`` by ``1 - zero_mass``.
Angle families (``VonMises``, ``WrappedCauchy``) have a mean that is either estimated or
fixed at 0 (``estimate_mean``).

Modules: :mod:`.base` (the protocol, prepared observations, the shared family machinery),
:mod:`.steps` (step families), :mod:`.angles` (angle families), :mod:`.families` (the
registries ``STEP_FAMILIES`` / ``ANGLE_FAMILIES`` / ``VALUE_FAMILIES``, :func:`from_dict`,
:func:`initial_guess`), :mod:`.values` (families of further data streams: ``Normal``,
``Beta``, ``Poisson``, ``NegativeBinomial``, ``Bernoulli``, ``Categorical`` and the inflated
``ZeroOneInflatedBeta``, ``ZeroInflatedPoisson``, ``ZeroInflatedNegativeBinomial``).
The names below are the package's public face.

Not for: hidden-state inference (``hmmtrack.hmm.inference``), transition matrices or EM
bookkeeping (``hmmtrack.hmm.fit``).
"""

from hmmtrack.hmm.distributions.angles import VonMises, WrappedCauchy
from hmmtrack.hmm.distributions.base import (
    PreparedAngles,
    PreparedSteps,
    StateDistribution,
    prepare_angles,
    prepare_steps,
)
from hmmtrack.hmm.distributions.families import (
    ANGLE_FAMILIES,
    STEP_FAMILIES,
    VALUE_FAMILIES,
    from_dict,
    initial_guess,
)
from hmmtrack.hmm.distributions.steps import Exponential, Gamma, LogNormal, Weibull
from hmmtrack.hmm.distributions.values import (
    Bernoulli,
    Beta,
    Categorical,
    NegativeBinomial,
    Normal,
    Poisson,
    PreparedValues,
    ZeroInflatedNegativeBinomial,
    ZeroInflatedPoisson,
    ZeroOneInflatedBeta,
    prepare_values,
)

__all__ = [
    "ANGLE_FAMILIES",
    "STEP_FAMILIES",
    "VALUE_FAMILIES",
    "Bernoulli",
    "Beta",
    "Categorical",
    "Exponential",
    "Gamma",
    "LogNormal",
    "NegativeBinomial",
    "Normal",
    "Poisson",
    "PreparedAngles",
    "PreparedSteps",
    "PreparedValues",
    "StateDistribution",
    "VonMises",
    "Weibull",
    "WrappedCauchy",
    "ZeroInflatedNegativeBinomial",
    "ZeroInflatedPoisson",
    "ZeroOneInflatedBeta",
    "from_dict",
    "initial_guess",
    "prepare_angles",
    "prepare_steps",
    "prepare_values",
]
