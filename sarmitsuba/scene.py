"""Loading a scene: XML path, built-in name or ``sionna:NAME``, plus the SAR sensor and tracer settings.

A scene is a Mitsuba XML file (docs/design.md section 4). ``load_scene`` resolves where it is,
loads it with sarmitsuba's plugins, reads the ``sar`` sensor and ``sbr`` integrator (or
uses the defaults when the scene has none, as Sionna RT scenes do), applies overrides
(from the CLI), and resolves the automatic parameters against the scene's bounding box.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import drjit as dr
import mitsuba as mi
import numpy as np

from . import materials
from .meshcheck import check_meshes, warn_mesh_defects
from .planning import resolve_parameters
from .radiometry import radar_equation
from .radar import ParameterError, RadarParameters
from .trace_inputs import MaterialTable, TraceSettings

__all__ = ["SceneError", "LoadedScene", "resolve_source", "load_scene", "material_table",
           "builtin_scenes", "sionna_scenes"]

#: Number of cos(incidence) samples of each material's reflection table.
TABLE_SIZE = 257


class SceneError(ValueError):
    """A scene cannot be found or loaded; the message says which file and why."""


@dataclass(frozen=True)
class LoadedScene:
    """A loaded scene with its resolved radar parameters and tracer settings.

    Attributes
    ----------
    scene : mitsuba.Scene
    path : Path
        The XML file.
    source : str
        What the user asked for (path, built-in name or ``sionna:NAME``).
    params : RadarParameters
        Resolved (scene_center and n_pulses filled in).
    settings : TraceSettings
    bbox_lo, bbox_hi : float64 [3], m
        Axis-aligned bounding box of the geometry.
    has_sensor : bool
        Whether the scene defines a ``sar`` sensor (otherwise defaults were used).
    n_shapes, n_triangles : int
    offset : float64 [3], m
        World position of the local frame's origin: geometry, ``params`` and the bounding box
        are local (world minus offset); zero unless the scene lies more than
        :data:`RECENTER_DISTANCE` from the origin.
    shape_boxes : float64 [n_shapes, 2, 3], m
        Each shape's bounding box ``(lo, hi)`` (local frame), for the ray planner's refinement
        around small objects.
    """

    scene: Any
    path: Path
    source: str
    params: RadarParameters
    settings: TraceSettings
    bbox_lo: np.ndarray
    bbox_hi: np.ndarray
    has_sensor: bool
    n_shapes: int
    n_triangles: int
    offset: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    shape_boxes: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 2, 3)))


def _package_dir(name: str) -> Path | None:
    spec = importlib.util.find_spec(name)          # does not import the package's code
    if spec is None or spec.origin is None:
        return None
    return Path(spec.origin).parent


def builtin_scenes() -> dict[str, Path]:
    """Built-in scenes shipped in ``scenes/``: name -> XML path."""
    folder = _package_dir("sarmitsuba_scenes")
    return {} if folder is None else {p.stem: p for p in sorted(folder.glob("*.xml"))}


def sionna_scenes() -> dict[str, Path]:
    """Scenes of the installed Sionna RT package (found without importing it): name -> XML path."""
    folder = _package_dir("sionna")
    if folder is None:
        return {}
    root = folder / "rt" / "scenes"
    return {p.name: p / f"{p.name}.xml" for p in sorted(root.iterdir()) if (p / f"{p.name}.xml").is_file()}


def resolve_source(source: str | Path | None) -> Path:
    """Path of the XML file for ``source`` (None = the default ``urban`` scene).

    Raises
    ------
    SceneError
        Unknown built-in or Sionna scene name (listing the valid ones), Sionna RT not
        installed, or a file that does not exist.
    """
    source = "urban" if source is None else str(source)
    if source.startswith("sionna:"):
        name = source.split(":", 1)[1]
        scenes = sionna_scenes()
        if not scenes:
            raise SceneError(f"{source}: Sionna RT is not installed; install it with "
                             "`pip install 'sarmitsuba[sionna]'` (or `pip install sionna-rt`)")
        if name not in scenes:
            raise SceneError(f"{source}: no Sionna RT scene named {name!r}; available: {', '.join(scenes)}")
        return scenes[name]
    builtins = builtin_scenes()
    if source in builtins:
        return builtins[source]
    path = Path(source)
    if not path.is_file():
        hint = f"; built-in scenes: {', '.join(builtins)}" if builtins else ""
        raise SceneError(f"scene file {str(path)!r} does not exist{hint}")
    return path


def load_scene(source: str | Path | None = None, sensor_overrides: Mapping[str, Any] | None = None,
               integrator_overrides: Mapping[str, Any] | None = None,
               material_overrides: Mapping[str, Any] | None = None) -> LoadedScene:
    """Load a scene and resolve its radar parameters and tracer settings.

    Parameters
    ----------
    source : str or Path or None
        XML path, built-in scene name (``urban``, ``dihedral``, ``trihedral``) or
        ``sionna:NAME``; None = ``urban``.
    sensor_overrides, integrator_overrides : mapping, optional
        Parameter values replacing the scene's (names as in the plugin manuals).
    material_overrides : mapping, optional
        Roughness applied to every material: ``gamma_db`` [dB] or ``scattering_coefficient``.

    Raises
    ------
    SceneError
        File missing or malformed, or a plugin rejected its parameters.
    ParameterError
        An override names an unknown parameter or has an invalid value.
    """
    path = resolve_source(source)
    scene = _load_mitsuba(path)
    center = 0.5 * (np.array(scene.bbox().min, np.float64) + np.array(scene.bbox().max, np.float64))
    offset = np.zeros(3)
    if np.all(np.isfinite(center)) and np.linalg.norm(center) > RECENTER_DISTANCE:
        offset = np.round(center)              # whole metres: exact in float32 below 2^24 m
        scene = _load_mitsuba(path, offset)
    warn_mesh_defects(check_meshes(scene), str(path))
    _override_materials(scene, material_overrides or {})
    sensor = next((s for s in scene.sensors() if hasattr(s, "parameters") and hasattr(s, "given")), None)
    given = dict(sensor.given) if sensor is not None else {}
    given.update(sensor_overrides or {})
    params = RadarParameters.from_mapping(given)
    if params.scene_center is not None and np.any(offset):
        params = dataclasses.replace(params, scene_center=tuple((np.asarray(params.scene_center) - offset).tolist()))
    integrator = scene.integrator()
    settings_given = dict(getattr(integrator, "given", {}))
    settings_given.update(integrator_overrides or {})
    settings = TraceSettings.from_mapping(settings_given)
    if settings.range_kernel == "exact" and params.output == "raw":
        raise ParameterError("sbr range_kernel = 'exact' evaluates range-compressed samples and cannot make chirped "
                             "echoes: use sar output = 'compressed', or range_kernel 'linear' or 'sinc' with output = 'raw'")
    bbox = scene.bbox()
    lo, hi = np.array(bbox.min, np.float64), np.array(bbox.max, np.float64)
    if not (np.all(np.isfinite(lo)) and np.all(hi >= lo)):
        raise SceneError(f"scene {str(path)!r} has no geometry (empty bounding box)")
    params = resolve_parameters(params, lo, hi)
    radar_equation(params)                   # radiometry parameters checked before any tracing
    n_tri = sum(int(s.face_count()) for s in scene.shapes() if hasattr(s, "face_count"))
    return LoadedScene(scene=scene, path=path, source=str(source if source is not None else "urban"),
                       params=params, settings=settings, bbox_lo=lo, bbox_hi=hi,
                       has_sensor=sensor is not None, n_shapes=len(scene.shapes()), n_triangles=n_tri,
                       offset=offset, shape_boxes=_shape_boxes(scene))


def _shape_boxes(scene: Any) -> np.ndarray:
    """float64 [n_shapes, 2, 3]: every shape's axis-aligned bounding box."""
    boxes = [(np.array(s.bbox().min, np.float64), np.array(s.bbox().max, np.float64)) for s in scene.shapes()]
    return np.array(boxes, np.float64).reshape(-1, 2, 3)


