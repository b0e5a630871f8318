from hmmtrack.tracking.compiled.threads import ThreadChoice


def test_thread_choice_tries_both_keeps_the_cheaper_and_backs_off():
    choice = ThreadChoice(2)
    costs = {1: 2e-8, 2: 9e-8}  # two threads are slower (a busy machine)
    picks = []
    for _ in range(300):
        k = choice.pick()
        picks.append(k)
        choice.record(k, costs[k])
    assert picks[:3] == [1, 2, 1]
    retries = [i for i, k in enumerate(picks) if k == 2]
    # after the first probe, retries come in bursts of RETRY_CALLS; the interval between
    # them doubles from 32 each time the retry loses
    burst = ThreadChoice.RETRY_CALLS
    assert retries == [1, *range(33, 33 + burst), *range(99, 99 + burst), *range(229, 229 + burst)]
    assert choice.explore_every == 256 and choice.best() == 1
    costs[2] = 1e-8  # the machine became quiet: the next retry wins and two threads stay
    later = []
    for _ in range(300):
        k = choice.pick()
        later.append(k)
        choice.record(k, costs[k])
    assert choice.best() == 2
    assert later[-100:].count(2) > 90
    single = ThreadChoice(1)
    for _ in range(40):
        assert single.pick() == 1
        single.record(1, 1e-8)
