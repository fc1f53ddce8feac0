"""Building footprints of a mesh scene: a Mitsuba / Sionna RT XML scene back to GeoJSON.

The inverse of :mod:`sarmitsuba.scene.city`: :func:`footprints_from_scene` reads the ``<shape
type="ply">`` entries of a scene XML (Sionna RT's layout: one or more PLY meshes per building,
``itu-radio-material`` BSDFs), groups them into buildings by name, and writes each building as a
GeoJSON ``Feature`` (RFC 7946: WGS84 longitude, latitude) that
:func:`sarmitsuba.scene.footprints.parse_footprints` reads and :func:`~sarmitsuba.scene.city.build_city`
extrudes again. Used to test the footprint pipeline on real buildings (a city rebuilt from its
own footprints images like the original) and to turn mesh cities into footprint files.

Grouping: a shape's building is its id less a leading ``mesh-`` and a trailing
``-itu_<material>`` (Sionna's ``mesh-Altes_Rathaus-itu_marble`` and ``mesh-Altes_Rathaus-itu_metal``
are the building ``Altes_Rathaus``); a shape without id is named by its file's stem.

Per building (all in the scene's frame: x east, y north, z up, metres):

* **outline**: the union (shapely) of the horizontal projections of its triangles, those of
  projected area above :data:`MIN_TRIANGLE_AREA` (walls project to lines and drop out), closed
  by a :data:`CLEAN_DISTANCE` buffer out and back in (seams between triangles that meet to
  float rounding), made valid, parts below :data:`MIN_PART_AREA` dropped; a ``Polygon`` or
  ``MultiPolygon`` with its holes (courtyards);
* **ground**: the lowest height of the ground mesh under the outline (at the outline's vertices
  and the ground's vertices inside it), OpenStreetMap's convention for ``height``;
* **roof height**: the mean height of the roof over its plan area: the roof is the triangles
  facing up (normal z > :data:`ROOF_NORMAL_Z`), each weighted by its projected area, so a flat
  roof at that height keeps the building's volume (vertical walls, a roof covering the plan
  once); a pitched roof's ridge is higher: the mean of a gabled roof lies halfway between eaves
  and ridge. Chosen over the highest vertex, which a spire or a ridge would set for the whole
  block. A building without such triangles gets its highest vertex. ``height`` = roof height -
  ground;
* **material**: the ITU-R P.2040 name of the BSDF of its walls: of the shape with the most
  wall area (normal z within +-:data:`ROOF_NORMAL_Z`), the first shape when none has walls.
  In Sionna's Munich this is the ``marble`` shape of a marble / metal pair (walls / roofs).
  A BSDF that is no ITU material leaves the property out (the reader's default applies);
* ``min_height``: the lowest vertex above the ground, written when over :data:`MIN_HEIGHT_GAP`
  (a spire standing on a roof; OpenStreetMap's key; :mod:`~sarmitsuba.scene.city` builds every
  building from the ground).

:func:`write_scene_subset` writes a copy of a scene XML that keeps only some buildings (and the
ground), its PLY files named by absolute paths: a cropped scene to render beside a rebuilt one.
"""
from __future__ import annotations

import re
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core import georef
from .footprints import building_material
from .terrain import GroundSurface

__all__ = ["SceneShape", "scene_shapes", "building_name", "scene_buildings", "footprints_from_scene",
           "write_scene_subset", "ROOF_NORMAL_Z", "MIN_TRIANGLE_AREA", "CLEAN_DISTANCE", "MIN_PART_AREA",
           "MIN_HEIGHT_GAP"]

#: A triangle is roof when its unit normal's z exceeds this (60 deg from vertical), wall within +- it.
ROOF_NORMAL_Z = 0.5
#: m^2: triangles whose horizontal projection is smaller are left out of the outline (walls).
MIN_TRIANGLE_AREA = 1e-6
#: m: the outline is buffered out and back in by this much (mitred) to close rounding seams.
CLEAN_DISTANCE = 1e-3
#: m^2: outline parts smaller than this (slivers) are dropped.
MIN_PART_AREA = 1e-2
#: m: a building whose lowest vertex stands higher than this above the ground gets ``min_height``.
MIN_HEIGHT_GAP = 0.5


