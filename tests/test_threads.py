from hmmtrack.tracking.compiled.threads import ThreadChoice


def _picks(choice: ThreadChoice, calls: int, cost) -> list[int]:
    """The options ``choice`` picks over ``calls`` calls, told ``cost(call, option)``."""
    picks = []
    for call in range(calls):
        k = choice.pick()
        picks.append(k)
        choice.record(k, cost(call, k))
    return picks


def test_thread_choice_tries_both_keeps_the_cheaper_and_backs_off():
    choice = ThreadChoice(2)
    costs = {1: 2e-8, 2: 9e-8}  # two threads are slower (a busy machine)
    picks = _picks(choice, 300, lambda call, k: costs[k])
    burst = ThreadChoice.RETRY_CALLS
    assert picks[: 2 * burst + 1] == [1] * burst + [2] * burst + [1]
    retries = [i for i, k in enumerate(picks) if k == 2]
    # after the first trial, retries come in bursts of RETRY_CALLS; the interval between
    # them doubles from 32 each time the retry loses
    assert retries == [
        *range(burst, 2 * burst),
        *range(37, 37 + burst),
        *range(103, 103 + burst),
        *range(233, 233 + burst),
    ]
    assert choice.explore_every == 256 and choice.best() == 1
    costs[2] = 1e-8  # the machine became quiet: the next retry wins and two threads stay
    later = _picks(choice, 300, lambda call, k: costs[k])
    assert choice.best() == 2
    assert later[-100:].count(2) > 90
    single = ThreadChoice(1)
    for _ in range(40):
        assert single.pick() == 1
        single.record(1, 1e-8)


def test_thread_choice_is_not_flipped_by_one_slow_call():
    """Medians on both sides: a cold first call of a trial, or one slow call of the option in
    use (a lost time slice), does not change the choice; slow calls that persist do."""
    choice = ThreadChoice(2)
    costs = {1: 2e-8, 2: 1.5e-8}  # two threads are faster (a quiet machine)
    slow = (3, 50, 120)  # two threads' first call, then two spikes
    picks = _picks(choice, 200, lambda call, k: costs[k] * (5.0 if call in slow else 1.0))
    assert choice.best() == 2
    # one thread only in its retries, each lost (the interval doubled from 16 to 128)
    assert picks[6:].count(1) == 3 * ThreadChoice.RETRY_CALLS
    assert choice.explore_every == 128
    for _ in range(ThreadChoice.RECENT):  # the second core becomes busy
        choice.record(2, 9e-8)
    assert choice.best() == 1
