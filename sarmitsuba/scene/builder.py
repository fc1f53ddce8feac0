"""Scenes built in Python: meshes, a material per mesh and the sensor parameters, with no file.

:class:`Scene` is the in-memory counterpart of a scene XML file (docs/design.md section 4)::

    import trimesh, sarmitsuba
    scene = sarmitsuba.Scene(
        meshes=[(trimesh.creation.box((20, 20, 10)), "concrete"),
                (ground, {"type": "radar", "material": "medium_dry_ground", "gamma_db": -14}, "ground")],
        sensor={"frequency": 9.6e9, "incidence_angle": 45, "n_pulses": 64},
        integrator={"max_depth": 3})
    sim = sarmitsuba.simulate(scene)

Everything that accepts a scene path (:func:`sarmitsuba.scene.loader.load_scene`,
:func:`sarmitsuba.simulate`, :func:`sarmitsuba.render`, :func:`sarmitsuba.info.scene_info`)
accepts a :class:`Scene`; it goes through the same checks (mesh defects, parameter
resolution, recentring of scenes far from the origin) as an XML file. Inputs are checked
when the Scene is made, so a mistake is reported where it was written.
"""
from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from typing import Any

import mitsuba as mi
import numpy as np

from . import materials
from ..core.radar import ParameterError, RadarParameters
from ..core.valid_ranges import unknown_name
from .loader import SceneError, mitsuba_message
from .trace_inputs import TraceSettings

__all__ = ["Scene", "material_names"]

#: BSDF plugins of a material dict (``"plugin"``, or ``"type"`` for ``radar``; default ``"radar"``).
MATERIAL_TYPES = ("radar", "itu-radio-material")
#: Keys of the Mitsuba scene dict that are not shapes (no mesh may have these ids).
_RESERVED = ("type", "sar_sensor", "sbr_integrator")
#: String shortcut for a perfect electric conductor (``{"type": "radar", "model": "pec"}``).
PEC = "pec"


def material_names() -> tuple[str, ...]:
    """Valid string shortcuts for a mesh's material: ``"pec"`` and the ITU-R P.2040 names of
    :func:`sarmitsuba.scene.materials.itu_material_names` (``"concrete"``, ``"brick"``, ``"metal"``, ...)."""
    return (PEC,) + tuple(materials.itu_material_names())


