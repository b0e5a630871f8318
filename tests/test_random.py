import numpy as np

from hmmtrack.random import as_generator, spawn


def test_same_seed_same_stream():
    assert as_generator(7).normal(size=5).tolist() == as_generator(7).normal(size=5).tolist()


def test_generator_passes_through():
    rng = np.random.default_rng(1)
    assert as_generator(rng) is rng


def test_spawn_children_independent_and_repeatable():
    a = [np.random.default_rng(s).integers(1 << 30) for s in spawn(3, 4)]
    b = [np.random.default_rng(s).integers(1 << 30) for s in spawn(3, 4)]
    assert a == b
    assert len(set(a)) == 4
