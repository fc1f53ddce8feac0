"""Loading a scene: XML path, built-in name or ``sionna:NAME``, plus the SAR sensor and tracer settings.

A scene is a Mitsuba XML file (docs/design.md section 4). ``load_scene`` resolves where it is,
loads it with sarmitsuba's plugins, reads the ``sar`` sensor and ``sbr`` integrator (or
uses the defaults when the scene has none, as Sionna RT scenes do), applies overrides
(from the CLI), and resolves the automatic parameters against the scene's bounding box.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import math
import os
import re
import warnings
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import drjit as dr
import mitsuba as mi
import numpy as np

from ..core import georef
from . import materials
from .meshcheck import check_meshes, shape_points, silent_scene, warn_mesh_defects
from .meshrepair import repair_meshes
from .geometry_checks import check_geometry
from .planning import AcquisitionWarning, resolve_parameters
from .track_checks import check_beam_reach
from .radar_equation import radar_equation
from ..core.radar import TRAJECTORIES, ParameterError, RadarParameters
from ..core.orbit import choose_pass, in_scene_frame, orbit_of
from ..core.trajectory import StateVectors, read_state_vectors
from ..core.valid_ranges import unknown_name
from ..core.outputs import product_kind
from .ground import ground_shapes
from .rough_tables import coherent_factor, rough_tables
from .rough_presets import PRESETS, ROLE_PRESETS, preset_row, preset_surface
from .roles import shape_roles
from ..core.constants import SPEED_OF_LIGHT
from .mitsuba_errors import located, mitsuba_message
from .motion import ShapeMotion, file_velocities, moving_shapes, swept_box, xml_velocities
from .trace_inputs import MaterialTable, TraceSettings

__all__ = ["SceneError", "LoadedScene", "resolve_source", "load_scene", "material_table", "shape_frame", "mitsuba_message",
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
    path : Path or None
        The XML file; None for a scene built in Python (:class:`sarmitsuba.scene.builder.Scene`).
    source : str
        What the user asked for (path, built-in name or ``sionna:NAME``), or
        ``python:<name>`` for a scene built in Python.
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
    motion : ShapeMotion or None
        The shapes that move (:mod:`sarmitsuba.scene.motion`); ``bbox_lo``, ``bbox_hi`` then hold
        their paths across the aperture. None: the scene holds still.
    """

    scene: Any
    path: Path | None
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
    motion: ShapeMotion | None = None


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


def resolve_source(source: Any) -> Path | None:
    """Path of the XML file for ``source`` (None = the default ``urban`` scene); None for a
    scene built in Python (:class:`sarmitsuba.scene.builder.Scene`), which has no file.

    Raises
    ------
    SceneError
        Unknown built-in or Sionna scene name (listing the valid ones), Sionna RT not
        installed, or a file that does not exist.
    """
    if _built_in_python(source):
        return None
    source = "urban" if source is None else str(source)
    if source.startswith("sionna:"):
        name = source.split(":", 1)[1]
        scenes = sionna_scenes()
        if not scenes:
            raise SceneError(f"{source}: Sionna RT is not installed; install it with "
                             "`pip install 'sarmitsuba[sionna]'` (or `pip install sionna-rt`)")
        if name not in scenes:
            raise SceneError(f"{source}: {unknown_name('Sionna RT scene', name, scenes)}")
        return scenes[name]
    builtins = builtin_scenes()
    if source in builtins:
        return builtins[source]
    path = Path(source)
    if path.is_dir() and (path / "scene.xml").is_file():       # a scene folder (scene from-footprints)
        return path / "scene.xml"
    if not path.is_file():
        hint = f"; built-in scenes: {', '.join(builtins)}" if builtins else ""
        if builtins and path.suffix == "" and len(path.parts) == 1:         # a misspelt built-in name
            hint = "; " + unknown_name("built-in scene", source, builtins).split("; ", 1)[1]
        raise SceneError(f"scene file {str(path)!r} does not exist{hint}")
    kind = product_kind(path)
    if kind is not None:                                # before Mitsuba's "No document element found"
        raise SceneError(f"{str(path)!r} is {kind}, not a scene: render, info and preview take a "
                         "scene (XML, a folder holding scene.xml, or a built-in name); focus takes raw data "
                         "(raw.npz, .cphd), analyze an image (image.npz, .nitf), info also a render folder")
    return path


