"""Movement hidden Markov models of step lengths and turning angles.

The public workflow (moveHMM's ``prepData`` -> ``fitHMM`` -> ``viterbi`` / ``pseudoRes`` /
``CI``)::

    from hmmtrack import io, tracks
    from hmmtrack.hmm import fit_movement_hmm, MovementHMM

    prepared = tracks.prepare(io.read_tracks("data/example_tracks.csv"))
    model = fit_movement_hmm(prepared, n_states=2, n_starts=5, seed=1)
    model.save("model.json")
    states = MovementHMM.load("model.json").viterbi(prepared)

Submodules: :mod:`~hmmtrack.hmm.distributions` (emission families),
:mod:`~hmmtrack.hmm.inference` (forward-backward, Viterbi), :mod:`~hmmtrack.hmm.covariates`
(logit transition matrices), :mod:`~hmmtrack.hmm.fit` (EM, multi-start),
:mod:`~hmmtrack.hmm.em_kernels` (the fused EM iteration of the common 2-3 state model),
:mod:`~hmmtrack.hmm.model` (the fitted model and its JSON file),
:mod:`~hmmtrack.hmm.diagnostics` (pseudo-residuals, Wald intervals, AIC/BIC),
:mod:`~hmmtrack.hmm.crw` (irregular tracks: continuous-time correlated random walk,
regularisation and imputed tracks), :mod:`~hmmtrack.hmm.imputation` (fits to imputed tracks
pooled by Rubin's rules), :mod:`~hmmtrack.hmm.formula` (formula design matrices),
:mod:`~hmmtrack.hmm.decoding` (decoded states as a table aligned to the input rows),
:mod:`~hmmtrack.hmm.emission` (emission formulas: covariates on a stream's distribution),
:mod:`~hmmtrack.hmm.constraints` (fixed parameters, equality constraints, a stationary
initial distribution).
"""

from hmmtrack.hmm.distributions import (
    Exponential,
    Gamma,
    LogNormal,
    VonMises,
    Weibull,
    WrappedCauchy,
)
from hmmtrack.hmm.fit import MovementHMMEstimator, fit_movement_hmm
from hmmtrack.hmm.inference import forward_backward, viterbi
from hmmtrack.hmm.model import MovementHMM

__all__ = [
    "Exponential",
    "Gamma",
    "LogNormal",
    "MovementHMM",
    "MovementHMMEstimator",
    "VonMises",
    "Weibull",
    "WrappedCauchy",
    "fit_movement_hmm",
    "forward_backward",
    "viterbi",
]
