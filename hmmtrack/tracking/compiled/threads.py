"""How many threads a compiled call should use, chosen by timing: :class:`ThreadChoice`.

On a shared machine more threads are often slower than one, and which is faster changes with
the load; the particle filter (:class:`hmmtrack.tracking.filter.ParticleFilter`) therefore
times its compiled prediction calls (:func:`hmmtrack.tracking.compiled.chunks.run_chunks`),
each with the correction and resampling that follow it on the same threads (from one
prediction to the next), on one thread and on all, keeps the cheaper and retries the other
now and then. Only speed depends on the choice, never results.
"""

from __future__ import annotations

__all__ = ["ThreadChoice"]


def _median(costs: list[float]) -> float:
    """The middle of ``costs`` (the upper middle of an even count): a sort of at most
    ``ThreadChoice.RECENT`` numbers, cheaper than NumPy's median on every call."""
    return sorted(costs)[len(costs) // 2]


class ThreadChoice:
    """Chooses between one thread and ``max_threads`` for compiled calls by timing both.

    The cost (s per particle-step) of an option is the median of its latest calls: the last
    ``RECENT`` of the option in use, the ``RETRY_CALLS`` of the other's latest retry (a burst
    of calls; an option left idle starts cold, its first call slow). Medians on both sides,
    because a running average of the option in use against the best call of a retry let
    one slow call (a page fault, a time slice lost) flip the choice, and a
    one-call trial at the start let a cold call decide it. The first calls try each option
    ``RETRY_CALLS`` times; afterwards the cheaper one runs, and the other is retried after
    ``explore_every`` calls -- an interval that doubles (up to 1024) each time the retry
    loses and resets to 16 when it wins, so that a machine whose load changes is followed
    without paying often for a bad option. Only speed depends on the choice, never results.

    Parameters
    ----------
    max_threads : int
        The alternative to one thread (numba's maximum).
    """

    RETRY_CALLS = 3
    RECENT = 5

    def __init__(self, max_threads: int) -> None:
        self.options = (1, max_threads) if max_threads > 1 else (1,)
        #: s per particle-step of each option (None until measured)
        self.cost: dict[int, float | None] = dict.fromkeys(self.options)
        #: calls recorded of each option (what a run ran on: benchmarks print it)
        self.calls: dict[int, int] = dict.fromkeys(self.options, 0)
        self.explore_every = 16
        self._calls_since_explore = 0
        # latest costs of each option: its calls in use, its retry, or its first trial
        self._latest: dict[int, list[float]] = {k: [] for k in self.options}
        self._retry_left = 0

    def best(self) -> int:
        """The option with the lowest measured cost (one thread while unmeasured)."""
        measured = {k: v for k, v in self.cost.items() if v is not None}
        return min(measured, key=measured.get) if measured else 1

    def _other(self) -> int:
        return next(k for k in self.options if k != self.best())

    def pick(self) -> int:
        """Threads for the next call."""
        if len(self.options) == 1:
            return 1
        for option, cost in self.cost.items():
            if cost is None:
                return option
        if self._retry_left:
            return self._other()
        self._calls_since_explore += 1
        if self._calls_since_explore < self.explore_every:
            return self.best()
        self._calls_since_explore = 0
        self._latest[self._other()] = []
        self._retry_left = self.RETRY_CALLS
        return self._other()

    def record(self, threads: int, cost: float) -> None:
        """Note that a call with ``threads`` (as :meth:`pick` said) cost ``cost`` s per
        particle-step."""
        self.calls[threads] += 1
        latest = self._latest[threads]
        latest.append(cost)
        if self.cost[threads] is None:  # the first trial of this option
            if len(latest) == self.RETRY_CALLS:
                self.cost[threads] = _median(latest)
                if None not in self.cost.values():
                    self._settle(won=self.best() == threads)
        elif self._retry_left and threads == self._other():
            self._retry_left -= 1
            if not self._retry_left:
                self.cost[threads] = _median(latest)
                self._settle(won=self.best() == threads)
        else:
            del latest[: -self.RECENT]
            self.cost[threads] = _median(latest)

    def _settle(self, won: bool) -> None:
        self.explore_every = 16 if won else min(2 * self.explore_every, 1024)