def load_scene(source: str | Path | None = None, sensor_overrides: Mapping[str, Any] | None = None,
               integrator_overrides: Mapping[str, Any] | None = None,
               material_overrides: Mapping[str, Any] | None = None) -> LoadedScene:
    """Load a scene and resolve its radar parameters and tracer settings.

    Parameters
    ----------
    source : str or Path or sarmitsuba.scene.builder.Scene or None
        XML path, built-in scene name (``urban``, ``dihedral``, ``trihedral``),
        ``sionna:NAME``, or a scene built in Python (:class:`sarmitsuba.Scene`); None = ``urban``.
    sensor_overrides, integrator_overrides : mapping, optional
        Parameter values replacing the scene's (names as in the plugin manuals).
    material_overrides : mapping, optional
        Roughness applied to every material: ``gamma_db`` [dB] or ``scattering_coefficient``.

    Raises
    ------
    SceneError
        File missing or malformed, a plugin rejected its parameters, or no shape can scatter
        (every triangle of zero area; :func:`~sarmitsuba.scene.meshcheck.silent_scene`).
    ParameterError
        An override names an unknown parameter or has an invalid value; or the geometry cannot
        be imaged (:func:`~sarmitsuba.scene.geometry_checks.check_geometry`: geometry at or beyond the
        nadir, a scene beyond the radar horizon, an automatic track mostly empty).
    """
    path = resolve_source(source)
    label = str(path) if path is not None else source.source      # a Python scene: python:<name>
    load = source.to_mitsuba if path is None else lambda offset=None: _load_mitsuba(path, offset)
    scene = load()
    center = 0.5 * (np.array(scene.bbox().min, np.float64) + np.array(scene.bbox().max, np.float64))
    offset = np.zeros(3)
    if np.all(np.isfinite(center)) and np.linalg.norm(center) > RECENTER_DISTANCE:
        offset = np.round(center)              # whole metres: exact in float32 below 2^24 m
        scene = load(offset)
    reports = check_meshes(scene)
    silent = silent_scene(reports, len(scene.shapes()), label)
    if silent is not None:
        raise SceneError(silent)
    repairs = repair_meshes(scene, reports)          # duplicates traced once, closed bodies wound outward
    if any(fix.dropped or fix.rewound for fix in repairs):
        reports = check_meshes(scene)
    warn_mesh_defects(reports, label, repairs)
    _override_materials(scene, material_overrides or {})
    sensor = next((s for s in scene.sensors() if hasattr(s, "parameters") and hasattr(s, "given")), None)
    given = dict(sensor.given) if sensor is not None else {}
    given.update(sensor_overrides or {})
    params = RadarParameters.from_mapping(given)
    # a trajectory given on its own: only the values given with it pick its pass (as _note_replaced counts them)
    params = _read_trajectory(params, path if "trajectory" not in (sensor_overrides or {}) else None, offset,
                              given if "trajectory" not in (sensor_overrides or {}) else sensor_overrides)
    if params.geo_origin is None and isinstance(source, str) and source.startswith("sionna:"):
        known = georef.SCENE_ORIGINS.get(source.split(":", 1)[1])
        params = params if known is None else dataclasses.replace(params, geo_origin=known.as_tuple())
    if params.scene_center is not None and np.any(offset):
        params = dataclasses.replace(params, scene_center=tuple((np.asarray(params.scene_center) - offset).tolist()))
    integrator = scene.integrator()
    settings_given = dict(getattr(integrator, "given", {}))
    settings_given.update(integrator_overrides or {})
    settings = TraceSettings.from_mapping(settings_given)
    ground_shapes(settings.ground_shapes, [shape.id() for shape in scene.shapes()])     # names checked before tracing
    if settings.range_kernel == "exact" and params.output == "raw":
        raise ParameterError("sbr range_kernel = 'exact' evaluates range-compressed samples and cannot make chirped "
                             "echoes: use sar output = 'compressed', or range_kernel 'linear' or 'sinc' with output = 'raw'")
    if settings.polarimetry == "scalar" and params.polarimetric:
        raise ParameterError(f"sbr polarimetry = 'scalar' has one co-polarised channel only, but sar polarization = "
                             f"{params.polarization!r}: use polarimetry = 'jones' (the default), or polarization "
                             "'HH' or 'VV'")
    bbox = scene.bbox()
    lo, hi = np.array(bbox.min, np.float64), np.array(bbox.max, np.float64)
    if not (np.all(np.isfinite(lo)) and np.all(hi >= lo)):
        raise SceneError(f"scene {label!r} has no geometry (empty bounding box)")
    automatic_track = params.n_pulses == 0
    params = resolve_parameters(params, lo, hi)
    boxes = _shape_boxes(scene)
    motion = moving_shapes(scene, source.velocities if path is None else file_velocities(path), params, label)
    if motion is not None:
        if settings.lit_regions != "patches":
            raise ParameterError("moving shapes are traced by the mesh's lit regions only: set sbr lit_regions = "
                                 f"'patches' (the default), not {settings.lit_regions!r}, or give no velocity")
        lo, hi = swept_box(motion, boxes, label)
    # a trajectory given on its own replaces the scene's platform silently: only values given with it count
    _note_replaced(given if "trajectory" not in (sensor_overrides or {}) else sensor_overrides, params)
    check_geometry(params, lo, hi, shape_points(scene), automatic_track, offset)   # before any cost estimate
    check_beam_reach(params, lo, hi)                  # some pulse's beam must reach the scene, any trajectory
    radar_equation(params)                   # radiometry parameters checked before any tracing
    n_tri = sum(int(s.face_count()) for s in scene.shapes() if hasattr(s, "face_count"))
    name = label if path is None else str(source if source is not None else "urban")
    return LoadedScene(scene=scene, path=path, source=name,
                       params=params, settings=settings, bbox_lo=lo, bbox_hi=hi,
                       has_sensor=sensor is not None, n_shapes=len(scene.shapes()), n_triangles=n_tri,
                       offset=offset, shape_boxes=boxes, motion=motion)


