"""Fuzzing of the readers and the model loader: any bytes load or raise a one-line error.

``io.read_tracks``, ``io.read_detections`` (plain, VUE and Fathom detection),
``io.read_receivers``, ``MovementHMM.load`` and ``sync.read_clocks`` get byte strings built
from CSV-like pieces (headers of each format, numbers, times, quotes, non-UTF-8 bytes,
ragged rows) and arbitrary bytes;
``MovementHMM.load`` gets arbitrary bytes and valid model files with fields replaced by
arbitrary JSON values or removed. Each either returns or raises a ``ValueError`` whose
message is one line naming the file; anything else (another exception, a traceback-worthy
bug, a multi-line message) fails.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hmmtrack import io
from hmmtrack.hmm import MovementHMM
from hmmtrack.scenarios.white_shark_hmm import load_white_shark_hmm
from hmmtrack.sync import read_clocks

PIECES = [
    b"id,time,x,y\n",
    b"time,receiver,transmitter\n",
    b"receiver,time,x,y\n",
    b"receiver,lon,lat\n",
    b"Date and Time (UTC),Receiver,Transmitter\n",
    b"VEMCO DATA LOG,1\n",
    b"DET_DESC,Time,Receiver,Transmitter\n",
    b"DET,2022-06-08 17:00:00,VR2W-1,A69-1602-1\n",
    b"a,2024-01-01T00:00:00Z,1.5,-2\n",
    b"2022-06-08T17:00:03.969Z,auv,A69-1602-1234\n",
    b"boat,,4.5,32.3\n",
    b"boat,nan,inf,1e999\n",
    b",,,\n",
    b'"a,b\n',
    b"1,2,3,4,5,6\n",
    b"1,2\n",
    b"\n",
    b"\xff\xfe",
    "é,ü".encode("latin-1"),
    b"\xef\xbb\xbf",  # a UTF-8 byte-order mark
]
CSV_BYTES = st.one_of(
    st.binary(max_size=300),
    st.lists(st.sampled_from(PIECES), max_size=10).map(b"".join),
)
READERS = {
    "tracks": io.read_tracks,
    "detections": io.read_detections,
    "receivers": io.read_receivers,
    "model": MovementHMM.load,
    "clocks": read_clocks,
}
FUZZ = settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])


def loads_or_says_why_in_one_line(reader, data: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "input.csv"
        path.write_bytes(data)
        try:
            reader(path)
        except ValueError as exc:
            text = str(exc)
            assert "\n" not in text.strip(), text
            assert "input.csv" in text, text


@pytest.mark.parametrize("name", READERS)
def test_any_bytes_load_or_raise_one_line(name):
    @FUZZ
    @given(CSV_BYTES)
    def check(data):
        loads_or_says_why_in_one_line(READERS[name], data)

    check()


def _paths(node, prefix=()):
    if prefix:
        yield prefix
    children = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(
        node, list) else ()  # fmt: skip
    for key, value in children:
        yield from _paths(value, (*prefix, key))


MODEL = load_white_shark_hmm().to_dict()
FIELDS = list(_paths(MODEL))
JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-3, 5) | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner,
                                                                max_size=3),
    max_leaves=8,
)  # fmt: skip


@FUZZ
@given(st.lists(st.tuples(st.sampled_from(FIELDS), JSON_VALUES, st.booleans()), max_size=3))
def test_model_files_with_changed_fields_load_or_raise_one_line(changes):
    document = json.loads(json.dumps(MODEL))
    for path, value, remove in changes:
        node = document
        try:
            for key in path[:-1]:
                node = node[key]
            if remove and isinstance(node, dict):
                del node[path[-1]]
            else:
                node[path[-1]] = value
        except (KeyError, IndexError, TypeError):
            pass  # an earlier change removed or replaced the field's parent
    loads_or_says_why_in_one_line(MovementHMM.load, json.dumps(document).encode())
