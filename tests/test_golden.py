"""The golden runs (``tests/golden.py``) give exactly the stored answers.

Every case is recomputed and compared with ``tests/data/golden/<case>/*.csv``: same
tables, same columns, same shape, the same numbers bit for bit (NaN equal to NaN), the
same text. A difference means an answer changed; if it was meant to, regenerate with
``python tests/make_golden.py`` and say why in the commit.
"""

from __future__ import annotations

import golden
import pytest


def test_every_case_is_stored_and_every_stored_case_exists():
    stored = sorted(path.name for path in golden.GOLDEN_DIR.iterdir() if path.is_dir())
    assert stored == sorted(golden.CASES)


@pytest.mark.parametrize("case", list(golden.CASES))
def test_golden_run_gives_the_stored_answer(case):
    tables = golden.CASES[case]()
    stored = golden.read_case(case)
    assert sorted(tables) == sorted(stored), f"{case}: tables {sorted(tables)}"
    problems = [
        problem
        for name, table in tables.items()
        for problem in golden.differences(stored[name], table, f"{case}/{name}")
    ]
    assert not problems, "\n".join(problems)