def _read_trajectory(params: RadarParameters, scene_file: Path | None, offset: np.ndarray,
                     given: Mapping[str, Any] | None = None) -> RadarParameters:
    """A trajectory file read into state vectors in the tracing frame (``offset`` subtracted): a
    relative path from the scene file's folder when the scene names it, else from the working
    directory (docs/physics.md (J2)). Named trajectories and Python state vectors pass through
    (the latter moved by ``offset``). An ECEF orbit is cut to the pass it images (J6,
    :func:`_one_pass`; ``given``: the sensor values the user gave)."""
    kind = params.trajectory
    if params.orbit_pass_time is not None and isinstance(kind, str) and kind in TRAJECTORIES:
        raise ParameterError(f"orbit_pass_time = {params.orbit_pass_time} picks a pass of an ECEF orbit file, but "
                             f"trajectory = {getattr(kind, 'source', kind)!r}: remove orbit_pass_time")
    if isinstance(kind, StateVectors):
        kind = _one_pass(in_scene_frame(kind, georef.of(params)), params, given or {})   # ECEF: ENU at geo_origin
        return dataclasses.replace(params, trajectory=kind.shifted(offset) if np.any(offset) else kind)
    if kind == "orbit":                                  # the built-in orbit on the real Earth (J7)
        states = in_scene_frame(orbit_of(params), georef.of(params))
        return dataclasses.replace(params, trajectory=states.shifted(offset) if np.any(offset) else states)
    if kind in TRAJECTORIES:
        return params
    file = Path(kind).expanduser()
    if not file.is_absolute() and scene_file is not None:
        file = scene_file.parent / file
    states = _one_pass(in_scene_frame(read_state_vectors(file), georef.of(params)), params, given or {})
    return dataclasses.replace(params, trajectory=states.shifted(offset) if np.any(offset) else states)


