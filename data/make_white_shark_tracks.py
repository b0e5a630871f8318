"""Write data/white_shark_tracks.csv.gz: the synthetic historical white-shark tracks.

A synthetic stand-in for the paper's non-public dataset (22 white sharks, ~124k positions,
Santa Barbara, May-August 2020), drawn from the documented ground-truth model of
``hmmtrack.scenarios.shark_motion`` and sampled like a receiver array
(``hmmtrack.scenarios.historical``). Columns: ``id``, ``time`` (ISO 8601 UTC), ``x``, ``y``
(m, UTM zone 11N, EPSG:32611), ``true_state`` (0 resident, 1 transit; the simulation's
truth, kept to check decoding). Run from the repository root::

    python data/make_white_shark_tracks.py

The same table is available without the file: ``hmmtrack.scenarios.white_shark_tracks()``.
"""

from __future__ import annotations

from pathlib import Path

from hmmtrack.io import format_times
from hmmtrack.scenarios.historical import WHITE_SHARK_TRACKS_SEED, white_shark_tracks

OUTPUT = Path(__file__).resolve().parent / "white_shark_tracks.csv.gz"


def main() -> None:
    tracks = white_shark_tracks(WHITE_SHARK_TRACKS_SEED)
    table = tracks.assign(time=format_times(tracks["time"].to_numpy()))
    # fixed gzip mtime so that the same data give the same bytes
    table.to_csv(
        OUTPUT, index=False, float_format="%.1f", compression={"method": "gzip", "mtime": 0}
    )
    segments = (tracks.groupby("id")["time"].diff().fillna(1e9) > 180).sum()
    print(
        f"wrote {OUTPUT}: {len(tracks)} positions of {tracks['id'].nunique()} sharks, "
        f"{segments} segments (gaps > 3 min), {OUTPUT.stat().st_size / 1e6:.2f} MB"
    )


if __name__ == "__main__":
    main()
