"""Building footprints from GeoJSON: outlines, heights, roofs and materials, checked.

A footprint file is a GeoJSON ``FeatureCollection`` (RFC 7946: WGS84 longitude, latitude) of
``Polygon`` and ``MultiPolygon`` features, holes (courtyards) included, as OpenStreetMap
exports (overpass-turbo, osmtogeojson), cadastral data and the Microsoft and Google building
footprints come or convert. :func:`read_footprints` turns it into :class:`Footprint` records;
:mod:`sarmitsuba.scene.city` extrudes them into meshes.

Properties read (OpenStreetMap's conventions, https://wiki.openstreetmap.org/wiki/Key:height,
``Key:building:levels``, ``Key:roof:shape``, ``Key:building:material``):

==========================  =========================================================================
``height``                  metres from the lowest ground point to the top of the roof; a number or
                            ``"12"``, ``"12 m"``, ``"40 ft"``
``building:levels``         used when ``height`` is missing: :data:`LEVEL_HEIGHT` (3 m) per level
``roof:shape``              ``flat`` (default), ``gabled``, ``hipped`` or ``pyramidal``; any other
                            shape is modelled flat, with a warning naming the features
``roof:height``             metres of the roof above its eaves (part of ``height``); else
                            ``roof:levels`` x 3 m; else the height of a :data:`ROOF_PITCH_DEG` pitch
``roof:orientation``        ``along`` (default: ridge along the longer side) or ``across``
``building:material``,      an ITU-R P.2040 name (``concrete``, ``brick``, ``glass``, ``metal``,
``material``                ``wood``, ``marble``, ...) or an OpenStreetMap value of
                            :data:`OSM_MATERIALS` (``stone`` -> ``marble``, ``steel`` -> ``metal``, ...)
==========================  =========================================================================

A feature is named in messages by its index in the file and its ``id`` (the feature's, else
the ``id``, ``@id`` or ``name`` property). Every problem of a file is collected and reported
together, one line per feature (:class:`FootprintError`); nothing is written.
"""
from __future__ import annotations

import json
import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.valid_ranges import unknown_name
from . import materials
from .loader import SceneError

__all__ = ["FootprintError", "Footprint", "FootprintSet", "read_footprints", "parse_footprints", "building_material",
           "LEVEL_HEIGHT", "ROOF_PITCH_DEG", "ROOF_SHAPES", "OSM_MATERIALS"]

#: m per storey of ``building:levels`` (and ``roof:levels``), OpenStreetMap's usual assumption.
LEVEL_HEIGHT = 3.0
#: deg: roof pitch of a gabled, hipped or pyramidal roof that gives no ``roof:height`` (a roof within a
#: measured ``height`` is kept to at most half of it).
ROOF_PITCH_DEG = 30.0
#: Roof shapes built as such; any other ``roof:shape`` is built flat (with a warning).
ROOF_SHAPES = ("flat", "gabled", "hipped", "pyramidal")
#: OpenStreetMap ``building:material`` values -> ITU-R P.2040 material (stone has no ITU model;
#: marble, the only stone of P.2040 Table 3, stands for it).
OSM_MATERIALS = {
    "reinforced_concrete": "concrete", "cement_block": "concrete", "plaster": "concrete",
    "stone": "marble", "sandstone": "marble", "limestone": "marble", "granite": "marble",
    "steel": "metal", "aluminium": "metal", "copper": "metal", "timber_framing": "wood",
    "log": "wood", "bamboo": "wood", "mirror": "glass",
}
_UNITS = {"": 1.0, "m": 1.0, "ft": 0.3048, "'": 0.3048}


