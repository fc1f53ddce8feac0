"""Scenes from building footprints: GeoJSON outlines -> local frame -> meshes -> scene.xml.

``.venv/bin/python -m sarmitsuba scene from-footprints FILE.geojson --out DIR`` and
:meth:`sarmitsuba.Scene.from_footprints` run :func:`build_city` (read, check, project, extrude,
ground; :meth:`sarmitsuba.Scene.from_city` makes a City an in-memory scene) and, given a folder,
:func:`write_city`, which writes ``DIR/scene.xml`` and
``DIR/meshes/*.ply`` in the layout of Sionna RT's scenes (one PLY per building,
``itu-radio-material`` BSDFs), so that ``render``, ``info`` and ``preview`` take the folder or its
``scene.xml`` as they are.

The frame (docs/physics.md (FP1)): a local east-north-up frame (x east, y north, z up, metres)
whose origin is the centre of the footprints' longitude-latitude bounding box on the ground,
written as the sensor's ``geo_origin`` (height: ``elevation``, or the DEM's height there), so
GeoTIFF, SICD and CPHD products land on the map. Outlines are projected with PROJ's
``topocentric`` operation (:func:`sarmitsuba.core.georef.geodetic_to_enu`). The ground is the
tangent plane (or the DEM): at 5 km from the origin the Earth's surface falls 2 m below it,
so areas wider than :data:`MAX_EXTENT` are refused.

Buildings stand on the lowest ground under them (OpenStreetMap's ``height`` is measured from the
lowest ground point), with walls reaching :data:`BASE_DEPTH` below it so that no gap opens at
their foot on terrain. The written sensor is the default ``sar`` sensor (heading 0: flying east,
looking right, i.e. south) aimed at the origin, ``n_pulses`` automatic.
"""
from __future__ import annotations

import contextlib
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from ..core import georef
from ..core.folder_lock import STAGING_PREFIX, hold_folder
from ..core.radar import RadarParameters
from .buildings import building_mesh, building_parts
from .facades import FacadeLayout
from .footprints import ROOF_PITCH_DEG, FootprintError, FootprintSet, building_material, read_footprints
from .terrain import GroundSurface, flat_ground, read_dem

__all__ = ["City", "build_city", "write_city", "scene_folder", "MAX_EXTENT", "BASE_DEPTH", "WALL_THICKNESS", "GROUND_THICKNESS",
           "SCATTERING_COEFFICIENT", "GROUND_SCATTERING_COEFFICIENT"]

#: m: widest area (east-west or north-south, margin included) a flat local frame is built for.
MAX_EXTENT = 20_000.0
#: m: walls reach this far below the lowest ground under a building.
BASE_DEPTH = 1.0
#: m: slab thickness of building materials (``itu-radio-material`` ``thickness``); glass 2 cm.
WALL_THICKNESS = {"glass": 0.02}
DEFAULT_WALL_THICKNESS = 0.2
#: m: thickness of the ground slab: enough that it reflects as a half space from L band up.
GROUND_THICKNESS = 1.0
#: Default ``scattering_coefficient`` of buildings (facades: windows, balconies, masonry) and of
#: the ground; docs/physics.md (C), Lambertian model.
SCATTERING_COEFFICIENT = 0.3
GROUND_SCATTERING_COEFFICIENT = 0.2