@dataclass(frozen=True)
class SceneShape:
    """One ``<shape type="ply">`` of a scene XML.

    Attributes
    ----------
    id : str
        The shape's ``id`` (its file's stem when it has none).
    path : Path
        The PLY file, absolute.
    material : str
        The ``type`` of its BSDF (``itu-radio-material``: an ITU-R P.2040 name), else the BSDF's
        id, else the ``-itu_<material>`` suffix of the shape id, else ``""``.
    """

    id: str
    path: Path
    material: str


def scene_shapes(xml_path: str | Path) -> list[SceneShape]:
    """The PLY shapes of a scene XML, in file order (other shape types are skipped).

    Raises
    ------
    OSError
        The XML file cannot be read.
    ValueError
        The file is not XML (names the file and the parser's message).
    """
    xml_path = Path(xml_path)
    try:
        root = ET.parse(xml_path).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"{xml_path}: not a scene XML ({exc})") from None
    bsdfs = {b.get("id"): b for b in root.iter("bsdf") if b.get("id")}
    shapes = []
    for shape in root.iter("shape"):
        if shape.get("type") != "ply":
            continue
        filename = shape.find("string[@name='filename']")
        if filename is None:
            continue
        path = Path(filename.get("value", ""))
        path = path if path.is_absolute() else (xml_path.parent / path)
        ident = shape.get("id") or path.stem
        shapes.append(SceneShape(ident, path.resolve(), _material(shape, bsdfs, ident)))
    return shapes


def _material(shape: ET.Element, bsdfs: dict, ident: str) -> str:
    """The material name of a shape (see :class:`SceneShape`)."""
    bsdf, ref = shape.find("bsdf"), shape.find("ref")
    if bsdf is None and ref is not None:
        bsdf = bsdfs.get(ref.get("id"))
    kind = None if bsdf is None else bsdf.find(".//string[@name='type']")
    if kind is not None and kind.get("value"):
        return kind.get("value")
    if ref is not None and ref.get("id"):
        return ref.get("id")
    suffix = re.search(r"-itu_([A-Za-z0-9_]+)$", ident)
    return suffix.group(1) if suffix else ""


def building_name(shape_id: str) -> str:
    """The building a shape belongs to: its id less ``mesh-`` and ``-itu_<material>``.

    ``"mesh-Palais_Toerring-Jettenbach-itu_metal"`` -> ``"Palais_Toerring-Jettenbach"``;
    ``"mesh-Alter_Hof"`` -> ``"Alter_Hof"``.
    """
    name = shape_id.removeprefix("mesh-")
    return re.sub(r"-itu_[A-Za-z0-9_]+$", "", name) or name


def scene_buildings(xml_path: str | Path, ground: str | None = "ground") -> tuple[dict[str, list[SceneShape]],
                                                                                   list[SceneShape]]:
    """The PLY shapes of a scene grouped by :func:`building_name`: ``(buildings, ground_shapes)``.

    ``buildings`` maps each name to its shapes in file order (dict in file order of first
    appearance); the shapes named ``ground`` go to ``ground_shapes``. Raises ValueError when
    ``ground`` is given but no shape bears that name, and as :func:`scene_shapes`.
    """
    buildings: dict[str, list[SceneShape]] = {}
    ground_shapes = []
    for shape in scene_shapes(xml_path):
        name = building_name(shape.id)
        if ground is not None and name == ground:
            ground_shapes.append(shape)
        else:
            buildings.setdefault(name, []).append(shape)
    if ground is not None and not ground_shapes:
        raise ValueError(f"{xml_path}: no shape named {ground!r} (ground): give the ground shape's name "
                         f"(without 'mesh-'), or ground=None for a ground plane at z = 0")
    return buildings, ground_shapes


def _load(shapes: list[SceneShape]) -> list:
    """The trimesh of each shape's PLY file (float64 vertices, m)."""
    import trimesh
    return [trimesh.load(str(s.path), file_type="ply", force="mesh", process=False) for s in shapes]


def _joined(meshes: list):
    """One trimesh of several."""
    import trimesh
    return trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]


