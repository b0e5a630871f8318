"""One step of a Markov chain for every particle: the HMM motion model's behavioural states
and the velocity model's regimes (:mod:`hmmtrack.tracking.motion.hmm`,
:mod:`hmmtrack.tracking.motion.regimes`) move along their chains with these passes, each
particle's uniform drawn from its own stream (:mod:`hmmtrack.tracking.compiled.streams`), and
with their NumPy references (:func:`draw_states`, :func:`step_states`), whose uniforms come
from the filter's generator.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from hmmtrack.tracking.compiled import streams as rs

__all__ = ["SELECT_STATES", "draw_states", "next_states", "step_states", "transition_pass"]

#: the transition pass picks a particle's threshold by selects for up to this many states,
#: by a lookup (gather) for more (reports/decisions.md, "The HMM kernels' passes")
SELECT_STATES = 4


def draw_states(rng: np.random.Generator, cumulative: np.ndarray, n: int) -> np.ndarray:
    """``n`` states (int64) drawn from the distribution of cumulative probabilities
    ``cumulative`` (K,): each the first ``j`` with ``u < cumulative[j]`` for a uniform ``u``,
    at most ``K - 1``."""
    drawn = np.searchsorted(cumulative, rng.random(n), side="right")
    return np.minimum(drawn, cumulative.size - 1).astype(np.int64)


def step_states(rng: np.random.Generator, states: np.ndarray, cumulative: np.ndarray) -> np.ndarray:
    """The states (N,) after one step of the chain whose transition rows are cumulated in
    ``cumulative`` (K, K): the NumPy twin of :func:`next_states`, one uniform per state."""
    u = rng.random(states.size)
    moved = (u[:, None] > cumulative[states]).sum(axis=1)
    return np.minimum(moved, cumulative.shape[0] - 1).astype(np.int64)


@njit(cache=True, inline="always")
def transition_pass(behaviour, streams, cumulative, u, next_state):
    """One step of the behavioural chain for particles ``(n,)``: a uniform ``u`` from each
    stream, then :func:`next_states`. ``u`` (float) and ``next_state`` (int) are
    scratch."""
    for i in range(behaviour.size):
        u[i], streams[i] = rs.uniform(streams[i])
    next_states(behaviour, cumulative, u, next_state)


@njit(cache=True, inline="always")
def next_states(behaviour, cumulative, u, next_state):
    """Move the states ``behaviour`` (n,) one step of the chain given their uniforms ``u``:
    the next state is the first ``j`` with ``u <= cumulative[state, j]``
    (:func:`streams.categorical`), counted as the number of ``j < K - 1`` with
    ``cumulative[state, j] < u`` in branch-free passes. For up to :data:`SELECT_STATES`
    states each pass picks the particle's threshold by selects among the column's values
    (vector blends) rather than by a lookup in the table (a gather): the same threshold.
    ``next_state`` (int) is scratch."""
    for i in range(behaviour.size):
        next_state[i] = 0
    n_states = cumulative.shape[0]
    for j in range(n_states - 1):
        if n_states <= SELECT_STATES:
            last = n_states - 1
            c0, c1 = cumulative[0, j], cumulative[min(1, last), j]
            c2, c3 = cumulative[min(2, last), j], cumulative[min(3, last), j]
            for i in range(behaviour.size):
                k = behaviour[i]
                cut = c0 if k == 0 else (c1 if k == 1 else (c2 if k == 2 else c3))
                next_state[i] += cut < u[i]
        else:
            for i in range(behaviour.size):
                next_state[i] += cumulative[behaviour[i], j] < u[i]
    for i in range(behaviour.size):
        behaviour[i] = next_state[i]