def _one_pass(states: StateVectors, params: RadarParameters, given: Mapping[str, Any]) -> StateVectors:
    """An orbit file's states (the ENU frame at ``geo_origin``) cut to the pass the sensor images,
    :func:`sarmitsuba.core.orbit.choose_pass` (``look_side`` and ``incidence_angle`` count when the
    user gave them), warning (AcquisitionWarning) when several passes qualify and none was chosen;
    other states pass unchanged. Raises ParameterError when no pass qualifies."""
    if not states.closest_approach:
        if params.orbit_pass_time is not None:
            raise ParameterError(f"orbit_pass_time = {params.orbit_pass_time} picks a pass of an ECEF orbit file, "
                                 f"but trajectory {states.source} is in the scene frame: remove orbit_pass_time")
        return states
    incidence = params.incidence_angle if given.get("incidence_angle") is not None else None
    states, note = choose_pass(states, georef.of(params), params.look_side, given.get("look_side") is not None,
                               incidence, params.orbit_pass_time)
    if note is not None:
        warnings.warn(note, AcquisitionWarning, stacklevel=4)
    return states


#: Platform parameters that state vectors set (docs/physics.md (J2)).
_FROM_STATES = ("altitude", "incidence_angle", "velocity", "heading", "look_side")


def _note_replaced(given: Mapping[str, Any], params: RadarParameters) -> None:
    """Warn once when state vectors replace platform parameters given with them (``given``: the
    overrides when the trajectory is one, else the scene's values and the overrides); the scene's
    own defaults, replaced by a trajectory the user gives, are not named."""
    if not isinstance(params.trajectory, StateVectors):
        return
    replaced = []
    used = ("altitude", "incidence_angle", "look_side") if params.trajectory.source == "orbit" else ()  # placed it
    for name in _FROM_STATES:
        if name not in given or given[name] is None or name in used:
            continue
        old, new = given[name], getattr(params, name)
        same = str(old) == new if name == "look_side" else math.isclose(float(old), new, rel_tol=1e-3, abs_tol=1e-3)
        if not same:
            replaced.append(f"{name} {float(old):g} -> {new:.6g}" if name != "look_side" else f"{name} {old} -> {new}")
    if replaced:
        # the built-in orbit (J7): Kepler fixes its speed, the orbit's plane its heading
        fix = ("; the orbit's speed follows from altitude, its heading from orbit_inclination and orbit_direction"
               if params.trajectory.source == "orbit" else "")
        warnings.warn(f"trajectory {params.trajectory.source} sets the platform from its mid-aperture state: "
                      f"{', '.join(replaced)} (the values given are not used{fix})", AcquisitionWarning, stacklevel=3)


def _built_in_python(source: Any) -> bool:
    """Whether ``source`` is a scene built in Python (:class:`sarmitsuba.scene.builder.Scene`): it builds its
    own Mitsuba scene (``to_mitsuba``), where a path names a file or a built-in scene."""
    return not isinstance(source, (str, os.PathLike)) and source is not None and callable(getattr(source, "to_mitsuba", None))


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
        if offset is None and not file_velocities(path):
            return _check_ids(mi.load_file(str(path), optimize=False), path)
        resolver.prepend(str(path.parent.resolve()))
        return _check_ids(mi.load_string(_edited_xml(path, offset), optimize=False), path)
    except (RuntimeError, ET.ParseError) as exc:
        file, line, message = located(exc)
        where = "" if line is None else (f", line {line}" if file is None or Path(file) == path
                                         else f" ({file!r}, line {line})")
        raise SceneError(f"cannot load scene {str(path)!r}{where}: {message}") from None
    finally:
        mi.set_log_level(level)
        resolver.clear()
        for entry in saved:
            resolver.append(entry)


