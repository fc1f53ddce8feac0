"""Shapes that move during the acquisition (docs/physics.md (V1)-(V3)).

A shape may carry a constant velocity [m/s] in the scene frame, as Sionna RT's scene objects
do (``SceneObject.velocity``): in XML a ``<vector name="velocity" value="vx, vy, vz"/>`` inside
the ``<shape>`` (read here and removed before Mitsuba sees the file), in Python the
``velocities`` mapping of :class:`sarmitsuba.scene.builder.Scene`. It may also turn, at a
constant angular velocity [deg/s] about its centre (the middle of its bounding box as given):
``<vector name="angular_velocity" value="wx, wy, wz"/>``, or a mapping ``{"velocity": v,
"angular_velocity": w}`` in ``velocities``. The shape's geometry as given is where it stands at
the middle of the aperture (the mean of the first and last pulses' transmit times); at any other
time ``t`` each vertex is at ``c + v (t - t_mid) + R(w (t - t_mid)) (x - c)``, ``R`` the rotation
by the angle vector ``w (t - t_mid)``.

:func:`moving_shapes` checks the velocities and gives the :class:`ShapeMotion` that the tracer
follows (:mod:`sarmitsuba.tracing.driver.moving`); :func:`swept_box` is the scene's box with
every moving shape's path across the aperture, for the fast-time window and the beam checks.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..core.valid_ranges import ParameterError

__all__ = ["ShapeMotion", "VELOCITY", "ANGULAR_VELOCITY", "xml_velocities", "file_velocities", "moving_shapes", "swept_box"]

#: The XML parameters (``vector`` children of a ``<shape>``): velocity [m/s] and angular velocity [deg/s].
VELOCITY = "velocity"
ANGULAR_VELOCITY = "angular_velocity"


@dataclass(frozen=True)
class ShapeMotion:
    """The shapes that move, each at a constant velocity (hashable: tuples only).

    Attributes
    ----------
    ids : tuple of str
        The moving shapes' ids.
    shapes : tuple of int
        Their indices in ``mitsuba.Scene.shapes()``.
    velocity : tuple of (float, float, float)
        Each one's velocity in the scene frame, m/s.
    duration : float
        The aperture's length in time, ``(n_pulses - 1) / PRF``, s: every shape stands where the
        scene puts it at the middle of it.
    angular_velocity : tuple of (float, float, float)
        Each one's angular velocity about its centre, deg/s (zeros: it does not turn).
    centre : tuple of (float, float, float)
        Each one's centre of rotation, the middle of its bounding box at mid-aperture, m.
    radius : tuple of float
        Each one's farthest vertex from its centre, m.
    """

    ids: tuple[str, ...]
    shapes: tuple[int, ...]
    velocity: tuple[tuple[float, float, float], ...]
    duration: float
    angular_velocity: tuple[tuple[float, float, float], ...] = ()
    centre: tuple[tuple[float, float, float], ...] = ()
    radius: tuple[float, ...] = ()

    def velocities(self) -> np.ndarray:
        """float64 [n, 3]: :attr:`velocity` as an array, m/s."""
        return np.asarray(self.velocity, np.float64).reshape(-1, 3)

    def angular_velocities(self) -> np.ndarray:
        """float64 [n, 3]: :attr:`angular_velocity` in rad/s (zeros where none was given)."""
        if not self.angular_velocity:
            return np.zeros((len(self.ids), 3))
        return np.radians(np.asarray(self.angular_velocity, np.float64).reshape(-1, 3))

    def speeds(self) -> np.ndarray:
        """float64 [n]: the fastest any point of each shape moves, ``|v| + |w| r``, m/s."""
        radius = np.asarray(self.radius, np.float64) if self.radius else np.zeros(len(self.ids))
        return np.linalg.norm(self.velocities(), axis=1) + np.linalg.norm(self.angular_velocities(), axis=1) * radius


def _vector(element: ET.Element, where: str) -> tuple[float, float, float]:
    """A Mitsuba ``vector`` element's value (``value="x, y, z"`` or ``x= y= z=``), checked finite."""
    try:
        if element.get("value") is not None:
            parts = [float(p) for p in element.get("value").replace(",", " ").split()]
        else:
            parts = [float(element.get(c, "0")) for c in "xyz"]
        if len(parts) != 3:
            raise ValueError
    except ValueError:
        name = element.get("name")
        unit = "deg/s" if name == ANGULAR_VELOCITY else "m/s"
        raise ParameterError(f"{where}: {name} must be three numbers in {unit}, as <vector name=\"{name}\" "
                             f"value=\"10, 0, 0\"/>") from None
    return tuple(parts)


