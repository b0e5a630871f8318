"""Seeds in, generators out: the one place where user seeds become ``numpy.random.Generator``.

Every stochastic function of hmmtrack takes a ``Generator``; public entry points take a
``seed`` and call :func:`as_generator`. Independent streams for trials or workers come from
:func:`spawn`, so that serial and parallel runs draw the same numbers.
"""

from __future__ import annotations

import numpy as np

SeedLike = int | np.random.SeedSequence | np.random.Generator | None


def as_generator(seed: SeedLike) -> np.random.Generator:
    """Return a ``Generator`` for ``seed``.

    Parameters
    ----------
    seed : int, SeedSequence, Generator or None
        A ``Generator`` is returned as it is. ``None`` draws fresh entropy from the OS (the
        caller asked for an unrepeatable run); there is no hidden default seed.
    """
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(seed)


def spawn(seed: int | np.random.SeedSequence | None, n: int) -> list[np.random.SeedSequence]:
    """Return ``n`` independent child seed sequences of ``seed`` (``SeedSequence.spawn``)."""
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return ss.spawn(n)