def _edited_xml(path: Path, offset: np.ndarray | None) -> str:
    """The scene file's XML with every top-level shape translated by ``-offset`` (None: not) and
    its ``velocity`` taken out (:func:`~sarmitsuba.scene.motion.xml_velocities`)."""
    data = path.read_bytes()
    try:
        root = ET.fromstring(data)
    except ET.ParseError:      # as Mitsuba, accept a non-UTF-8 byte (a Latin-1 comment) where none is declared
        if data.startswith((b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff")) or re.match(rb"<\?xml[^>]*encoding", data):
            raise
        root = ET.fromstring(data.decode("latin-1"))     # (ids were checked by the first load)
    xml_velocities(root, str(path))
    for shape in root.findall("shape") if offset is not None else ():
        transform = shape.find("transform[@name='to_world']")
        if transform is None:
            transform = ET.SubElement(shape, "transform", name="to_world")
        ET.SubElement(transform, "translate", x=repr(-float(offset[0])), y=repr(-float(offset[1])),
                      z=repr(-float(offset[2])))
    return ET.tostring(root, encoding="unicode")


MATERIAL_OVERRIDES = ("gamma_db", "scattering_coefficient", "roughness")


def _override_materials(scene: Any, overrides: Mapping[str, Any]) -> None:
    unknown = set(overrides) - set(MATERIAL_OVERRIDES)
    if unknown:
        raise ParameterError(unknown_name("material override", sorted(unknown)[0], MATERIAL_OVERRIDES))
    if not overrides:
        return
    overrides = dict(overrides)
    preset = overrides.pop("roughness", None)
    if preset is not None and overrides:
        raise ParameterError(f"--material-set roughness={preset} gives every material its preset surface; "
                             f"it cannot be combined with {', '.join(sorted(overrides))}")
    if preset is not None and str(preset) not in PRESETS:
        raise ParameterError(unknown_name("roughness preset", str(preset), tuple(PRESETS)))
    bsdfs = {id(s.bsdf()): s.bsdf() for s in scene.shapes()}.values()
    for bsdf in bsdfs:
        if preset is not None and hasattr(bsdf, "set_surface"):
            # an ITU class the preset names takes its surface; other materials keep theirs
            if str(preset) == "none" or bsdf.itu_name in PRESETS[str(preset)]:
                bsdf.set_surface(preset_surface(str(preset), bsdf.itu_name))
        elif hasattr(bsdf, "set_roughness"):
            bsdf.set_roughness(**{k: float(v) for k, v in overrides.items()})
    if preset is not None:
        _set_role_surfaces(scene, str(preset))


def _set_role_surfaces(scene: Any, preset: str) -> None:
    """Where the preset's rules say a class does not describe a role's surface (Sionna's metal
    roofs), the shapes of that role take the role's surface (docs/physics.md (RS8)). The roles are
    cast only when some material in the scene has such a rule."""
    rules = ROLE_PRESETS[preset][1]
    shapes = list(scene.shapes())
    ruled = {r for bsdf in (s.bsdf() for s in shapes) for (name, r) in rules
             if getattr(bsdf, "itu_name", None) == name and hasattr(bsdf, "set_role_surfaces")}
    if not ruled:
        return
    roles = shape_roles(scene)
    by_bsdf: dict[int, tuple[Any, dict]] = {}
    for shape, role in zip(shapes, roles.role):
        bsdf = shape.bsdf()
        if hasattr(bsdf, "set_role_surfaces") and (bsdf.itu_name, role) in rules:
            shape_id = int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])
            by_bsdf.setdefault(id(bsdf), (bsdf, {}))[1][shape_id] = role
    for bsdf, members in by_bsdf.values():
        rows = {r: preset_row(preset, bsdf.itu_name, r) for r in set(members.values())}
        bsdf.set_role_surfaces({r: row.surface for r, row in rows.items()}, members,
                               {r: row.material for r, row in rows.items()})


#: A vertex counts as distinct from the frame's origin, and from the line of its first axis,
#: beyond this fraction of the shape's largest extent (:func:`shape_frame`): far above float32
#: round-off of the vertex positions (1e-7), far below any shape's features.
FRAME_TOLERANCE = 1e-3