class FootprintError(SceneError):
    """Bad footprints: ``problems`` holds one line per feature (or one for the file)."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = list(problems)


@dataclass(frozen=True)
class Footprint:
    """One building: its outline, height, roof and material.

    Attributes
    ----------
    index : int
        Position of its feature in the file's ``features`` (0-based).
    label : str
        ``feature 3 (id way/123)``: how messages name it.
    slug : str
        ``b3_way_123``: the shape id and mesh file name (letters, digits, ``_``).
    polygon : shapely.Polygon or shapely.MultiPolygon
        The outline in longitude, latitude [deg] (WGS84), valid (shapely ``is_valid``).
    height : float, m
        Ground to the top of the roof (``height``), or to the eaves (``building:levels`` or the
        default height: a pitched roof then sits on top, as OpenStreetMap counts roof storeys apart).
    roof_shape : str
        One of :data:`ROOF_SHAPES`.
    roof_height : float or None, m
        Eaves to ridge (0 for a flat roof; None: from a :data:`ROOF_PITCH_DEG` pitch).
    roof_across : bool
        Ridge across the longer side (``roof:orientation = across``).
    material : str
        ITU-R P.2040 name.
    repaired : str
        What ``make_valid`` changed (``""``: nothing).
    """

    index: int
    label: str
    slug: str
    polygon: Any
    height: float
    roof_shape: str
    roof_height: float | None
    roof_across: bool
    material: str
    repaired: str = ""
    roof_on_top: bool = False


@dataclass(frozen=True)
class FootprintSet:
    """The footprints of one file.

    Attributes
    ----------
    source : str
        The file's path (or ``"<geojson>"`` for a parsed object).
    footprints : tuple of Footprint
    repairs : tuple of str
        One line per repaired feature: ``feature 3 (id way/7): self-intersection, repaired (...)``.
    """

    source: str
    footprints: tuple
    repairs: tuple = ()

    def bounds(self) -> tuple[float, float, float, float]:
        """(min longitude, min latitude, max longitude, max latitude) [deg] of all outlines."""
        b = np.array([f.polygon.bounds for f in self.footprints])
        return float(b[:, 0].min()), float(b[:, 1].min()), float(b[:, 2].max()), float(b[:, 3].max())

    def centre(self) -> tuple[float, float]:
        """(latitude, longitude) [deg] of the centre of :meth:`bounds`: the scene's origin."""
        lon0, lat0, lon1, lat1 = self.bounds()
        return 0.5 * (lat0 + lat1), 0.5 * (lon0 + lon1)


