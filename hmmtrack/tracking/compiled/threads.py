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

    The option in use changes only at the end of a trial, which times both options side by
    side: ``RETRY_CALLS`` calls of the other option, then ``RETRY_CALLS`` of the option in
    use, and keeps the one with the lower median cost (s per particle-step). Both medians
    come from the same few calls' window, because the speed of a shared machine drifts by
    tens of percent within seconds: an option compared with what the other cost a few
    hundred calls earlier (or switched to when its own latest calls grew dearer than that
    old figure) was chosen on the drift, not on the threads (reports/decisions.md, "The
    timed thread choice side by side"). Medians, so that one slow call (a cold first call
    after an idle stretch, a time slice lost) does not decide.

    The first calls are a trial with one thread in use. Afterwards a trial starts after
    ``explore_every`` calls -- an interval that doubles (up to ``LONGEST_INTERVAL``) each
    time the other option loses and resets to ``FIRST_INTERVAL`` when it wins -- or sooner,
    when the median of the latest ``RECENT`` calls in use exceeds the other option's cost
    at the last trial (the second core became busy, say). The cap bounds how long a choice
    made in a busy spell outlives it; a trial of the worse option costs about
    ``RETRY_CALLS`` of its calls. Only speed depends on the choice, never results.

    Parameters
    ----------
    max_threads : int
        The alternative to one thread (numba's maximum).
    """

    RETRY_CALLS = 3
    RECENT = 5
    FIRST_INTERVAL = 16
    LONGEST_INTERVAL = 128

    def __init__(self, max_threads: int) -> None:
        self.options = (1, max_threads) if max_threads > 1 else (1,)
        #: s per particle-step of each option at the last trial (None until measured)
        self.cost: dict[int, float | None] = dict.fromkeys(self.options)
        #: calls recorded of each option (what a run ran on: benchmarks print it)
        self.calls: dict[int, int] = dict.fromkeys(self.options, 0)
        self.explore_every = self.FIRST_INTERVAL
        self._in_use = 1
        self._calls_since_trial = 0
        # costs of each option in the trial under way (None between trials)
        self._trial: dict[int, list[float]] | None = self._new_trial()
        # latest costs of the option in use between trials
        self._recent: list[float] = []

    def _new_trial(self) -> dict[int, list[float]] | None:
        return {k: [] for k in self.options} if len(self.options) > 1 else None

    def best(self) -> int:
        """The option in use (the cheaper at the last trial; one thread before the first)."""
        return self._in_use

    def _other(self) -> int:
        return next(k for k in self.options if k != self._in_use)

    def pick(self) -> int:
        """Threads for the next call."""
        if len(self.options) == 1:
            return 1
        if self._trial is None:
            self._calls_since_trial += 1
            if self._calls_since_trial < self.explore_every:
                return self._in_use
            self._trial = self._new_trial()
        other = self._other()
        return other if len(self._trial[other]) < self.RETRY_CALLS else self._in_use

    def record(self, threads: int, cost: float) -> None:
        """Note that a call with ``threads`` (as :meth:`pick` said) cost ``cost`` s per
        particle-step."""
        self.calls[threads] += 1
        if len(self.options) == 1:
            return
        if self._trial is not None:
            self._trial[threads].append(cost)
            if min(map(len, self._trial.values())) >= self.RETRY_CALLS:
                self._end_trial()
        elif threads == self._in_use:
            self._recent.append(cost)
            del self._recent[: -self.RECENT]
            dearer = _median(self._recent) > self.cost[self._other()]
            if len(self._recent) == self.RECENT and dearer:
                self._calls_since_trial = self.explore_every  # a trial at the next call

    def _end_trial(self) -> None:
        self.cost = {k: _median(costs) for k, costs in self._trial.items()}
        other = self._other()
        won = self.cost[other] < self.cost[self._in_use]
        if won:
            self._in_use = other
        self.explore_every = (
            self.FIRST_INTERVAL if won else min(2 * self.explore_every, self.LONGEST_INTERVAL)
        )
        self._trial = None
        self._calls_since_trial = 0
        self._recent = []
