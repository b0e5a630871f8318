"""File formats in and out: tracks, detection logs, receiver (hydrophone) tracks, estimates.

This package is the only place that parses or prints calendar times, knows map projections
and reads vendor formats. Everything it returns follows ``docs/interfaces.md``: times are UTC
seconds since the Unix epoch (``float64``, millisecond and finer precision kept) and
positions are projected metres (``x`` east, ``y`` north), with the CRS kept as WKT in
``attrs["crs"]``. Bad input raises ``ValueError`` (or ``FileNotFoundError``) naming the file,
lines and columns at fault.

Readers and writers (the names below are the package's public face)
--------------------------------------------------------------------
* :func:`read_tracks` -- plain CSV of animal fixes (id, time, x, y in metres);
  :func:`read_movebank` -- Movebank CSV (``timestamp``, ``location-long``, ``location-lat``,
  ``individual-local-identifier``), projected with :class:`Projection` (:mod:`.tracks`).
* :func:`read_detections` -- Innovasea VUE export, Innovasea Fathom CSV, or plain CSV
  (:mod:`.detections`).
* :func:`read_receivers` -- GPS tracks of mobile receivers, or one row per moored receiver;
  :func:`validate_receivers` checks such a table; :func:`receivers_from_yaps_hydros` turns
  a YAPS hydros table into one (:mod:`.receivers`).
* :func:`read_burst_sequence` -- the interval sequence of a tag with a known pseudo-random
  burst interval (:mod:`.sequence`).
* :func:`write_estimates` -- the filter's estimates with ISO 8601 UTC times (and lon/lat);
  :func:`read_truth` -- a truth track to score them against (:mod:`.estimates`).
* :func:`parse_times`, :func:`format_times` -- ISO 8601 UTC <-> epoch seconds
  (:mod:`.times`, which documents the time-zone rules).
* :class:`Projection`, :func:`choose_projection`, :func:`bounds_in_metres` -- lon/lat <->
  metres (:mod:`.geo`).

Row bookkeeping
---------------
Tables read from a file carry an index named ``"line"`` holding each row's 1-based line in
the file (header = line 1) and ``attrs["source"]`` (the file name), so that later errors
(:func:`hmmtrack.tracks.describe_rows`) still name file lines. Blank lines carry no data and
are skipped. Rows removed on request (``missing_coordinates="drop"``) are listed in
``attrs["dropped"]`` (``[{"rows": [line, ...], "reason": str}]``) and logged as a warning;
nothing else is ever removed (:mod:`.tables`).

Not for: track maths (:mod:`hmmtrack.tracks`), ranging
(:mod:`hmmtrack.tracking.measurement.ranging`).
"""

from hmmtrack.io.detections import (
    VUE_COLUMNS,
    detect_format,
    drop_duplicate_detections,
    read_detections,
)
from hmmtrack.io.estimates import EstimatesWriter, read_truth, write_estimates
from hmmtrack.io.geo import Projection, bounds_in_metres, choose_projection
from hmmtrack.io.receivers import read_receivers, receivers_from_yaps_hydros, validate_receivers
from hmmtrack.io.sequence import read_burst_sequence
from hmmtrack.io.times import format_times, parse_times
from hmmtrack.io.tracks import read_movebank, read_tracks

__all__ = [
    "VUE_COLUMNS",
    "EstimatesWriter",
    "Projection",
    "bounds_in_metres",
    "choose_projection",
    "detect_format",
    "drop_duplicate_detections",
    "format_times",
    "read_burst_sequence",
    "parse_times",
    "read_detections",
    "read_movebank",
    "read_receivers",
    "receivers_from_yaps_hydros",
    "read_tracks",
    "read_truth",
    "validate_receivers",
    "write_estimates",
]