@dataclass(frozen=True)
class City:
    """A footprint scene in its local frame (module docstring).

    Attributes
    ----------
    source : str
        The footprint file.
    geo_origin : GeoReference
        WGS84 position of the local origin.
    buildings : tuple of (Footprint, trimesh.Trimesh)
        Each footprint and its closed mesh (float64 vertices, m, local frame).
    ground : trimesh.Trimesh
        Flat rectangle or DEM mesh.
    extent : tuple (x0, y0, x1, y1), m
        The ground's rectangle: the footprints' box plus the margin.
    ground_material : str
    sensor : dict
        ``sar`` sensor parameters written (``geo_origin``, ``scene_center``, then the overrides), strings.
    scattering_coefficient, ground_scattering_coefficient : float
    dem : str or None
    repairs : tuple of str
    parts : tuple of dict
        Per building, the meshes of its parts (:func:`sarmitsuba.scene.buildings.building_parts`):
        ``"walls"`` (with the floor, recesses and balconies), ``"roof"`` and, with a facade
        layout, ``"windows"`` (glass panes). Written as separate shapes, so that a roughness
        preset tells roofs from walls (:mod:`sarmitsuba.scene.roles`).
    facade : FacadeLayout or None
        The windows and balconies of every wall (:mod:`sarmitsuba.scene.facades`); None: plain walls.
    """

    source: str
    geo_origin: georef.GeoReference
    buildings: tuple
    ground: Any
    extent: tuple
    ground_material: str
    sensor: dict
    scattering_coefficient: float = SCATTERING_COEFFICIENT
    ground_scattering_coefficient: float = GROUND_SCATTERING_COEFFICIENT
    dem: str | None = None
    repairs: tuple = field(default_factory=tuple)
    parts: tuple = field(default_factory=tuple)
    facade: FacadeLayout | None = None

    def material_specs(self) -> dict[str, dict]:
        """BSDF parameters per material id: ``{"plugin": "itu-radio-material", "type": ..., ...}``."""
        specs = {}
        for footprint, _ in self.buildings:
            specs[footprint.material] = {"plugin": "itu-radio-material", "type": footprint.material,
                                         "thickness": WALL_THICKNESS.get(footprint.material, DEFAULT_WALL_THICKNESS),
                                         "scattering_coefficient": self.scattering_coefficient}
        if any("windows" in p for p in self.parts):
            specs["glass"] = {"plugin": "itu-radio-material", "type": "glass", "thickness": WALL_THICKNESS["glass"],
                              "scattering_coefficient": 0.0}
        specs["ground"] = {"plugin": "itu-radio-material", "type": self.ground_material,
                           "thickness": GROUND_THICKNESS, "scattering_coefficient": self.ground_scattering_coefficient}
        return specs

    def shapes(self, split: bool = True) -> list:
        """``[(shape name, mesh, material id)]``: every building's parts (``slug``: walls,
        ``slug-roof``, ``slug-windows``), then ``ground``, as :func:`write_city` writes them;
        ``split`` False: each building as one closed mesh ``slug`` (no windows), a body that moves
        or grows whole (the shape parameters of :mod:`sarmitsuba.derivatives`)."""
        out = []
        parts_of = self.parts if split and self.parts else [None] * len(self.buildings)
        for (footprint, closed), parts in zip(self.buildings, parts_of):
            if parts is None:
                out.append((footprint.slug, closed, footprint.material))
                continue
            out += [(footprint.slug + ("" if name == "walls" else f"-{name}"), mesh,
                     "glass" if name == "windows" else footprint.material) for name, mesh in parts.items()]
        return out + [("ground", self.ground, "ground")]

    def window_count(self) -> int:
        """Windows of all facades (two triangles each)."""
        return sum(len(p["windows"].faces) // 2 for p in self.parts if "windows" in p)

    def summary(self) -> str:
        """``12 buildings, 3,456 triangles, 480 m x 360 m about 48.13780 N, 11.57570 E, 519.0 m``."""
        x0, y0, x1, y1 = self.extent
        triangles = sum(len(m.faces) for _, m, _ in self.shapes())
        n = len(self.buildings)
        plain = sum(len(m.faces) for _, m in self.buildings) + len(self.ground.faces)
        windows = (f", {self.window_count():,} windows (+{triangles - plain:,} triangles)" if self.facade is not None
                   else "")
        return (f"{n} building{'' if n == 1 else 's'}{windows}, {triangles:,} triangles, {x1 - x0:.0f} m x "
                f"{y1 - y0:.0f} m about {self.geo_origin.describe()}")


def build_city(footprints: str | Path | FootprintSet, default_height: float | None = None,
               material: str = "concrete", ground_material: str = "concrete", dem: str | Path | None = None,
               elevation: float = 0.0, margin: float | None = None, repair: bool = False,
               scattering_coefficient: float = SCATTERING_COEFFICIENT,
               ground_scattering_coefficient: float = GROUND_SCATTERING_COEFFICIENT,
               sensor: Mapping[str, Any] | None = None, origin: Any = None,
               facade: FacadeLayout | None = None) -> City:
    """Read, check, project and extrude footprints (module docstring).

    Parameters
    ----------
    footprints : path-like or FootprintSet
        GeoJSON file (:func:`sarmitsuba.scene.footprints.read_footprints`) or its parsed set.
    default_height, material, repair
        As :func:`~sarmitsuba.scene.footprints.read_footprints`.
    ground_material : str, default "concrete"
        ITU-R P.2040 material of the ground.
    dem : path-like, optional
        DEM GeoTIFF for the ground (:func:`sarmitsuba.scene.terrain.read_dem`); None: a flat plane.
    elevation : float, default 0
        m above the WGS84 ellipsoid of the flat ground (the ``geo_origin`` height); ignored with a DEM.
    margin : float, optional
        m of ground around the footprints' box; default max(10 m, the tallest building).
    scattering_coefficient, ground_scattering_coefficient : float in [0, 1)
        Roughness of buildings and ground (Lambertian, physics.md (C)); 0: smooth.
    sensor : mapping, optional
        ``sar`` sensor parameters written besides ``geo_origin`` and ``scene_center``.
    origin : GeoReference or "lat, lon[, h]", optional
        The local frame's origin instead of the footprints' centre (to share another scene's
        frame); its height replaces ``elevation`` (the ground stays at z = 0; with a DEM,
        z = DEM - height).
    facade : FacadeLayout, optional
        Windows (recessed panes of glass) and balconies on every wall (:mod:`sarmitsuba.scene.facades`).

    Raises
    ------
    FootprintError
        Bad file or features (one line each), a roof not below its building, a bad option value.
    DemError
        The DEM cannot be read or does not cover the area.
    ParameterError
        A bad sensor parameter.
    """
    fs = footprints if isinstance(footprints, FootprintSet) else read_footprints(footprints, default_height, material,
                                                                               repair)
    _check_options(ground_material, elevation, margin, scattering_coefficient, ground_scattering_coefficient)
    margin = max(10.0, max(f.height for f in fs.footprints)) if margin is None else float(margin)
    lat0, lon0 = fs.centre()
    lonlat = _margin_box(fs, margin)
    terrain = None if dem is None else read_dem(dem, lonlat)
    height0 = elevation if terrain is None else float(terrain.height_at(np.array(lon0), np.array(lat0)))
    ref = georef.parse(origin) or georef.GeoReference(lat0, lon0, height0)
    outlines = [_project(f.polygon, ref) for f in fs.footprints]
    boxes = np.array([o.bounds for o in outlines])
    extent = (boxes[:, 0].min() - margin, boxes[:, 1].min() - margin, boxes[:, 2].max() + margin,
              boxes[:, 3].max() + margin)
    if max(extent[2] - extent[0], extent[3] - extent[1]) > MAX_EXTENT:
        raise FootprintError([f"{fs.source}: the footprints and margin span {extent[2] - extent[0]:.0f} m x "
                              f"{extent[3] - extent[1]:.0f} m, wider than {MAX_EXTENT:.0f} m: a flat local frame "
                              "would sink its edges by the Earth's curvature; split the area into tiles"])
    ground = flat_ground(*extent) if terrain is None else terrain.mesh(ref)
    surface = GroundSurface(None if terrain is None else ground)
    buildings, parts, problems = [], [], []
    for footprint, outline in zip(fs.footprints, outlines):
        try:
            buildings.append((footprint, _building(footprint, outline, surface)))
            parts.append(_building(footprint, outline, surface, facade, split=True))
        except ValueError as exc:
            problems.append(f"{fs.source}: {footprint.label}: {exc}")
    if problems:
        raise FootprintError(problems)
    values = {"geo_origin": "{:.8f}, {:.8f}, {:.3f}".format(*ref.as_tuple()), "scene_center": "0, 0, 0",
              **{str(k): str(v) for k, v in (sensor or {}).items()}}
    RadarParameters.from_mapping(values)            # ParameterError names a bad one
    return City(fs.source, ref, tuple(buildings), ground, tuple(float(v) for v in extent), ground_material,
                values, scattering_coefficient, ground_scattering_coefficient, None if dem is None else str(dem),
                fs.repairs, tuple(parts), facade)


def _check_options(ground_material: str, elevation: float, margin: float | None, *scattering: float) -> None:
    """FootprintError naming a bad option of :func:`build_city`."""
    try:
        if building_material(ground_material) != ground_material:
            raise ValueError(f"give an ITU-R P.2040 name, e.g. {building_material(ground_material)!r}")
    except ValueError as exc:
        raise FootprintError([f"--ground-material: {exc}"]) from None
    checks = [("--elevation", elevation, -500.0, 9000.0, "m above the WGS84 ellipsoid"),
              ("--margin", 10.0 if margin is None else margin, 0.0, 5000.0, "m of ground around the buildings")]
    checks += [(flag, s, 0.0, 0.999, "(Lambertian roughness; 0 is smooth)")
               for flag, s in zip(("--scattering-coefficient", "--ground-scattering-coefficient"), scattering)]
    for flag, value, lo, hi, unit in checks:
        if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
            raise FootprintError([f"{flag} = {value!r} is outside [{lo:g}, {hi:g}] {unit}"])


def _margin_box(fs: FootprintSet, margin: float) -> tuple[float, float, float, float]:
    """The footprints' lon/lat box grown by ``margin`` metres (and 10 % for the DEM window's rounding)."""
    lon0, lat0, lon1, lat1 = fs.bounds()
    dlat = 1.1 * margin / 110_540.0
    dlon = 1.1 * margin / (111_320.0 * max(math.cos(math.radians(max(abs(lat0), abs(lat1)))), 1e-6))
    return lon0 - dlon, lat0 - dlat, lon1 + dlon, lat1 + dlat


def _project(polygon, ref: georef.GeoReference):
    """The lon/lat outline as local (x east, y north) metres at ``ref`` (FP1)."""
    import shapely

    def to_local(lonlat: np.ndarray) -> np.ndarray:
        llh = np.column_stack([lonlat[:, 1], lonlat[:, 0], np.full(len(lonlat), ref.height_m)])
        return georef.geodetic_to_enu(llh, ref)[:, :2]

    return shapely.transform(polygon, to_local)


def _building(footprint, outline, surface: GroundSurface, facade: FacadeLayout | None = None, split: bool = False):
    """The closed mesh of one footprint on its lowest ground (flat: z = 0; DEM: its mesh under the
    outline); ``split``: its parts (:func:`~sarmitsuba.scene.buildings.building_parts`) with ``facade``."""
    ground = surface.lowest_under(outline)
    roof = footprint.roof_height
    if roof is None:                 # a 30 deg pitch over half the rectangle's short side
        rect = np.asarray(outline.minimum_rotated_rectangle.exterior.coords)
        roof = 0.5 * float(np.linalg.norm(np.diff(rect[:3], axis=0), axis=1).min()) * math.tan(
            math.radians(ROOF_PITCH_DEG))
        roof = roof if footprint.roof_on_top else min(roof, 0.5 * footprint.height)
    eaves = footprint.height if footprint.roof_on_top else footprint.height - roof
    if eaves <= 0.0:
        raise ValueError(f"roof:height {roof:g} m is not below the height {footprint.height:g} m; fix height "
                         "or roof:height")
    if split:
        return building_parts(outline, ground - BASE_DEPTH, ground + eaves, footprint.roof_shape, roof,
                              footprint.roof_across, ground=ground, facade=facade, key=footprint.slug)
    return building_mesh(outline, ground - BASE_DEPTH, ground + eaves, footprint.roof_shape, roof,
                         footprint.roof_across)


def write_city(city: City, out: str | Path) -> Path:
    """Write ``out/scene.xml`` and ``out/meshes/*.ply`` (module docstring); returns the XML's path.

    Written in a staging folder inside ``out`` and moved into place at the end, replacing an
    earlier ``scene.xml`` and ``meshes/``: a failure or Ctrl-C leaves the folder as it was.
    Raises OSError naming ``out`` when it is a file or cannot be written.
    """
    import trimesh
    with scene_folder(out) as staging:
        for name, mesh, _ in city.shapes():
            lean = trimesh.Trimesh(np.asarray(mesh.vertices, np.float32), mesh.faces, process=False)
            (staging / "meshes" / f"{name}.ply").write_bytes(trimesh.exchange.ply.export_ply(lean, encoding="binary"))
        (staging / "scene.xml").write_text(_xml(city), encoding="utf-8")
    return Path(out) / "scene.xml"


@contextlib.contextmanager
def scene_folder(out: str | Path) -> Iterator[Path]:
    """Write a scene folder (``out/scene.xml`` and ``out/meshes/``) atomically: yields an empty
    staging folder holding ``meshes/``, whose ``scene.xml`` and ``meshes/`` replace ``out``'s when
    the block ends without an error; a failure or Ctrl-C leaves ``out`` as it was. One run per
    folder (:func:`~sarmitsuba.core.folder_lock.hold_folder`).

    Raises OSError naming ``out`` when it is a file or cannot be written.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OSError(f"--out {out}: an existing file, not a directory; give a folder for scene.xml and meshes/")
    with hold_folder(out):            # one run per folder: creates it (removed again if left empty), and
        try:                          # removes the staging folders of a killed run
            staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))
        except OSError as exc:
            raise OSError(f"--out {out}: cannot create it ({exc.strerror or exc}); choose another folder") from None
        try:
            (staging / "meshes").mkdir()
            yield staging
            _swap_in(staging, out)
        finally:
            shutil.rmtree(staging, ignore_errors=True)


def _swap_in(staging: Path, out: Path) -> None:
    """Move ``staging/meshes`` and ``staging/scene.xml`` to ``out``; the earlier ones go back on failure."""
    old = staging / "old-meshes"
    if (out / "meshes").exists():
        os.rename(out / "meshes", old)
    try:
        os.rename(staging / "meshes", out / "meshes")
        os.replace(staging / "scene.xml", out / "scene.xml")
    except BaseException:
        if old.exists():
            shutil.rmtree(out / "meshes", ignore_errors=True)
            os.rename(old, out / "meshes")
        raise


def _xml(city: City) -> str:
    """The scene XML of a city (Sionna RT's layout plus the sar sensor)."""
    lines = ["<!-- Built by `sarmitsuba scene from-footprints` from "
             f"{escape(Path(city.source).name).replace('--', '- -')}: {escape(city.summary())}.",
             "     Frame: local east-north-up (x east, y north, z up, metres) about geo_origin; ground: "
             + ("DEM " + escape(Path(city.dem).name).replace('--', '- -') if city.dem else "flat plane at z = 0")
             + ". -->", '<scene version="3.0.0">', '    <sensor type="sar">']
    lines += [f"        <string name={quoteattr(k)} value={quoteattr(v)}/>" for k, v in city.sensor.items()]
    lines += ["    </sensor>", ""]
    for key, spec in city.material_specs().items():
        lines += [f'    <bsdf type="itu-radio-material" id={quoteattr(key)}>',
                  f'        <string name="type" value={quoteattr(spec["type"])}/>',
                  f'        <float name="thickness" value="{spec["thickness"]!r}"/>',
                  f'        <float name="scattering_coefficient" value="{spec["scattering_coefficient"]!r}"/>',
                  "    </bsdf>"]
    lines.append("")
    labels = {f.slug: f.label for f, _ in city.buildings}
    for slug, _, material in city.shapes():
        lines += [f"    <!-- {escape(labels[slug]).replace('--', '- -')} -->" if slug in labels else "",
                  f'    <shape type="ply" id={quoteattr("mesh-" + slug)}>',
                  f'        <string name="filename" value={quoteattr(f"meshes/{slug}.ply")}/>',
                  '        <boolean name="face_normals" value="true"/>',
                  f'        <ref id={quoteattr(material)} name="bsdf"/>', "    </shape>"]
    return "\n".join(lines) + "\n</scene>\n"
