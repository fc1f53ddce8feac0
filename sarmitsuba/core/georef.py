"""Geographic reference of a scene: its local east-north-up frame placed on the WGS84 ellipsoid.

A scene's world frame (the frame of its XML, metres) is taken as a local east-north-up (ENU,
topocentric) frame whose origin sits at the sensor parameter ``geo_origin`` = latitude [deg],
longitude [deg], height [m] above the WGS84 ellipsoid: x east, y north, z up along the
ellipsoid normal (docs/physics.md (GEO1)). The maps to Earth-centred Earth-fixed (ECEF, EPSG:4978),
geodetic (EPSG:4979) and UTM coordinates are PROJ's, through pyproj (the ``cart`` and
``topocentric`` operations; Snyder 1987 for UTM); this module only assembles them.

Defaults:

- a scene that gives no ``geo_origin`` sits at :data:`DEFAULT`, 0 deg N 0 deg E 0 m, a
  placeholder that GIS users recognise ("null island") and that ``info`` marks as such;
- Sionna RT's Munich (``sionna:munich``) sits at :data:`SCENE_ORIGINS` ``["munich"]``. Sionna
  publishes no geographic origin for its scenes, so this one is an estimate: the scene's x axis
  points east and its y axis north, and the origin puts the centre of the scene's Frauenkirche
  mesh, (-163, 66) m, at the church's published position, 48 deg 08' 19" N, 11 deg 34' 25" E
  (Wikipedia, "Frauenkirche, Munich"); the height is Munich's 519 m above sea level plus a geoid
  height of about 47 m. Good to some tens of metres: enough to overlay a map, not to geocode
  one facade.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["GeoReference", "GeoReferenceError", "DEFAULT", "SCENE_ORIGINS", "of", "parse",
           "enu_to_ecef", "ecef_to_enu", "enu_axes", "enu_to_geodetic", "geodetic_to_enu", "utm_crs",
           "enu_to_utm"]


class GeoReferenceError(ValueError):
    """A geographic origin outside its valid range (names ``geo_origin`` and the range)."""


@dataclass(frozen=True)
class GeoReference:
    """WGS84 position of a scene's local origin.

    Attributes
    ----------
    latitude_deg : float
        Geodetic latitude [deg], in [-90, 90].
    longitude_deg : float
        Longitude [deg], in [-180, 180].
    height_m : float
        Height above the WGS84 ellipsoid [m], in [-11000, 100000].
    """

    latitude_deg: float
    longitude_deg: float
    height_m: float = 0.0

    def __post_init__(self) -> None:
        for name, value, lo, hi, unit in (("latitude", self.latitude_deg, -90.0, 90.0, "deg"),
                                          ("longitude", self.longitude_deg, -180.0, 180.0, "deg"),
                                          ("height", self.height_m, -11000.0, 1e5, "m")):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
                raise GeoReferenceError(
                    f"geo_origin: {name} = {value!r} {unit} is outside the valid range [{lo:g}, {hi:g}] {unit} "
                    "(geo_origin = \"latitude, longitude, height\": degrees north, degrees east, metres "
                    "above the WGS84 ellipsoid, e.g. \"48.137, 11.575, 519\")")

    def as_tuple(self) -> tuple[float, float, float]:
        """(latitude [deg], longitude [deg], height [m])."""
        return (float(self.latitude_deg), float(self.longitude_deg), float(self.height_m))

    def describe(self) -> str:
        """``48.13780 N, 11.57570 E, 519.0 m`` (hemisphere letters, 1 cm of latitude)."""
        lat, lon, h = self.as_tuple()
        return f"{abs(lat):.5f} {'N' if lat >= 0 else 'S'}, {abs(lon):.5f} {'E' if lon >= 0 else 'W'}, {h:.1f} m"


#: The placeholder origin of a scene that gives none: 0 deg N, 0 deg E, on the ellipsoid.
DEFAULT = GeoReference(0.0, 0.0, 0.0)

#: Origins of Sionna RT scenes whose place is known (``sionna:NAME`` -> origin); see the module docstring.
SCENE_ORIGINS = {"munich": GeoReference(48.13802, 11.57580, 566.0)}


def parse(value: Any) -> GeoReference | None:
    """``"lat, lon, h"`` (or ``"lat lon h"``, or a 2- or 3-sequence; h defaults to 0) to a GeoReference.

    None and ``""`` give None (the scene's default). Raises GeoReferenceError naming ``geo_origin``.
    """
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if isinstance(value, GeoReference):
        return value
    parts = value.replace(",", " ").split() if isinstance(value, str) else list(value)
    try:
        numbers = [float(p) for p in parts]
    except (TypeError, ValueError):
        numbers = []
    if len(numbers) not in (2, 3):
        raise GeoReferenceError(f"geo_origin = {value!r} must be \"latitude, longitude[, height]\" in degrees "
                                "north, degrees east and metres above the WGS84 ellipsoid, e.g. \"48.137, 11.575, 519\"")
    return GeoReference(*numbers)


def of(radar: Any) -> GeoReference:
    """The geographic reference of radar parameters: their ``geo_origin``, else :data:`DEFAULT`.

    ``radar`` is a :class:`~sarmitsuba.core.radar.RadarParameters` or its dictionary form as stored
    in ``metadata["radar"]`` of raw data and images (missing key: :data:`DEFAULT`).
    """
    value = radar.get("geo_origin") if isinstance(radar, dict) else getattr(radar, "geo_origin", None)
    return parse(value) or DEFAULT


@functools.lru_cache(maxsize=16)
def _topocentric(ref: GeoReference) -> Any:
    """pyproj Transformer ECEF -> ENU at ``ref`` (PROJ ``cart`` + ``topocentric``), cached."""
    from pyproj import Transformer
    lat, lon, h = ref.as_tuple()
    return Transformer.from_pipeline(
        f"+proj=pipeline +step +proj=topocentric +ellps=WGS84 +lat_0={lat!r} +lon_0={lon!r} +h_0={h!r}")


@functools.lru_cache(maxsize=4)
def _geocentric_to_geodetic() -> Any:
    """pyproj Transformer ECEF (EPSG:4978) -> geodetic lat, lon, h (EPSG:4979)."""
    from pyproj import Transformer
    return Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=False)


def _apply(transformer: Any, points: np.ndarray, inverse: bool) -> np.ndarray:
    """Run a 3-D pyproj transform on float64 [..., 3] points; same shape out."""
    from pyproj.enums import TransformDirection
    pts = np.asarray(points, dtype=np.float64)
    flat = pts.reshape(-1, 3)
    direction = TransformDirection.INVERSE if inverse else TransformDirection.FORWARD
    x, y, z = transformer.transform(flat[:, 0], flat[:, 1], flat[:, 2], direction=direction)
    return np.column_stack([x, y, z]).reshape(pts.shape)


def enu_to_ecef(points: np.ndarray, ref: GeoReference = DEFAULT) -> np.ndarray:
    """Local ENU metres [..., 3] (float64) at ``ref`` to ECEF metres [..., 3] (WGS84, EPSG:4978)."""
    return _apply(_topocentric(ref), points, inverse=True)


def ecef_to_enu(points: np.ndarray, ref: GeoReference = DEFAULT) -> np.ndarray:
    """ECEF metres [..., 3] to local ENU metres [..., 3] at ``ref`` (inverse of :func:`enu_to_ecef`)."""
    return _apply(_topocentric(ref), points, inverse=False)


def enu_axes(ref: GeoReference = DEFAULT) -> np.ndarray:
    """float64 [3, 3]: row i is the ECEF unit vector of local axis i (east, north, up) at ``ref``.

    Velocities and directions map as ``v_ecef = v_enu @ enu_axes(ref)`` (the map is rigid).
    """
    scale = 1.0e3
    points = enu_to_ecef(np.vstack([np.zeros(3), scale * np.eye(3)]), ref)
    return (points[1:] - points[0]) / scale


def enu_to_geodetic(points: np.ndarray, ref: GeoReference = DEFAULT) -> np.ndarray:
    """Local ENU metres [..., 3] to geodetic [..., 3]: latitude [deg], longitude [deg], height [m] (WGS84)."""
    return _apply(_geocentric_to_geodetic(), enu_to_ecef(points, ref), inverse=False)


def geodetic_to_enu(llh: np.ndarray, ref: GeoReference = DEFAULT) -> np.ndarray:
    """Geodetic [..., 3] (latitude [deg], longitude [deg], height [m], WGS84) to local ENU metres
    [..., 3] at ``ref`` (inverse of :func:`enu_to_geodetic`)."""
    return ecef_to_enu(_apply(_geocentric_to_geodetic(), llh, inverse=True), ref)


def utm_crs(ref: GeoReference = DEFAULT) -> Any:
    """The pyproj CRS of the WGS84 UTM zone holding ``ref`` (EPSG:326zz north, 327zz south)."""
    from pyproj import CRS
    zone = min(int((ref.longitude_deg + 180.0) // 6.0) + 1, 60)
    return CRS.from_epsg((32600 if ref.latitude_deg >= 0 else 32700) + zone)


def enu_to_utm(points: np.ndarray, ref: GeoReference = DEFAULT) -> np.ndarray:
    """Local ENU metres [..., 3] to (easting, northing) [..., 2] in :func:`utm_crs` of ``ref`` [m]."""
    from pyproj import Transformer
    llh = enu_to_geodetic(points, ref)
    to_utm = Transformer.from_crs("EPSG:4326", utm_crs(ref), always_xy=True)
    east, north = to_utm.transform(llh[..., 1].ravel(), llh[..., 0].ravel())
    return np.stack([np.asarray(east), np.asarray(north)], axis=-1).reshape(llh.shape[:-1] + (2,))