def shape_frame(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A frame fixed to a shape, from its vertices in their stored order: the frame the clutter
    scatterer lattice is anchored to (docs/physics.md (C)).

    The origin is vertex 0; the first axis points to the first vertex farther than
    ``FRAME_TOLERANCE`` times the shape's extent, the second to the first vertex that far off the
    first axis' line (made orthogonal to it), the third is their cross product. Vertex order does
    not change when a shape is translated or rotated, so the frame moves rigidly with the shape:
    rotating the vertices by ``R`` and translating them by ``t`` gives origin ``R o + t`` and
    axes ``R a``.

    Parameters
    ----------
    vertices : float [n, 3], m

    Returns
    -------
    origin : float64 [3], m
    axes : float64 [3, 3]
        Rows: the frame's orthonormal axes, right-handed. Without two distinct vertices the axes
        are the world's; without a third off the first axis' line (a shape on one line), the
        second axis is the world's ``z x a1`` (or ``x x a1`` for a vertical line), which is then
        not rigid about that line.
    """
    v = np.asarray(vertices, np.float64).reshape(-1, 3)
    if v.shape[0] == 0:
        return np.zeros(3), np.eye(3)
    offsets = v - v[0]
    tolerance = FRAME_TOLERANCE * max(float(np.ptp(v, axis=0).max()), np.finfo(np.float64).tiny)
    distance = np.linalg.norm(offsets, axis=1)
    far = np.flatnonzero(distance > tolerance)
    if far.size == 0:
        return v[0].copy(), np.eye(3)
    first = offsets[far[0]] / distance[far[0]]
    across = offsets - np.outer(offsets @ first, first)
    off_line = np.linalg.norm(across, axis=1)
    wide = np.flatnonzero(off_line > tolerance)
    if wide.size:
        second = across[wide[0]] / off_line[wide[0]]
    else:
        helper = np.array([0.0, 0.0, 1.0]) if abs(first[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        second = np.cross(helper, first)
        second /= np.linalg.norm(second)
    return v[0].copy(), np.stack([first, second, np.cross(first, second)])


def _shape_frame_of(shape: Any) -> tuple[np.ndarray, np.ndarray]:
    """:func:`shape_frame` of a Mitsuba shape; a shape without vertices (an analytic sphere, say)
    gets its bounding box's lowest corner and the world's axes, which translate with it but do not
    rotate."""
    if shape.is_mesh() and shape.vertex_count() > 0:
        return shape_frame(np.array(shape.vertex_positions_buffer(), np.float64))
    return np.array(shape.bbox().min, np.float64), np.eye(3)


def _check_ids(scene: Any, path: Path) -> Any:
    """``scene``, once every shape's and BSDF's id can be read. Mitsuba reads an XML file without
    an encoding declaration as UTF-8 and keeps any other byte as it is (a Latin-1 ``0xE9``), so
    such an id cannot reach Python: refused, naming the file and the fix."""
    for index, shape in enumerate(scene.shapes()):
        for what, obj in (("shape", shape), ("BSDF of shape", shape.bsdf())):
            try:
                obj.id()
            except UnicodeDecodeError as exc:
                raise SceneError(
                    f"scene {str(path)!r}: the id of {what} #{index} ({exc.object.decode('latin-1')!r} read as "
                    "Latin-1) is not UTF-8, the encoding of an XML file without a declaration: declare it "
                    "(<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?> as the first line) or save the file "
                    "as UTF-8") from None
    return scene


def material_table(scene: Any, frequency: float, polarization: str) -> MaterialTable:
    """Reflection-coefficient tables of every shape's material at ``frequency`` [Hz]: ``r`` of the
    ``polarization``'s channel (the scalar model (R)), ``r_te`` and ``r_tm`` (the Jones model),
    the clutter's cross-polarised level (docs/physics.md (P3'), (P7)) and the rough surfaces'
    sigma nought tables (RS6).

    Raises
    ------
    SceneError
        A shape whose BSDF is not a radar material (``radar`` or ``itu-radio-material``).
    materials.MaterialError
        A material used outside its valid frequency range.
    """
    rows: dict[int, int] = {}
    tables, clutter, specular, ids, names = [], [], [], [], []
    tables_te, tables_tm, cross_pol = [], [], []           # for the Jones model, docs/physics.md (P3')
    grazing = []                                            # the grazing wave's Delta, (E6)
    surfaces, permittivities = [], []                       # rough surfaces' statistics, (RS6)
    wavenumber = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    for index, shape in enumerate(scene.shapes()):
        bsdf = shape.bsdf()
        if not hasattr(bsdf, "material_at"):
            raise SceneError(f"shape {shape.id()!r} uses BSDF {bsdf.class_().name() if hasattr(bsdf, 'class_') else bsdf}"
                             ", which has no radar properties; give it a <bsdf type=\"radar\"> or "
                             "<bsdf type=\"itu-radio-material\">")
        shape_id = int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])
        # one row per BSDF object (inline, id-less BSDFs share no name) and role whose surface
        # a preset's rule gives it (RS8)
        role = bsdf.role_of(shape_id) if hasattr(bsdf, "role_of") else None
        material = bsdf.material_at(frequency) if role is None else bsdf.role_material_at(role, frequency)
        key = (bsdf.id_key, role)
        if key not in rows:
            rows[key] = len(tables)
            names.append(bsdf.name if role is None else f"{bsdf.name} ({role})")
            surface = getattr(bsdf, "surface", None) if role is None else bsdf.role_surfaces[role]
            # a rough surface's specular reflection carries its coherent factor (RS6)
            coherent = 1.0 if surface is None else coherent_factor(surface, wavenumber, np.linspace(0, 1, TABLE_SIZE))
            tables_te.append((materials.reflection_table(material, frequency, "HH", n=TABLE_SIZE) * coherent).astype(np.complex64))
            tables_tm.append((materials.reflection_table(material, frequency, "VV", n=TABLE_SIZE) * coherent).astype(np.complex64))
            surfaces.append(surface)
            permittivities.append(material.relative_permittivity)
            tables.append(tables_tm[-1] if polarization == "VV" else tables_te[-1])
            cross_pol.append(getattr(bsdf, "cross_pol", 0.0))
            grazing.append(materials.grazing_impedance(material, frequency))
            clutter.append(bsdf.clutter if role is None else ((3, 1.0) if surface is not None else (0, 0.0)))
            specular.append(bsdf.specular_factor if role is None else 1.0)
        # the clutter hash's key: the shape's id, or for an id-less shape its place in the file
        # (never its position, so moving it keeps its speckle; never shared, so two id-less
        # copies of one shape get independent speckle)
        name = shape.id() or f"#shape{index}"
        # the scatterer lattice's anchor: a frame that moves and turns with the shape (C)
        ids.append((shape_id, rows[key], zlib.crc32(name.encode()), *_shape_frame_of(shape)))
    row_of_shape = np.zeros(max(i[0] for i in ids) + 1, np.uint32)
    shape_key = np.zeros_like(row_of_shape)
    shape_origin = np.zeros((row_of_shape.size, 3), np.float64)
    shape_axes = np.tile(np.eye(3), (row_of_shape.size, 1, 1))
    for shape_id, row, stable, origin, axes in ids:
        row_of_shape[shape_id] = row
        shape_key[shape_id] = stable
        shape_origin[shape_id] = origin
        shape_axes[shape_id] = axes
    return MaterialTable(row_of_shape=row_of_shape, table=np.stack(tables).astype(np.complex64),
                         names=names, clutter=np.array(clutter, np.float32).reshape(-1, 2),
                         shape_key=shape_key, shape_origin=shape_origin, shape_axes=shape_axes,
                         specular=np.array(specular, np.float32),
                         table_te=np.stack(tables_te).astype(np.complex64),
                         table_tm=np.stack(tables_tm).astype(np.complex64),
                         cross_pol=np.array(cross_pol, np.float32),
                         grazing_delta=np.array(grazing, np.complex128),
                         rough=rough_tables(surfaces, permittivities, wavenumber,
                                            cross=polarization in ("HV", "VH", "quad")) if any(surfaces) else None)