def xml_velocities(root: ET.Element, label: str) -> dict[str, dict[str, tuple[float, float, float]]]:
    """The motions of the top-level ``<shape>`` elements of a scene's XML tree ``root``, by shape
    id: ``{"velocity": v, "angular_velocity": w}`` with the vectors given, each
    ``<vector name="velocity">`` and ``<vector name="angular_velocity">`` removed from the tree
    (Mitsuba's plugins do not know them). Raises ParameterError for a moving shape without an id,
    or a value that is not three numbers."""
    found = {}
    for index, shape in enumerate(root.findall("shape")):
        for name in (VELOCITY, ANGULAR_VELOCITY):
            for element in shape.findall(f"vector[@name='{name}']"):
                where = f"scene {label!r}, shape #{index} ({shape.get('id', 'no id')})"
                if not shape.get("id"):
                    raise ParameterError(f"{where}: a shape with a {name} needs an id (<shape type=... "
                                         "id=\"car1\">), by which the tracer follows it")
                found.setdefault(shape.get("id"), {})[name] = _vector(element, where)
                shape.remove(element)
    return found


def file_velocities(path: Path) -> dict[str, dict[str, tuple[float, float, float]]]:
    """:func:`xml_velocities` of the XML file ``path`` ({} when it cannot be parsed: Mitsuba's load
    then says why)."""
    try:
        return xml_velocities(ET.parse(path).getroot(), str(path))
    except (ET.ParseError, OSError):
        return {}


def _vectors(shape_id: str, value: Any, label: str) -> tuple[np.ndarray, np.ndarray]:
    """``(velocity m/s, angular velocity deg/s)`` of one ``velocities`` entry: 3 floats, or a
    mapping with ``velocity`` and/or ``angular_velocity``; ParameterError when not finite."""
    parts = dict(value) if isinstance(value, Mapping) else {VELOCITY: value}
    unknown = set(parts) - {VELOCITY, ANGULAR_VELOCITY}
    if unknown:
        raise ParameterError(f"scene {label!r}, shape {shape_id!r}: unknown motion {sorted(unknown)[0]!r}; give "
                             f"{VELOCITY!r} [m/s] and/or {ANGULAR_VELOCITY!r} [deg/s]")
    out = []
    for name, unit in ((VELOCITY, "m/s"), (ANGULAR_VELOCITY, "deg/s")):
        given = parts.get(name, (0.0, 0.0, 0.0))
        try:
            v = np.asarray(given, np.float64).reshape(-1)
        except (TypeError, ValueError):
            v = np.full(1, np.nan)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ParameterError(f"scene {label!r}, shape {shape_id!r}: {name} {given!r} must be three finite "
                                 f"numbers in {unit}")
        out.append(v)
    return out[0], out[1]


def moving_shapes(scene: Any, velocities: Mapping[str, Any], params: Any, label: str) -> ShapeMotion | None:
    """The :class:`ShapeMotion` of a loaded ``scene`` (``mitsuba.Scene``) from ``velocities``
    (shape id -> 3 floats [m/s], or ``{"velocity": v, "angular_velocity": w}`` with ``w`` in
    deg/s); None when none is given or every one is zero (a still scene pays nothing).

    Raises
    ------
    ParameterError
        A velocity that is not finite; an id no shape has; a moving shape that is not a triangle
        mesh (a sphere: nothing for the tracer to move); a moving shape whose material is
        rough (its scatterers would have to move with it: not simulated); ``sbr lit_regions``
        other than ``patches`` (the ray tubes do not follow moving shapes).
    """
    shapes = list(scene.shapes())
    ids = [shape.id() for shape in shapes]
    rows = []
    for shape_id, value in velocities.items():
        v, w = _vectors(shape_id, value, label)
        if shape_id not in ids:
            raise ParameterError(f"scene {label!r}: velocity given for shape {shape_id!r}, which the scene does not "
                                 f"have (its shapes: {', '.join(ids[:8])}{', ...' if len(ids) > 8 else ''})")
        if np.any(v != 0) or np.any(w != 0):
            rows.append((ids.index(shape_id), shape_id, tuple(map(float, v)), tuple(map(float, w))))
    if not rows:
        return None
    centres, radii = [], []
    for index, shape_id, _, _ in sorted(rows):
        if not shapes[index].is_mesh():
            raise ParameterError(f"scene {label!r}, shape {shape_id!r}: a moving shape must be a triangle mesh "
                                 "(obj, ply, rectangle, cube or a Python mesh), not a sphere, disk or cylinder: "
                                 "give it as a mesh, or give it no velocity")
        clutter = getattr(shapes[index].bsdf(), "clutter", (0, 0))
        if clutter[0] > 0:
            raise ParameterError(f"scene {label!r}, shape {shape_id!r}: a moving shape's material must be smooth "
                                 "(its rough clutter's scatterers do not move with it): remove its gamma_db, "
                                 "rms_height or scattering_coefficient, or give it no velocity")
        box = shapes[index].bbox()
        lo, hi = np.array(box.min, np.float64), np.array(box.max, np.float64)
        centres.append(tuple(map(float, 0.5 * (lo + hi))))
        radii.append(float(0.5 * np.linalg.norm(hi - lo)))
    rows.sort()
    duration = max(params.n_pulses - 1, 0) / params.prf
    return ShapeMotion(ids=tuple(r[1] for r in rows), shapes=tuple(r[0] for r in rows),
                       velocity=tuple(r[2] for r in rows), duration=duration,
                       angular_velocity=tuple(r[3] for r in rows), centre=tuple(centres), radius=tuple(radii))