#: Scenes whose bounding-box centre lies farther than this [m] from the origin are traced in a
#: local frame (float32 geometry has 6 cm steps at 1e6 m, 12 rad of X-band phase).
RECENTER_DISTANCE = 100.0


def _load_mitsuba(path: Path, offset: np.ndarray | None = None) -> Any:
    """``mi.load_file`` (one shape per object), or with every top-level shape translated by
    ``-offset`` (appended to its ``to_world``: in float32 ``t - offset`` is exact for ``t`` near
    ``offset``, so the vertices arrive in local coordinates at full precision)."""
    level = mi.log_level()
    mi.set_log_level(mi.LogLevel.Error)      # silences the irrelevant default-film warning
    resolver = mi.file_resolver()
    saved = [str(resolver[i]) for i in range(len(resolver))]
    try:
        if offset is None:
            return mi.load_file(str(path), optimize=False)
        resolver.prepend(str(path.parent.resolve()))
        return mi.load_string(_shifted_xml(path, offset), optimize=False)
    except (RuntimeError, ET.ParseError) as exc:
        raise SceneError(f"cannot load scene {str(path)!r}: {_clean(exc)}") from None
    finally:
        mi.set_log_level(level)
        resolver.clear()
        for entry in saved:
            resolver.append(entry)