class Scene:
    """A scene built in Python (see the module docstring).

    Parameters
    ----------
    meshes : sequence of (mesh, material) or (mesh, material, id)
        ``mesh``: a ``trimesh.Trimesh`` (or any object with ``vertices`` float [n, 3], m, and
        ``faces`` int [m, 3]), in world coordinates; triangles use face normals, as
        ``face_normals = true`` in XML. ``material``: a name of :func:`material_names`
        (an ITU material as a ``radar`` half space, or ``"pec"``) or a dict of BSDF
        parameters as in the plugin manual (plugins/radar_material.py):
        ``{"type": "radar", "material": "brick", "model": "slab", "thickness": 0.25,
        "gamma_db": -8}`` (``"type"`` may be left out: ``radar`` is the default), or
        ``{"plugin": "itu-radio-material", "type": "brick", "scattering_coefficient": 0.3}``
        (with ``"plugin"`` given, ``"type"`` is the ITU name, as in Sionna's XML). An
        ``"id"`` entry names it (default: the first mesh's id). One name, or one dict object, used by several
        meshes is one material (like an XML ``<ref>``). ``id``: the shape's name (default
        ``mesh<i>``), which keys its clutter speckle.
    sensor : mapping, optional
        ``sar`` sensor parameters (names and units of :class:`sarmitsuba.core.radar.RadarParameters`,
        plus ``aperture_length``); ``scene_center`` as 3 floats. None: no sensor, defaults
        are used (as for Sionna RT scenes).
    integrator : mapping, optional
        ``sbr`` integrator parameters (:class:`sarmitsuba.scene.trace_inputs.TraceSettings`).
    name : str, default "scene"
        Reported as the scene ``python:<name>`` (``LoadedScene.source``, metadata, titles).
    velocities : mapping, optional
        Shape id -> velocity (3 floats, m/s, scene frame), as Sionna RT's ``SceneObject.velocity``:
        the shape moves at it, standing where ``meshes`` puts it at the middle of the aperture;
        or ``{"velocity": v, "angular_velocity": w}``, ``w`` in deg/s about the middle of the
        shape's box (:mod:`sarmitsuba.scene.motion`; checked when the scene is loaded).

    Raises
    ------
    SceneError
        ``meshes`` empty, an entry that is not (mesh, material[, id]), an object that is not
        a triangle mesh, an empty mesh, non-finite vertices, face indices out of range, a
        repeated id. Messages name the entry as ``meshes[i]``.
    ParameterError
        Unknown material name (listing the valid ones) or BSDF parameter, unknown sensor or
        integrator parameter, or an invalid value.
    """

    def __init__(self, meshes: Sequence[Any], sensor: Mapping[str, Any] | None = None,
                 integrator: Mapping[str, Any] | None = None, name: str = "scene",
                 velocities: Mapping[str, Any] | None = None) -> None:
        if isinstance(meshes, (str, bytes)) or not isinstance(meshes, Sequence) or len(meshes) == 0:
            raise SceneError("Scene(meshes=...): give a non-empty list of (mesh, material) pairs")
        self.name = str(name)
        self._shapes = [_checked_entry(i, entry) for i, entry in enumerate(meshes)]
        ids = [shape[0] for shape in self._shapes]
        repeated = sorted({i for i in ids if ids.count(i) > 1} | (set(ids) & set(_RESERVED)))
        if repeated:
            raise SceneError(f"Scene: mesh ids {repeated} are used more than once or reserved "
                             f"({', '.join(_RESERVED)}); give each mesh its own id")
        self._materials = _material_specs(self._shapes)
        self.sensor = _sensor_values(sensor)
        self.integrator = _integrator_values(integrator)
        self.velocities = dict(velocities or {})

    @classmethod
    def from_footprints(cls, footprints: Any, out: Any = None, **options: Any) -> "Scene":
        """A city from building footprints in GeoJSON (``scene from-footprints``).

        ``footprints`` is the GeoJSON path; ``options`` are those of
        :func:`sarmitsuba.scene.city.build_city` (``default_height``, ``material``,
        ``ground_material``, ``dem``, ``elevation``, ``margin``, ``repair``,
        ``scattering_coefficient``, ``ground_scattering_coefficient``, ``sensor``, ``origin``).
        With ``out``, the scene folder (``out/scene.xml``, ``out/meshes/``) is written as well.
        Returns the Scene (meshes in the local ENU frame, the ``sar`` sensor with ``geo_origin``).

        Raises FootprintError (a SceneError; ``problems`` lists one line per bad feature),
        DemError, ParameterError, OSError (``out`` not writable).
        """
        from .city import build_city, write_city
        city = build_city(footprints, **options)
        if out is not None:
            write_city(city, out)
        return cls.from_city(city)

    @classmethod
    def from_city(cls, city: Any, name: str | None = None, split: bool = True) -> "Scene":
        """The Scene of a :class:`sarmitsuba.scene.city.City`: its buildings' parts (shape ids
        ``mesh-<slug>`` for the walls, ``mesh-<slug>-roof``, ``mesh-<slug>-windows``), ground (``mesh-ground``), materials and ``sar`` sensor, as
        :func:`~sarmitsuba.scene.city.write_city` writes them; named after the footprint file.
        ``split`` False: each building one closed mesh ``mesh-<slug>`` (a body whose height or
        pose a :class:`~sarmitsuba.derivatives.ShapeParameter` moves whole)."""
        from pathlib import Path
        specs = {key: {"id": key, **spec} for key, spec in city.material_specs().items()}
        meshes = [(mesh, specs[material], f"mesh-{name}") for name, mesh, material in city.shapes(split)]
        return cls(meshes, sensor=city.sensor, name=name or Path(city.source).stem)

    @property
    def source(self) -> str:
        """How the scene is reported: ``python:<name>``."""
        return f"python:{self.name}"

    @property
    def n_triangles(self) -> int:
        """Number of triangles of all meshes."""
        return sum(len(faces) for _, _, faces, _ in self._shapes)

    def to_mitsuba(self, offset: np.ndarray | None = None) -> Any:
        """The ``mitsuba.Scene``, with every vertex at ``world - offset`` (float64 subtraction,
        then float32: exact local coordinates for a scene far from the origin).

        Raises SceneError if Mitsuba rejects it."""
        offset = np.zeros(3) if offset is None else np.asarray(offset, np.float64)
        bsdfs = {key: _bsdf(spec) for key, spec in self._materials.items()}
        tree: dict[str, Any] = {"type": "scene"}
        for shape_id, vertices, faces, key in self._shapes:     # the key is the shape's id
            tree[shape_id] = _mesh(shape_id, vertices - offset, faces, bsdfs[key])
        if self.sensor is not None:
            tree[_RESERVED[1]] = {"type": "sar", **self.sensor}
        if self.integrator is not None:
            tree[_RESERVED[2]] = {"type": "sbr", **self.integrator}
        level = mi.log_level()
        mi.set_log_level(mi.LogLevel.Error)      # silences the irrelevant default-film warning
        try:
            return mi.load_dict(tree, optimize=False)
        except RuntimeError as exc:
            raise SceneError(f"cannot build scene {self.source!r}: {mitsuba_message(exc)}") from None
        finally:
            mi.set_log_level(level)

    def __repr__(self) -> str:
        return f"Scene({self.source}: {len(self._shapes)} meshes, {self.n_triangles} triangles)"