def read_footprints(path: str | Path, default_height: float | None = None, material: str = "concrete",
                    repair: bool = False) -> FootprintSet:
    """Read and check a GeoJSON footprint file (see the module docstring).

    Parameters
    ----------
    path : path-like
        GeoJSON ``FeatureCollection`` (or a single ``Feature``) in WGS84 longitude, latitude.
    default_height : float, optional
        m, for buildings with neither ``height`` nor ``building:levels``; None: such a building
        is an error.
    material : str, default "concrete"
        Material of buildings without ``building:material`` / ``material``.
    repair : bool, default False
        Repair invalid outlines (self-intersections, bow-ties) with shapely's ``make_valid``
        and report each in :attr:`FootprintSet.repairs`; without it an invalid outline is an error.

    Raises
    ------
    FootprintError
        The file cannot be read or is not GeoJSON; or features are bad (one line each:
        invalid or empty outline, not a polygon, no height, unknown material, bad value).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise FootprintError([f"{path}: cannot read footprints: {getattr(exc, 'strerror', None) or exc}"]) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FootprintError([f"{path}: not GeoJSON (JSON error at line {exc.lineno}, column {exc.colno}: "
                              f"{exc.msg}); give a GeoJSON FeatureCollection of building polygons"]) from None
    return parse_footprints(data, str(path), default_height, material, repair)


def parse_footprints(data: Any, source: str = "<geojson>", default_height: float | None = None,
                     material: str = "concrete", repair: bool = False) -> FootprintSet:
    """:func:`read_footprints` of an already parsed GeoJSON object (dict); same checks and errors."""
    features = _features(data, source)
    _check_default(source, default_height, material)
    footprints, problems, repairs, odd_roofs = [], [], [], []
    for index, feature in enumerate(features):
        label = f"feature {index}" + _identity(feature)
        try:
            footprint, note = _footprint(index, label, feature, default_height, material, repair)
        except ValueError as exc:
            problems.append(f"{source}: {label}: {exc}")
            continue
        footprints.append(footprint)
        if note:
            repairs.append(f"{label}: {note}")
        shape = str((feature.get("properties") or {}).get("roof:shape", "flat")).strip().lower()
        if shape not in ROOF_SHAPES:
            odd_roofs.append(f"{index} ({shape})")
    if problems:
        raise FootprintError(problems)
    if not footprints:
        raise FootprintError([f"{source}: no features: give at least one building polygon"])
    if odd_roofs:
        warnings.warn(f"{source}: roof shapes other than {', '.join(ROOF_SHAPES)} are built flat: features "
                      f"{', '.join(odd_roofs[:10])}{' ...' if len(odd_roofs) > 10 else ''}", stacklevel=2)
    return FootprintSet(source, tuple(footprints), tuple(repairs))


def _features(data: Any, source: str) -> list:
    """The feature list of a FeatureCollection (or [feature]); FootprintError for anything else."""
    kind = data.get("type") if isinstance(data, dict) else None
    if kind == "Feature":
        return [data]
    if kind == "FeatureCollection" and isinstance(data.get("features"), list):
        return data["features"]
    what = f"a GeoJSON {kind}" if isinstance(kind, str) else f"JSON {type(data).__name__}"
    raise FootprintError([f"{source}: not a GeoJSON FeatureCollection ({what}): give a FeatureCollection of "
                          "Polygon / MultiPolygon features in WGS84 longitude, latitude (RFC 7946)"])


def _check_default(source: str, default_height: float | None, material: str) -> None:
    """FootprintError for a bad ``default_height`` or ``material`` argument."""
    if default_height is not None and not (math.isfinite(default_height) and 0.0 < default_height <= 1000.0):
        raise FootprintError([f"--default-height = {default_height!r} m is outside (0, 1000] m: give the height "
                              "of buildings that have neither height nor building:levels"])
    try:
        building_material(material)
    except ValueError as exc:
        raise FootprintError([f"--material: {exc}"]) from None


def _identity(feature: Any) -> str:
    """`` (id way/123)`` or `` (name Town hall)`` of a feature; ``""`` when it has neither."""
    if not isinstance(feature, dict):
        return ""
    props = feature.get("properties") if isinstance(feature.get("properties"), dict) else {}
    for key, value in (("id", feature.get("id")), ("id", props.get("id")), ("id", props.get("@id")),
                       ("name", props.get("name"))):
        if value not in (None, ""):
            return f" ({key} {value})"
    return ""


def _slug(index: int, feature: dict) -> str:
    """Shape id of a feature: ``b<index>`` plus its id or name in letters, digits and ``_``."""
    ident = _identity(feature)
    tail = re.sub(r"[^A-Za-z0-9]+", "_", ident.split(" ", 2)[-1].rstrip(")")).strip("_")[:40] if ident else ""
    return f"b{index}" + (f"_{tail}" if tail else "")


def _footprint(index: int, label: str, feature: Any, default_height: float | None, material: str,
               repair: bool) -> tuple[Footprint, str]:
    """The Footprint of one feature and its repair note; ValueError naming the problem."""
    if not isinstance(feature, dict) or feature.get("type") != "Feature":
        raise ValueError("not a GeoJSON Feature object")
    props = feature.get("properties") if isinstance(feature.get("properties"), dict) else {}
    polygon, note = _outline(feature.get("geometry"), repair)
    height, measured = _height(props, default_height)
    shape = str(props.get("roof:shape", "flat")).strip().lower()
    shape = shape if shape in ROOF_SHAPES else "flat"
    roof_height = 0.0 if shape == "flat" else _roof_height(props)
    if measured and roof_height is not None and roof_height >= height:
        raise ValueError(f"roof:height {roof_height:g} m is not below the building's height {height:g} m; "
                         "fix height or roof:height")
    name = props.get("building:material", props.get("material"))
    try:
        itu = building_material(material if name in (None, "") else str(name))
    except ValueError as exc:
        raise ValueError(f"{'building:material' if 'building:material' in props else 'material'}: {exc}") from None
    across = str(props.get("roof:orientation", "along")).strip().lower() == "across"
    return Footprint(index, label, _slug(index, feature), polygon, height, shape, roof_height, across, itu,
                     note, roof_on_top=not measured), note


def _outline(geometry: Any, repair: bool) -> tuple[Any, str]:
    """The shapely (Multi)Polygon of a GeoJSON geometry, valid, and what repairing it changed."""
    import shapely
    from shapely.geometry import shape
    kind = geometry.get("type") if isinstance(geometry, dict) else None
    if kind not in ("Polygon", "MultiPolygon"):
        raise ValueError(f"geometry is {kind or 'missing'}, not a Polygon or MultiPolygon: building "
                         "footprints are areas; drop the feature or give its outline")
    try:
        polygon = shape(geometry)
    except (ValueError, TypeError, AttributeError, IndexError, shapely.errors.GEOSException) as exc:
        raise ValueError(f"malformed {kind} coordinates ({exc}); each ring is a list of [longitude, latitude] "
                         "positions, closed (first = last)") from None
    if polygon.is_empty:
        raise ValueError(f"empty {kind} (no coordinates): give the building's outline")
    lon0, lat0, lon1, lat1 = polygon.bounds
    if not (-180.0 <= lon0 and lon1 <= 180.0 and -90.0 <= lat0 and lat1 <= 90.0):
        raise ValueError(f"coordinates outside longitude [-180, 180], latitude [-90, 90] deg (bounds {lon0:g}, "
                         f"{lat0:g}, {lon1:g}, {lat1:g}): GeoJSON is WGS84 longitude, latitude (RFC 7946); "
                         "reproject projected coordinates first")
    if polygon.is_valid:
        if polygon.area == 0.0:
            raise ValueError(f"{kind} without area (its points lie on a line): give the building's outline")
        return polygon, ""
    reason = re.sub(r"\[(\S+) (\S+)\]", r" at longitude \1, latitude \2", shapely.is_valid_reason(polygon)).lower()
    if not repair:
        raise ValueError(f"invalid outline: {reason}; fix the ring, or pass --repair to mend it with "
                         "shapely's make_valid")
    fixed = shapely.make_valid(polygon)
    parts = [g for g in getattr(fixed, "geoms", [fixed]) if g.geom_type in ("Polygon", "MultiPolygon")]
    fixed = shapely.union_all(parts) if parts else None
    if fixed is None or fixed.is_empty or fixed.area == 0.0:
        raise ValueError(f"invalid outline: {reason}; make_valid leaves no area: fix the ring by hand")
    return fixed, (f"{reason}: repaired with make_valid into a {fixed.geom_type} of "
                   f"{len(getattr(fixed, 'geoms', [fixed]))} part(s)")


def _length(props: dict, key: str) -> float | None:
    """Metres of a length property (number or ``"12"``, ``"12 m"``, ``"40 ft"``); None when absent."""
    value = props.get(key)
    if value is None or value == "":
        return None
    match = re.fullmatch(r"\s*([-+]?\d+(?:\.\d*)?|[-+]?\.\d+)\s*(m|ft|')?\s*", str(value))
    if isinstance(value, bool) or match is None:
        raise ValueError(f"{key} = {value!r} is not a length: give metres as a number, \"12 m\" or \"40 ft\"")
    metres = float(match.group(1)) * _UNITS[match.group(2) or ""]
    if not (0.0 < metres <= 1000.0):
        raise ValueError(f"{key} = {value!r} is outside (0, 1000] m")
    return metres


def _levels(props: dict, key: str) -> float | None:
    """m of a ``*:levels`` property (levels x :data:`LEVEL_HEIGHT`); None when absent."""
    value = props.get(key)
    if value is None or value == "":
        return None
    try:
        levels = float(str(value).strip())
    except ValueError:
        levels = float("nan")
    if isinstance(value, bool) or not (0.0 < levels <= 300.0):
        raise ValueError(f"{key} = {value!r} is not a number of storeys in (0, 300]")
    return levels * LEVEL_HEIGHT


def _height(props: dict, default_height: float | None) -> tuple[float, bool]:
    """Building height [m]: ``height`` (True: measured to the top of the roof), else
    ``building:levels`` x 3 m, else the default (False: to the eaves)."""
    for i, height in enumerate((_length(props, "height"), _levels(props, "building:levels"), default_height)):
        if height is not None:
            return float(height), i == 0
    raise ValueError("no height: give a height (m) or building:levels property, or --default-height")


def _roof_height(props: dict) -> float | None:
    """Roof height [m] of a pitched roof: ``roof:height``, else ``roof:levels`` x 3 m; None when neither
    is given (:mod:`sarmitsuba.scene.city` then uses a :data:`ROOF_PITCH_DEG` pitch)."""
    for height in (_length(props, "roof:height"), _levels(props, "roof:levels")):
        if height is not None:
            return float(height)
    return None


def building_material(name: str) -> str:
    """ITU-R P.2040 material of a ``building:material`` value: an ITU name as it is, an
    OpenStreetMap value through :data:`OSM_MATERIALS`. Raises ValueError listing the valid names."""
    key = str(name).strip().lower().replace(" ", "_")
    if key in materials.itu_material_names() and key != "vacuum":
        return key
    if key in OSM_MATERIALS:
        return OSM_MATERIALS[key]
    valid = tuple(n for n in materials.itu_material_names() if n != "vacuum") + tuple(OSM_MATERIALS)
    raise ValueError(unknown_name("building material", str(name), valid))