def swept_box(motion: ShapeMotion, boxes: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
    """The scene's bounding box ``(lo, hi)`` (float64 [3] each, m) with each moving shape's path
    across the aperture, ``box +- v duration / 2`` (a turning shape's box: the sphere about its
    centre through its farthest vertex; docs/physics.md (V1)); ``boxes`` float64 [n_shapes, 2, 3]
    are the shapes' own boxes.

    Raises ParameterError when a moving shape that stands within the box of the still shapes
    (horizontally, a car on its ground) leaves it during the aperture, naming the parameter that
    moves it (``velocity``, with the largest speed along the same direction that stays,
    :func:`_staying_speed`, or ``angular_velocity``). A shape that stands beyond the still ones (a
    target alone, or the ground itself turning) is not refused: the box returned holds its path.
    """
    still = np.setdiff1d(np.arange(len(boxes)), motion.shapes)
    half = 0.5 * motion.duration * motion.velocities()
    turning = np.any(motion.angular_velocities() != 0, axis=1)
    # a shape that turns may point any way: its sphere about its centre
    own = [np.array([np.asarray(c) - r, np.asarray(c) + r]) if t else boxes[k]
           for k, c, r, t in zip(motion.shapes, motion.centre, motion.radius, turning)]
    lo = [box[0] - np.abs(h) for box, h in zip(own, half)]
    hi = [box[1] + np.abs(h) for box, h in zip(own, half)]
    if len(still):
        s_lo, s_hi = boxes[still, 0].min(axis=0), boxes[still, 1].max(axis=0)
        for shape_id, k, a, b, v, t in zip(motion.ids, motion.shapes, lo, hi, motion.velocities(), turning):
            if np.any(boxes[k, 0, :2] < s_lo[:2] - 1e-6) or np.any(boxes[k, 1, :2] > s_hi[:2] + 1e-6):
                continue                     # it stands beyond the still shapes: its own path is planned below
            outside = max(float(np.max(s_lo[:2] - a[:2])), float(np.max(b[:2] - s_hi[:2])))
            if outside > 1e-6:
                w = np.degrees(motion.angular_velocities()[list(motion.ids).index(shape_id)])
                fix = f"angular_velocity {np.round(w, 9).tolist()} deg/s turns it" if t else \
                    f"velocity {v.tolist()} m/s takes it"
                room = np.minimum(boxes[k, 0, :2] - s_lo[:2], s_hi[:2] - boxes[k, 1, :2])
                allowed, edge = _staying_speed(v, room, motion.duration)
                if t:
                    hint = "give a slower turn, fewer pulses, or a larger ground"
                elif allowed > 0:
                    hint = f"give a speed below about {allowed:.3g} m/s, fewer pulses, or a larger ground"
                else:              # flush with the still shapes' edge along its motion: any speed leaves
                    hint = (f"it stands at the still shapes' edge along {edge} already: give it a velocity "
                            f"without an {edge} part, or a larger ground")
                raise ParameterError(
                    f"scene {label!r}, shape {shape_id!r}: {fix} {outside:.3g} m beyond the still shapes around it "
                    f"during the aperture ({motion.duration:.4g} s): {hint}")
        lo.append(s_lo)
        hi.append(s_hi)
    return np.min(lo, axis=0), np.max(hi, axis=0)


def _staying_speed(velocity: np.ndarray, room: np.ndarray, duration: float) -> tuple[float, str]:
    """The largest speed [m/s] along ``velocity``'s horizontal direction at which a shape stays
    within the still shapes around it, rounded down to 3 significant digits (so that the speed
    named stays), and the axis (``"x"`` or ``"y"``) that limits it. ``room`` float64 [2]: the
    shape's margin to the still shapes' box on each horizontal axis, m (the smaller of its two
    sides: it moves ``+- v duration / 2`` about where it stands, (V1)). Along a unit direction
    ``u`` it stays while ``|u_a| s duration / 2 <= room_a`` on both axes, so
    ``s = min_a 2 room_a / (duration |u_a|)``; 0 where the shape is flush with an edge it moves
    toward."""
    horizontal = np.asarray(velocity, np.float64)[:2]
    u = np.abs(horizontal) / max(float(np.linalg.norm(horizontal)), 1e-300)
    limits = [(2.0 * max(float(r), 0.0) / (max(duration, 1e-300) * float(c)), axis)
              for r, c, axis in zip(room, u, "xy") if c > 1e-12]
    speed, axis = min(limits) if limits else (math.inf, "x")
    if not math.isfinite(speed) or speed < 1e-9:
        return (0.0 if math.isfinite(speed) else speed), axis
    digits = 10.0 ** (math.floor(math.log10(speed)) - 2)
    return math.floor(speed / digits) * digits, axis
