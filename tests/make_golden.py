"""Write the golden runs' outputs: ``tests/data/golden/<case>/<table>.csv``.

Run ``python tests/make_golden.py`` (every case) or ``python tests/make_golden.py CASE ...``
to regenerate; the cases are the functions of ``tests/golden.py``. Each case's folder is
emptied first, and every table is read back and checked to compare exactly equal to what
was computed (``golden.differences``) before the script reports it.

Regenerate only when an answer is meant to change: ``tests/test_golden.py`` exists to
prove that a refactor did not change any.
"""

from __future__ import annotations

import sys
import time

import golden


def make(case: str) -> list[str]:
    """Compute ``case``, write its tables and read them back.

    Returns
    -------
    list of str
        A line per table: name, shape and file size.
    """
    tables = golden.CASES[case]()
    folder = golden.GOLDEN_DIR / case
    for old in folder.glob("*.csv"):
        old.unlink()
    lines = []
    for name, table in tables.items():
        path = folder / f"{name}.csv"
        golden.write_table(table, path)
        problems = golden.differences(golden.read_table(path), table, f"{case}/{name}")
        if problems:
            raise RuntimeError("the CSV does not round-trip:\n" + "\n".join(problems))
        lines.append(f"  {name}: {table.shape[0]} x {table.shape[1]}, {path.stat().st_size} bytes")
    return lines


def main(argv: list[str]) -> int:
    cases = argv or list(golden.CASES)
    unknown = sorted(set(cases) - set(golden.CASES))
    if unknown:
        print(f"unknown case(s) {unknown}; the cases are {list(golden.CASES)}", file=sys.stderr)
        return 2
    for case in cases:
        started = time.perf_counter()
        lines = make(case)
        print(f"{case} ({time.perf_counter() - started:.1f} s)")
        print("\n".join(lines))
    total = sum(path.stat().st_size for path in golden.GOLDEN_DIR.rglob("*.csv"))
    print(f"total {total} bytes in {golden.GOLDEN_DIR}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
