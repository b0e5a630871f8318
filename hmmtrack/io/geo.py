"""Map projections: WGS 84 lon/lat (degrees) <-> projected metres (``x`` east, ``y`` north).

Readers of lon/lat data take ``projection=`` (a :class:`Projection`, or ``"utm"`` /
``"local"`` to choose one from the data's centre) so that tracks, receivers, estimates and
search boxes share one frame; the chosen CRS is stored as WKT in ``attrs["crs"]``
(:meth:`Projection.from_frame` gives it back).

This is the only module of the package that knows coordinate reference systems.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from pyproj import CRS, Transformer
from pyproj.aoi import AreaOfInterest
from pyproj.database import query_utm_crs_info
from pyproj.exceptions import CRSError

from hmmtrack.tracks import describe_rows


@dataclass(frozen=True)
class Projection:
    """A map projection between WGS 84 lon/lat (degrees) and local metres.

    Parameters
    ----------
    crs : str
        The projected CRS as WKT (what ``attrs["crs"]`` stores).

    Use :meth:`utm` or :meth:`local` to choose one for data, :meth:`from_epsg` for a named
    CRS, :meth:`from_frame` to recover the one a table was projected with.
    """

    crs: str

    @classmethod
    def utm(cls, lon: np.ndarray, lat: np.ndarray) -> Projection:
        """The WGS 84 UTM zone that contains the centre of the points (degrees)."""
        lon0, lat0 = _centre(lon, lat)
        found = query_utm_crs_info(
            datum_name="WGS 84",
            area_of_interest=AreaOfInterest(lon0, lat0, lon0, lat0),
        )
        if not found:
            raise ValueError(f"no UTM zone found for lon {lon0}, lat {lat0}")
        return cls(CRS.from_epsg(int(found[0].code)).to_wkt())

    @classmethod
    def local(cls, lon: np.ndarray, lat: np.ndarray) -> Projection:
        """An azimuthal equidistant projection centred on the points (distances from the
        centre exact; good for small study areas anywhere, including across UTM zones)."""
        lon0, lat0 = _centre(lon, lat)
        return cls(
            CRS.from_proj4(
                f"+proj=aeqd +lat_0={lat0} +lon_0={lon0} +datum=WGS84 +units=m +no_defs"
            ).to_wkt()
        )

    @classmethod
    def from_epsg(cls, code: str | int) -> Projection:
        """The projected CRS in metres of an EPSG code (``"EPSG:32612"``, ``"32612"``, 32612).

        Raises
        ------
        ValueError
            For text that is not an EPSG code, an unknown code, or a CRS that is not projected
            in metres (e.g. EPSG:4326, lon/lat degrees).
        """
        text = str(code).strip()
        number = text.upper().removeprefix("EPSG:")
        if not number.isdigit():
            raise ValueError(
                f"projection must be 'utm', 'local' or an EPSG code such as 'EPSG:32612', "
                f"got {code!r}"
            )
        try:
            crs = CRS.from_epsg(int(number))
        except CRSError as exc:
            raise ValueError(f"EPSG:{number} is not a known coordinate reference system") from exc
        units = {axis.unit_name for axis in crs.axis_info}
        if not crs.is_projected or units != {"metre"}:
            raise ValueError(
                f"EPSG:{number} ({crs.name}) is not a projected CRS in metres (axis units "
                f"{sorted(units)}); give one in metres, e.g. the UTM zone's EPSG:326NN, or 'utm'"
            )
        return cls(crs.to_wkt())

    @classmethod
    def from_frame(cls, table: pd.DataFrame) -> Projection | None:
        """The projection stored in ``table.attrs["crs"]``, or ``None``."""
        crs = table.attrs.get("crs")
        return cls(crs) if crs else None

    def _transformer(self, inverse: bool) -> Transformer:
        src, dst = "EPSG:4326", CRS.from_user_input(self.crs)
        if inverse:
            src, dst = dst, src
        return Transformer.from_crs(src, dst, always_xy=True)

    def to_xy(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project lon/lat (degrees, shape (n,)) to x, y (m, shape (n,))."""
        x, y = self._transformer(False).transform(np.asarray(lon, float), np.asarray(lat, float))
        return np.asarray(x, float), np.asarray(y, float)

    def to_lonlat(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unproject x, y (m, shape (n,)) to lon/lat (degrees, shape (n,))."""
        lon, lat = self._transformer(True).transform(np.asarray(x, float), np.asarray(y, float))
        return np.asarray(lon, float), np.asarray(lat, float)


def _centre(lon: np.ndarray, lat: np.ndarray) -> tuple[float, float]:
    lon = np.asarray(lon, float)
    lat = np.asarray(lat, float)
    ok = np.isfinite(lon) & np.isfinite(lat)
    if not ok.any():
        raise ValueError("cannot choose a projection: no finite lon/lat")
    # circular mean of longitudes so that data across the antimeridian centre correctly
    rad = np.deg2rad(lon[ok])
    lon0 = float(np.rad2deg(np.arctan2(np.sin(rad).mean(), np.cos(rad).mean())))
    return lon0, float(np.mean(lat[ok]))


def choose_projection(
    lon: np.ndarray, lat: np.ndarray, projection: Projection | str | int = "utm"
) -> Projection:
    """Projection for lon/lat data (degrees, shape (n,)).

    ``projection`` is a :class:`Projection` (returned as it is, e.g. one shared with the
    receivers), ``"utm"`` (the UTM zone of the data's centre), ``"local"`` (azimuthal
    equidistant about the centre) or an EPSG code (``"EPSG:32612"``, ``"32612"`` or the
    integer) of a projected CRS in metres, such as the one a study area's maps use.
    """
    if isinstance(projection, Projection):
        return projection
    if projection == "utm":
        return Projection.utm(lon, lat)
    if projection == "local":
        return Projection.local(lon, lat)
    return Projection.from_epsg(projection)


def check_lonlat(table: pd.DataFrame, lon: str, lat: str) -> None:
    """Raise naming the rows whose longitude or latitude (degrees) is out of range."""
    for col, limit in ((lat, 90.0), (lon, 180.0)):
        values = table[col].to_numpy(dtype=float)
        bad = np.flatnonzero(np.abs(values) > limit)
        if bad.size:
            name = "latitude" if col == lat else "longitude"
            raise ValueError(
                f"{describe_rows(table, bad)}: {name} out of [-{limit:g}, {limit:g}] degrees in "
                f"column {col!r} (found {values[bad[0]]!r}); are longitude and latitude "
                "swapped or projected?"
            )


#: no projected coordinate on Earth is farther from its origin (m): half the equator
LARGEST_METRES = 2.0e7


def check_metres(table: pd.DataFrame, x: str, y: str) -> None:
    """Raise when x/y columns declared as metres cannot be: a value beyond
    :data:`LARGEST_METRES`, or values that look like lon/lat degrees (every ``|x| <= 180`` and
    ``|y| <= 90``, away from the origin, spanning under a metre both ways: a receiver array
    or a track in degrees, which read as metres would put everything within a metre)."""
    xs, ys = table[x].to_numpy(dtype=float), table[y].to_numpy(dtype=float)
    for col, values in ((x, xs), (y, ys)):
        bad = np.flatnonzero(np.abs(values) > LARGEST_METRES)
        if bad.size:
            raise ValueError(
                f"{describe_rows(table, bad)}: column {col!r} holds {values[bad[0]]:g}, farther "
                f"than any projected coordinate on Earth ({LARGEST_METRES:g} m); x and y must be "
                "metres (not millimetres or cm), or give lon and lat columns in degrees"
            )
    if not xs.size:
        return
    degrees = np.all(np.abs(xs) <= 180.0) and np.all(np.abs(ys) <= 90.0)
    spans = np.ptp(xs), np.ptp(ys)
    if degrees and max(spans) < 1.0 and max(np.abs(xs).max(), np.abs(ys).max()) > 1.0:
        raise ValueError(
            f"{table.attrs.get('source', 'table')}: columns {x!r}, {y!r} look like longitude "
            f"and latitude in degrees ({x} {xs.min():g} to {xs.max():g}, {y} {ys.min():g} to "
            f"{ys.max():g}: all within a metre if read as metres); name the columns lon and "
            "lat to have them projected to metres, or give x and y in metres"
        )


def bounds_in_metres(
    bounds: tuple[float, float, float, float], projection: Projection
) -> tuple[float, float, float, float]:
    """The smallest x/y box (m) that holds a lon/lat box, in a projection's metres.

    Parameters
    ----------
    bounds : (lon_min, lon_max, lat_min, lat_max)
        Degrees (WGS 84), ``lon_min < lon_max`` (a box across the antimeridian is not
        supported), latitudes in [-90, 90].
    projection : Projection
        The projection the receivers were converted with.

    Returns
    -------
    (xmin, xmax, ymin, ymax) : tuple of float
        Metres: the box's edges, each projected at 201 points, bounded (a projected
        lon/lat box is not a rectangle: the x/y box is slightly larger).

    Raises
    ------
    ValueError
        If ``bounds`` are not an ordered lon/lat box, or reach outside the projection.
    """
    lon_min, lon_max, lat_min, lat_max = bounds
    if not (-180.0 <= lon_min < lon_max <= 180.0 and -90.0 <= lat_min < lat_max <= 90.0):
        raise ValueError(
            "bounds are LON_MIN LON_MAX LAT_MIN LAT_MAX in degrees when the receivers are "
            "given in lon/lat: longitudes in [-180, 180], latitudes in [-90, 90], min < max; "
            f"got {tuple(bounds)} (metres of a projection are not accepted)"
        )
    t = np.linspace(0.0, 1.0, 201)
    lon = lon_min + (lon_max - lon_min) * t
    lat = lat_min + (lat_max - lat_min) * t
    edge_lon = np.concatenate([lon, lon, np.full_like(lat, lon_min), np.full_like(lat, lon_max)])
    edge_lat = np.concatenate([np.full_like(lon, lat_min), np.full_like(lon, lat_max), lat, lat])
    x, y = projection.to_xy(edge_lon, edge_lat)
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise ValueError(
            f"bounds {tuple(bounds)} (lon/lat degrees) reach outside the receivers' "
            "projection: give a box near the receivers"
        )
    return float(x.min()), float(x.max()), float(y.min()), float(y.max())