def _outline(mesh):
    """The building's plan outline (module docstring): shapely Polygon / MultiPolygon, or None."""
    import shapely
    plan = mesh.area_faces * np.abs(mesh.face_normals[:, 2])
    triangles = mesh.triangles[plan > MIN_TRIANGLE_AREA][:, :, :2]
    if not len(triangles):
        return None
    union = shapely.union_all(shapely.polygons(triangles))
    union = shapely.make_valid(union.buffer(CLEAN_DISTANCE, join_style="mitre")
                               .buffer(-CLEAN_DISTANCE, join_style="mitre"))
    parts = [p for g in getattr(union, "geoms", [union]) for p in getattr(g, "geoms", [g])
             if p.geom_type == "Polygon" and p.area >= MIN_PART_AREA]
    if not parts:
        return None
    outline = shapely.union_all(parts).simplify(CLEAN_DISTANCE, preserve_topology=True)
    return outline if outline.is_valid else shapely.make_valid(outline)


def _roof_height(mesh) -> float:
    """Mean height of the up-facing triangles over their plan area (module docstring) [m]."""
    nz = mesh.face_normals[:, 2]
    up = nz > ROOF_NORMAL_Z
    weights = mesh.area_faces[up] * nz[up]
    if not np.any(up) or weights.sum() <= 0.0:
        return float(mesh.vertices[:, 2].max())
    return float(np.average(mesh.triangles_center[up, 2], weights=weights))


def _wall_material(shapes: list[SceneShape], meshes: list) -> str:
    """Material of the shape with the most wall area (first shape when none has walls)."""
    walls = [float(m.area_faces[np.abs(m.face_normals[:, 2]) <= ROOF_NORMAL_Z].sum()) for m in meshes]
    return shapes[int(np.argmax(walls))].material if max(walls) > 0.0 else shapes[0].material


def _feature(name: str, outline, height: float, material: str, min_height: float, ref: georef.GeoReference) -> dict:
    """The GeoJSON Feature of one building (outline in local metres, RFC 7946 orientation)."""
    import shapely
    from shapely.geometry import mapping

    def to_lonlat(xy: np.ndarray) -> np.ndarray:
        llh = georef.enu_to_geodetic(np.column_stack([xy, np.zeros(len(xy))]), ref)
        return llh[:, [1, 0]]

    geometry = shapely.orient_polygons(shapely.transform(outline, to_lonlat), exterior_cw=False)
    properties: dict[str, Any] = {"name": name, "height": round(height, 3)}
    try:
        properties["building:material"] = building_material(material)
    except ValueError:
        pass
    if min_height > MIN_HEIGHT_GAP:
        properties["min_height"] = round(min_height, 3)
    return {"type": "Feature", "id": name, "properties": properties, "geometry": mapping(geometry)}


