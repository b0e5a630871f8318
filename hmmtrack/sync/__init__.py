"""Receiver clock synchronisation from sync tags: fit, file, apply.

A moored array's receivers log detections in their own clocks, which disagree by seconds to
minutes and drift by parts per million. Sync tags moored beside some receivers are heard
by their neighbours; their travel times are known from the receivers' positions, so their
detections reveal every receiver's clock relative to one *time keeper*.

* :func:`fit_clocks` - the fit (:mod:`.fit`; grouping of emissions in :mod:`.pings`),
  returning a :class:`SyncFit` (clocks, per-detection residuals, per-receiver summary);
* :class:`ReceiverClocks`, :func:`write_clocks`, :func:`read_clocks` - the fitted clocks and
  their versioned JSON file (:mod:`.clocks`);
* :func:`apply_clocks` - detections moved to the common time base, the step before any
  arrival-time measurement model sees them;
* :func:`mackenzie_sound_speed` - sound speed from temperature and salinity (:mod:`.sound`).

Not for: tracking (:mod:`hmmtrack.tracking`); this package needs only the io tables.
"""

from hmmtrack.sync.clocks import ReceiverClocks, apply_clocks, read_clocks, write_clocks
from hmmtrack.sync.fit import SyncFit, fit_clocks
from hmmtrack.sync.sound import mackenzie_sound_speed

__all__ = [
    "ReceiverClocks",
    "SyncFit",
    "apply_clocks",
    "fit_clocks",
    "mackenzie_sound_speed",
    "read_clocks",
    "write_clocks",
]