def _checked_entry(i: int, entry: Any) -> tuple[str, np.ndarray, np.ndarray, Any]:
    """(id, float64 vertices [n, 3], uint32 faces [m, 3], material) of ``meshes[i]``."""
    if isinstance(entry, (str, bytes)) or not isinstance(entry, Sequence) or len(entry) not in (2, 3):
        raise SceneError(f"meshes[{i}]: expected a (mesh, material) or (mesh, material, id) tuple, "
                         f"got {type(entry).__name__}")
    mesh, material = entry[0], entry[1]
    shape_id = str(entry[2]) if len(entry) == 3 else f"mesh{i}"
    if not shape_id or "." in shape_id:
        raise SceneError(f"meshes[{i}]: id {shape_id!r} must be non-empty and without '.' (Mitsuba's path "
                         "delimiter); use '_' instead")
    vertices, faces = _mesh_arrays(f"meshes[{i}]", mesh)
    return shape_id, vertices, faces, material


def _mesh_arrays(where: str, mesh: Any) -> tuple[np.ndarray, np.ndarray]:
    """Checked float64 vertices [n, 3] and uint32 faces [m, 3] of a trimesh-like object."""
    if type(mesh).__name__ == "Scene" and hasattr(mesh, "dump"):
        raise SceneError(f"{where}: a trimesh.Scene holds several meshes; pass mesh.dump(concatenate=True) "
                         "or one entry per geometry")
    if not (hasattr(mesh, "vertices") and hasattr(mesh, "faces")):
        raise SceneError(f"{where}: expected a trimesh.Trimesh (vertices [n, 3], faces [m, 3]), "
                         f"got {type(mesh).__name__}")
    try:
        vertices = np.array(mesh.vertices, dtype=np.float64)
        faces = np.array(mesh.faces)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{where}: vertices and faces must be numeric arrays ({exc})") from None
    if faces.size == 0 or vertices.size == 0:
        raise SceneError(f"{where}: empty mesh ({len(vertices)} vertices, {len(faces)} faces); "
                         "give at least one triangle")
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise SceneError(f"{where}: vertices must be [n, 3] and faces [m, 3] (triangles), "
                         f"got {vertices.shape} and {faces.shape}")
    if not np.all(np.isfinite(vertices)):
        raise SceneError(f"{where}: {int((~np.isfinite(vertices)).any(axis=1).sum())} vertices are not finite")
    if not np.issubdtype(faces.dtype, np.integer) or faces.min() < 0 or faces.max() >= len(vertices):
        raise SceneError(f"{where}: face indices must be integers in [0, {len(vertices) - 1}], "
                         f"got {faces.dtype} in [{faces.min()}, {faces.max()}]")
    return vertices, faces.astype(np.uint32)