def footprints_from_scene(xml_path: str | Path, geo_origin: Any, ground: str | None = "ground",
                          bbox: tuple[float, float, float, float] | None = None) -> dict:
    """GeoJSON footprints of the buildings of a Mitsuba / Sionna RT scene XML (module docstring).

    Parameters
    ----------
    xml_path : path-like
        Scene XML with ``<shape type="ply">`` entries (relative file names from its folder).
    geo_origin : GeoReference or str
        WGS84 position of the scene's local origin (``"lat, lon[, h]"`` or a
        :class:`~sarmitsuba.core.georef.GeoReference`), e.g.
        ``georef.SCENE_ORIGINS["munich"]``: the frame x east, y north, z up [m] about it.
    ground : str or None, default "ground"
        Building name (:func:`building_name`) of the ground shape(s): left out of the buildings
        and used for their ground height; None: no ground shape, the ground is z = 0.
    bbox : (x0, y0, x1, y1), m, optional
        Keep only the buildings whose outline's centroid lies in this box (local frame).

    Returns
    -------
    dict
        GeoJSON ``FeatureCollection``: one ``Feature`` per building, ``id`` and ``name`` its
        name, ``height`` [m] (ground to mean roof height), ``building:material`` (ITU-R P.2040),
        ``min_height`` [m] when over :data:`MIN_HEIGHT_GAP`; ``Polygon`` or ``MultiPolygon``
        geometry in longitude, latitude [deg], exterior rings counter-clockwise. Buildings without
        an outline (every triangle vertical or tiny) or not above the ground are left out with a
        warning naming them.

    Raises
    ------
    ValueError
        Not XML, no shape named ``ground``, a bad ``geo_origin`` or ``bbox``.
    OSError
        The XML or a PLY file cannot be read.
    """
    ref = georef.parse(geo_origin)
    if ref is None:
        raise ValueError(f"geo_origin = {geo_origin!r}: give the scene origin's 'lat, lon[, h]' or a GeoReference")
    if bbox is not None and not (len(bbox) == 4 and bbox[0] < bbox[2] and bbox[1] < bbox[3]):
        raise ValueError(f"bbox = {bbox!r}: give (x0, y0, x1, y1) in metres with x0 < x1 and y0 < y1")
    buildings, ground_shapes = scene_buildings(xml_path, ground)
    terrain = GroundSurface(_joined(_load(ground_shapes)) if ground_shapes else None)
    features, skipped = [], []
    for name, shapes in buildings.items():
        meshes = _load(shapes)
        mesh = _joined(meshes)
        (x0, y0, _), (x1, y1, _) = mesh.bounds
        if bbox is not None and (x1 < bbox[0] or x0 > bbox[2] or y1 < bbox[1] or y0 > bbox[3]):
            continue                            # cannot have its centroid in the box
        outline = _outline(mesh)
        if outline is None:
            skipped.append(f"{name} (no outline)")
            continue
        centre = outline.centroid
        if bbox is not None and not (bbox[0] <= centre.x <= bbox[2] and bbox[1] <= centre.y <= bbox[3]):
            continue
        base = terrain.lowest_under(outline)
        height = _roof_height(mesh) - base
        if not height > 0.0:
            skipped.append(f"{name} (roof {height:.2f} m above the ground)")
            continue
        min_height = float(mesh.vertices[:, 2].min()) - base
        features.append(_feature(name, outline, height, _wall_material(shapes, meshes), min_height, ref))
    if skipped:
        warnings.warn(f"{xml_path}: {len(skipped)} building(s) left out: {', '.join(skipped[:10])}"
                      f"{' ...' if len(skipped) > 10 else ''}", stacklevel=2)
    return {"type": "FeatureCollection", "features": features}


def write_scene_subset(xml_path: str | Path, out: str | Path, buildings: Iterable[str],
                       ground: str | None = "ground", ground_file: str | Path | None = None) -> Path:
    """Write a copy of a scene XML keeping only some buildings' PLY shapes and the ground.

    Every other element (BSDFs, sensor, integrator, non-PLY shapes) is kept as it is; the PLY
    ``filename`` values of the kept shapes become absolute paths, so ``out`` may lie anywhere.

    Parameters
    ----------
    xml_path : path-like
        The scene XML.
    out : path-like
        The XML to write (its folder must exist).
    buildings : iterable of str
        Building names (:func:`building_name`) to keep, e.g. the ``id`` of each feature of
        :func:`footprints_from_scene`.
    ground : str or None
        Building name of the ground shape(s), kept too.
    ground_file : path-like, optional
        A PLY file the ground shape(s) load instead of their own (e.g. a ground cropped to
        the kept buildings, :attr:`sarmitsuba.scene.city.City.ground` written with trimesh).

    Returns
    -------
    Path
        ``out``. Raises OSError / ValueError as :func:`scene_shapes`.
    """
    xml_path, keep = Path(xml_path), set(buildings) | ({ground} if ground is not None else set())
    try:
        tree = ET.parse(xml_path)
    except ET.ParseError as exc:
        raise ValueError(f"{xml_path}: not a scene XML ({exc})") from None
    for parent in list(tree.getroot().iter()):
        for shape in [c for c in parent if c.tag == "shape" and c.get("type") == "ply"]:
            filename = shape.find("string[@name='filename']")
            path = Path(filename.get("value", "")) if filename is not None else Path()
            name = building_name(shape.get("id") or path.stem)
            if name not in keep:
                parent.remove(shape)
            elif filename is not None and ground_file is not None and name == ground:
                filename.set("value", str(Path(ground_file).resolve()))
            elif filename is not None and not path.is_absolute():
                filename.set("value", str((xml_path.parent / path).resolve()))
    tree.write(out, encoding="unicode")
    return Path(out)
