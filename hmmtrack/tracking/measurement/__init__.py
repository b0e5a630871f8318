"""Measurement models of the tracking filter, by name.

:data:`MEASUREMENTS` maps each name a configuration may give (``TrackingConfig.measurement``,
``hmmtrack track --measurement``) to its class, which follows the
:class:`hmmtrack.tracking.measurement.base.Measurement` protocol: ``"range-rate"``, the paper's
ranges and range-rates (:mod:`~hmmtrack.tracking.measurement.range_rate`), and
``"arrival-time"``, arrival times scored against an emission clock carried by every particle
(:mod:`~hmmtrack.tracking.measurement.clocked`), and ``"ping"``, the detections of one emission
scored jointly on their time differences, the emission time integrated out, for tags with a
random burst interval (:mod:`~hmmtrack.tracking.measurement.tdoa`), and ``"ping-sequence"``, the
same for a tag with a known pseudo-random interval sequence, its emission times known up to the
tag's clock (:mod:`~hmmtrack.tracking.measurement.sequence`), and ``"range-rate-gps"``, the paper's
ranges and range-rates with each receiver's GPS error as an offset correlated in time,
integrated out per particle (:mod:`~hmmtrack.tracking.measurement.gps_offset`). A new
measurement registers here.
"""

from hmmtrack.tracking.measurement.clocked import ClockedArrivalTime
from hmmtrack.tracking.measurement.gps_offset import GpsOffsetMeasurement
from hmmtrack.tracking.measurement.range_rate import RangeRateMeasurement
from hmmtrack.tracking.measurement.sequence import PingSequence
from hmmtrack.tracking.measurement.tdoa import PingTDOA

#: measurement classes by name
MEASUREMENTS = {
    cls.name: cls
    for cls in (
        RangeRateMeasurement,
        ClockedArrivalTime,
        PingTDOA,
        PingSequence,
        GpsOffsetMeasurement,
    )
}
