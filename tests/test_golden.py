"""The golden runs (``tests/golden.py``) give the stored answers.

Every case is recomputed and compared with ``tests/data/golden/<case>/*.csv``: same
tables, same columns, same shape, the same integers and text, and floats equal to within
:data:`golden.ACROSS_MACHINES` of each column's scale (NaN equal to NaN): the stored
answers were made on one machine, and another CPU or another NumPy or numba release
changes their last bits. A difference means an answer changed; if it was meant to,
regenerate with ``python tests/make_golden.py`` and say why in the commit. The same bits
before and after a change on one machine are ``benchmarks/run_hashes.py``'s check.
"""

from __future__ import annotations

import golden
import numpy as np
import pandas as pd
import pytest


def test_every_case_is_stored_and_every_stored_case_exists():
    stored = sorted(path.name for path in golden.GOLDEN_DIR.iterdir() if path.is_dir())
    assert stored == sorted(golden.CASES)


@pytest.mark.parametrize("case", list(golden.CASES))
def test_golden_run_gives_the_stored_answer(case):
    tables = golden.CASES[case]()
    stored = golden.read_case(case)
    assert sorted(tables) == sorted(stored), f"{case}: tables {sorted(tables)}"
    tolerance = golden.ACROSS_MACHINES
    problems = [
        problem
        for name, table in tables.items()
        for problem in golden.differences(stored[name], table, f"{case}/{name}", tolerance)
    ]
    assert not problems, "\n".join(problems)


def test_the_tolerance_passes_last_bits_and_catches_a_changed_answer():
    """Across machines a float may move in its last bits, never by a changed answer's
    amount; integers and text stay exact, and ``rtol = 0`` asks for the same bits."""
    stored = pd.DataFrame(
        {"x": [74.04518321546325, -1930.8306464504058, np.nan], "n": [1, 2, 3], "kind": list("abc")}
    )
    last_bits = stored.assign(x=[74.0451832154632, -1930.830646450384, np.nan])
    assert golden.differences(stored, last_bits, "t", golden.ACROSS_MACHINES) == []
    assert len(golden.differences(stored, last_bits, "t")) == 1  # (bits: rtol = 0)
    for changed in (
        stored.assign(x=[74.04518321546325 * (1 + 1e-7), -1930.8306464504058, np.nan]),
        stored.assign(x=[74.04518321546325, -1930.8306464504058, 0.0]),  # (NaN no more)
        stored.assign(n=[1, 2, 4]),
        stored.assign(kind=list("abd")),
    ):
        assert len(golden.differences(stored, changed, "t", golden.ACROSS_MACHINES)) == 1
