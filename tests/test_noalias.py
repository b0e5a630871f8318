"""numba's ``noalias`` flag for one function (:mod:`hmmtrack.tracking.compiled.noalias`)."""

import re

import numpy as np
from numba import njit

from hmmtrack.tracking.compiled.noalias import NoAliasCompiler


def _lookups(table, index, scale, out):
    """``out = table[index] * scale``: a gathered load and a store in one loop."""
    for i in range(out.size):
        out[i] = table[index[i]] * scale[i]


promised = njit(pipeline_class=NoAliasCompiler)(_lookups)
plain = njit(_lookups)


def _definition(dispatcher) -> str:
    """The LLVM definition line of ``dispatcher``'s one compiled function (not its wrappers)."""
    llvm = dispatcher.inspect_llvm(dispatcher.signatures[0])
    name = re.escape(dispatcher.py_func.__name__)
    lines = [line for line in llvm.splitlines() if line.startswith("define")]
    (line,) = [
        line for line in lines if re.search(rf"@_ZN.*{name}", line) and "cpython" not in line
    ]
    return line


def _arguments(line: str) -> list[str]:
    """The arguments of an LLVM ``define`` line, one string each."""
    return line[line.index("(") + 1 : line.rindex(")")].split(", ")


def test_the_pipeline_computes_what_the_plain_one_computes():
    rng = np.random.default_rng(3)
    table, scale = rng.normal(size=50), rng.normal(size=1000)
    index = rng.integers(0, 50, 1000)
    out, expected = np.empty(1000), np.empty(1000)
    promised(table, index, scale, out)
    plain(table, index, scale, expected)
    np.testing.assert_array_equal(out, table[index] * scale)
    np.testing.assert_array_equal(out, expected)


def test_every_pointer_argument_is_marked_noalias_only_by_the_pipeline():
    """The arrays' data pointers (and every other pointer argument) carry ``noalias`` with
    the pipeline; without it only numba's own return and exception pointers do."""
    n = np.zeros(3)
    promised(n, np.zeros(3, dtype=np.int64), n.copy(), np.empty(3))
    plain(n, np.zeros(3, dtype=np.int64), n.copy(), np.empty(3))
    pointers = [a for a in _arguments(_definition(promised)) if a.split()[0] == "ptr"]
    data = [a for a in pointers if a.endswith(".4")]  # an array's data: its fifth member
    assert [a.split("%arg.")[1] for a in data] == ["table.4", "index.4", "scale.4", "out.4"]
    assert all("noalias" in a for a in pointers)
    plain_pointers = [a for a in _arguments(_definition(plain)) if a.split()[0] == "ptr"]
    assert [a for a in plain_pointers if "noalias" in a] == [
        a for a in plain_pointers if "retptr" in a or "excinfo" in a
    ]
