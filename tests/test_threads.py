import itertools
import math

from hmmtrack.tracking.compiled.threads import ThreadChoice

BURST = ThreadChoice.RETRY_CALLS


def _picks(choice: ThreadChoice, calls: int, cost, start: int = 0) -> list[int]:
    """The options ``choice`` picks over ``calls`` calls, told ``cost(call, option)``."""
    picks = []
    for call in range(start, start + calls):
        k = choice.pick()
        picks.append(k)
        choice.record(k, cost(call, k))
    return picks


def _bursts(picks: list[int], option: int) -> list[tuple[int, int]]:
    """(first call, length) of each run of ``option`` in ``picks``."""
    runs, at = [], 0
    for k, group in itertools.groupby(picks):
        length = len(list(group))
        if k == option:
            runs.append((at, length))
        at += length
    return runs


def test_thread_choice_tries_both_keeps_the_cheaper_and_backs_off():
    choice = ThreadChoice(2)
    costs = {1: 2e-8, 2: 9e-8}  # two threads are slower (a busy machine)
    picks = _picks(choice, 600, lambda call, k: costs[k])
    # the first trial: two threads, then one; afterwards each trial is a burst of two
    # threads and one of one thread, after an interval that doubles from 32 up to the cap
    assert picks[: 2 * BURST + 1] == [2] * BURST + [1] * BURST + [1]
    starts, at = [0], 0
    for interval in (32, 64, 128, 128, 128):
        at += 2 * BURST + interval - 1
        starts.append(at)
    assert _bursts(picks, 2) == [(s, BURST) for s in starts]
    assert ThreadChoice.LONGEST_INTERVAL == 128
    assert choice.explore_every == 128 and choice.best() == 1
    assert choice.cost == {1: 2e-8, 2: 9e-8}
    costs[2] = 1e-8  # the machine became quiet: the next trial wins and two threads stay
    later = _picks(choice, 300, lambda call, k: costs[k])
    assert choice.best() == 2 and choice.explore_every == 128
    assert later[-100:].count(2) > 90
    single = ThreadChoice(1)
    for _ in range(40):
        assert single.pick() == 1
        single.record(1, 1e-8)
    assert single.calls == {1: 40}


def test_thread_choice_follows_the_threads_not_the_drift_of_the_machine():
    """The speed of a shared machine drifts threefold within tens of calls while two threads
    stay 1.5x cheaper than one at any moment: one thread runs only in its trials. (Judged on
    each option's own latest calls against the other's cost at an older trial, the choice
    would follow the drift and run one thread in a third or more of the calls.)"""
    choice = ThreadChoice(2)

    def cost(call, k):
        drift = 2.0 + math.sin(call / 12.0)  # 1 to 3, a period of 75 calls
        return drift * {1: 3e-8, 2: 2e-8}[k]

    picks = _picks(choice, 1200, cost)
    assert choice.best() == 2
    assert all(length == BURST for _, length in _bursts(picks[2 * BURST :], 1))
    assert picks.count(1) < 0.12 * len(picks)


def test_thread_choice_leaves_a_busy_spell_within_the_longest_interval():
    """A long busy spell grows the interval to its cap, not beyond: once two threads are
    cheaper again, they are in use within LONGEST_INTERVAL calls and a trial."""
    choice = ThreadChoice(2)
    busy = 1100
    picks = _picks(choice, 2000, lambda call, k: {1: 2e-8, 2: 9e-8 if call < busy else 1e-8}[k])
    assert choice.explore_every <= ThreadChoice.LONGEST_INTERVAL
    # the first run of two threads longer than a trial's burst: two threads in use
    back = next(at for at, length in _bursts(picks, 2) if at > busy and length > BURST)
    assert back <= busy + ThreadChoice.LONGEST_INTERVAL + 2 * BURST
    assert picks[-300:].count(2) > 280


def test_thread_choice_tries_again_at_once_when_the_option_in_use_grows_dear():
    """Two threads in use and the interval at its cap: the second core becomes busy. The
    median of the latest calls in use exceeds one thread's cost at the last trial, so a
    trial starts at once (not after the interval) and one thread takes over."""
    choice = ThreadChoice(2)
    costs = {1: 2e-8, 2: 1.5e-8}
    _picks(choice, 400, lambda call, k: costs[k])
    assert choice.best() == 2 and choice.explore_every == ThreadChoice.LONGEST_INTERVAL
    costs[2] = 9e-8
    picks = _picks(choice, ThreadChoice.RECENT + 2 * BURST + 1, lambda call, k: costs[k])
    assert choice.best() == 1
    assert picks[-1] == 1 and choice.explore_every == ThreadChoice.FIRST_INTERVAL


def test_thread_choice_is_not_flipped_by_one_slow_call():
    """Medians within a trial: a cold first call of each option in a trial, or one slow call
    of the option in use (a lost time slice), does not change the choice."""
    choice = ThreadChoice(2)
    costs = {1: 2e-8, 2: 1.5e-8}  # two threads are faster (a quiet machine)
    slow = {0, 50, 120}  # two threads' first call, then two spikes in use

    def cost(call, k):
        return costs[k] * (5.0 if call in slow else 1.0)

    picks = _picks(choice, 200, cost)
    assert choice.best() == 2
    # the first trial and each later one run one thread BURST times; every trial lost
    assert all(length == BURST for _, length in _bursts(picks, 1))
    assert choice.explore_every == 128
    # a trial whose first call of each option is cold (5x) keeps the cheaper option
    trial = ThreadChoice(2)
    first = {1: True, 2: True}

    def cold(call, k):
        factor = 5.0 if first[k] else 1.0
        first[k] = False
        return costs[k] * factor

    _picks(trial, 2 * BURST, cold)
    assert trial.best() == 2