def _material_specs(shapes: list) -> dict[Any, dict]:
    """One BSDF spec per distinct material (a name, or one dict object); rewrites each shape's
    material to its key. Each spec is built once here, so bad parameters fail now."""
    specs: dict[Any, dict] = {}
    for i, (shape_id, vertices, faces, material) in enumerate(shapes):
        key = material if isinstance(material, str) else id(material)
        if key not in specs:
            specs[key] = _material_spec(f"meshes[{i}]", material, shape_id)
            _bsdf(specs[key], where=f"meshes[{i}]")
        shapes[i] = (shape_id, vertices, faces, key)
    return specs


def _material_spec(where: str, material: Any, shape_id: str) -> dict:
    """``{"plugin": plugin, "id": name, **parameters}`` of a material name or dict."""
    if isinstance(material, str):
        if material == PEC:
            return {"plugin": "radar", "id": PEC, "model": "pec"}
        if material not in materials.itu_material_names():
            raise ParameterError(f"{where}: {unknown_name('material', material, material_names())}, or a dict "
                                 "of radar BSDF parameters")
        return {"plugin": "radar", "id": material, "material": material}
    if not isinstance(material, Mapping):
        raise ParameterError(f"{where}: material must be a name ({', '.join(material_names())}) or a dict "
                             f"of BSDF parameters, got {type(material).__name__}")
    parameters = {str(k): v for k, v in material.items()}
    plugin = parameters.pop("plugin") if "plugin" in parameters else parameters.pop("type", "radar")
    if plugin not in MATERIAL_TYPES:
        raise ParameterError(f"{where}: material plugin {plugin!r}; valid: {', '.join(MATERIAL_TYPES)} "
                             "(give it as \"plugin\", or as \"type\" for radar)")
    return {"id": shape_id, **parameters, "plugin": plugin}


def _bsdf(spec: dict, where: str | None = None) -> Any:
    """The radar BSDF object of a spec; ParameterError prefixed with ``where``."""
    module = sys.modules["sarmitsuba_plugins.radar_material"]      # registered by sarmitsuba.tracing._variant
    props = mi.Properties(spec["plugin"])
    props.set_id(str(spec["id"]))
    for key, value in spec.items():
        if key in ("plugin", "id"):
            continue
        props[key] = mi.ScalarColor3f(*module._as_rgb(value)) if key in ("color", "reflectance", "base_color") \
            else _scalar(value)
    try:
        return module.RadarMaterial(props, sionna=spec["plugin"] == "itu-radio-material")
    except (ParameterError, TypeError, ValueError) as exc:
        if where is None:
            raise
        raise ParameterError(f"{where}: {exc}") from None


def _mesh(shape_id: str, vertices: np.ndarray, faces: np.ndarray, bsdf: Any) -> Any:
    """A ``mi.Mesh`` with face normals from float64 ``vertices`` (converted to float32) and ``faces``."""
    props = mi.Properties()
    props["bsdf"] = bsdf
    mesh = mi.Mesh(shape_id, len(vertices), len(faces), props=props, has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(vertices.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(faces.ravel())
    params.update()
    return mesh


def _scalar(value: Any) -> Any:
    """A Python scalar for mi.Properties (NumPy scalars converted; sequences joined as "a, b, c")."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, str):
        return value
    return ", ".join(repr(float(v)) for v in value)


def _sensor_values(sensor: Mapping[str, Any] | None) -> dict | None:
    """The sensor parameters, checked (names and values) as the ``sar`` plugin would."""
    return _parameters("sensor", "sar sensor", sensor, RadarParameters.from_mapping)


def _integrator_values(integrator: Mapping[str, Any] | None) -> dict | None:
    """The integrator parameters, checked (names and values) as the ``sbr`` plugin would."""
    return _parameters("integrator", "sbr integrator", integrator, TraceSettings.from_mapping)


def _parameters(argument: str, kind: str, values: Mapping[str, Any] | None, check) -> dict | None:
    """``values`` as Mitsuba property values, after ``check`` (ParameterError naming a bad one)."""
    if values is None:
        return None
    if not isinstance(values, Mapping):
        raise ParameterError(f"Scene({argument}=...): a dict of {kind} parameters, got {type(values).__name__}")
    out = {}
    for key, value in values.items():
        try:
            out[str(key)] = _scalar(value)
        except (TypeError, ValueError):
            raise ParameterError(f"{kind} parameter {key}: cannot use value {value!r} (a number, a string, or "
                                 "3 numbers for scene_center)") from None
    check(out)
    return out