def _shifted_xml(path: Path, offset: np.ndarray) -> str:
    root = ET.parse(path).getroot()
    for shape in root.findall("shape"):
        transform = shape.find("transform[@name='to_world']")
        if transform is None:
            transform = ET.SubElement(shape, "transform", name="to_world")
        ET.SubElement(transform, "translate", x=repr(-float(offset[0])), y=repr(-float(offset[1])),
                      z=repr(-float(offset[2])))
    return ET.tostring(root, encoding="unicode")


MATERIAL_OVERRIDES = ("gamma_db", "scattering_coefficient")


def _override_materials(scene: Any, overrides: Mapping[str, Any]) -> None:
    unknown = set(overrides) - set(MATERIAL_OVERRIDES)
    if unknown:
        raise ParameterError(f"unknown material override {sorted(unknown)}; valid: {', '.join(MATERIAL_OVERRIDES)}")
    if not overrides:
        return
    for bsdf in {id(s.bsdf()): s.bsdf() for s in scene.shapes()}.values():
        if hasattr(bsdf, "set_roughness"):
            bsdf.set_roughness(**{k: float(v) for k, v in overrides.items()})


def _clean(exc: Exception) -> str:
    text = str(exc)
    return text.split("]", 1)[1].strip() if text.startswith("[") and "]" in text else text


def material_table(scene: Any, frequency: float, polarization: str) -> MaterialTable:
    """Reflection-coefficient tables of every shape's material at ``frequency`` [Hz].

    Raises
    ------
    SceneError
        A shape whose BSDF is not a radar material (``radar`` or ``itu-radio-material``).
    materials.MaterialError
        A material used outside its valid frequency range.
    """
    rows: dict[int, int] = {}
    tables, clutter, specular, ids, names = [], [], [], [], []
    for index, shape in enumerate(scene.shapes()):
        bsdf = shape.bsdf()
        if not hasattr(bsdf, "material_at"):
            raise SceneError(f"shape {shape.id()!r} uses BSDF {bsdf.class_().name() if hasattr(bsdf, 'class_') else bsdf}"
                             ", which has no radar properties; give it a <bsdf type=\"radar\"> or "
                             "<bsdf type=\"itu-radio-material\">")
        material = bsdf.material_at(frequency)
        key = bsdf.id_key            # one row per BSDF object: inline (id-less) BSDFs share no name
        if key not in rows:
            rows[key] = len(tables)
            names.append(bsdf.name)
            tables.append(materials.reflection_table(material, frequency, polarization, n=TABLE_SIZE))
            clutter.append(bsdf.clutter)
            specular.append(bsdf.specular_factor)
        shape_id = int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])
        # the clutter hash's key: the shape's id, or for an id-less shape its place in the file
        # (never its position, so moving it keeps its speckle; never shared, so two id-less
        # copies of one shape get independent speckle)
        name = shape.id() or f"#shape{index}"
        ids.append((shape_id, rows[key], zlib.crc32(name.encode()), np.array(shape.bbox().min, np.float32)))
    row_of_shape = np.zeros(max(i[0] for i in ids) + 1, np.uint32)
    shape_key = np.zeros_like(row_of_shape)
    shape_origin = np.zeros((row_of_shape.size, 3), np.float32)
    for shape_id, row, stable, origin in ids:
        row_of_shape[shape_id] = row
        shape_key[shape_id] = stable
        shape_origin[shape_id] = origin
    return MaterialTable(row_of_shape=row_of_shape, table=np.stack(tables).astype(np.complex64),
                         names=names, clutter=np.array(clutter, np.float32).reshape(-1, 2),
                         shape_key=shape_key, shape_origin=shape_origin,
                         specular=np.array(specular, np.float32))
