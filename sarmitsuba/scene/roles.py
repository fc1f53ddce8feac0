"""What each surface of a scene is to a radar: a roof, a facade, the ground, or an underside.

A roughness preset (:mod:`.rough_presets`) gives a surface by its role as well as by its ITU
class, because a city model's class labels often say little about the surface: Sionna RT's
city scenes label every roof ``itu_metal`` whatever covers it. The rules (docs/physics.md (RS8)):

==============  ==================================================================================
``facade``      steep: the face's normal lies within :data:`STEEP_DEG` (20 deg) of horizontal
``roof``        facing up (slope under 70 deg) with other geometry at least
                :data:`ROOF_MIN_HEIGHT` (2 m) straight below its centre
``ground``      facing up with nothing below, or less than that height above what is below
``underside``   facing down (a balcony's or an overhang's soffit)
==============  ==================================================================================

A face's role comes from its normal and one ray cast straight down from just below its
centre. A shape takes the role that holds most of its area (:func:`shape_roles`), because the
tracer's materials are per shape; a shape whose faces disagree is reported with the share of
its area that takes another role. A shape that is not a mesh (an analytic sphere) has no role
and keeps its class's surface.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ROLES", "STEEP_DEG", "ROOF_MIN_HEIGHT", "MIXED_SHARE", "face_normals", "steep", "face_roles", "ShapeRoles",
           "shape_roles"]

#: The roles, in the order of their codes (``face_roles`` returns indices into this tuple).
ROLES = ("roof", "facade", "ground", "underside")
#: deg: a face whose normal lies within this angle of horizontal is a facade (assumption: walls
#: lean less than 20 deg; a mansard's steep slope, 70 deg and more, reads as a wall to a radar).
STEEP_DEG = 20.0
#: m: an upward face this far or farther above the geometry below it is a roof (assumption: the
#: lowest storey is taller than 2 m; kerbs, steps, low walls and parked cars are lower).
ROOF_MIN_HEIGHT = 2.0
#: A shape whose majority role holds less than this share of its area is listed as mixed.
MIXED_SHARE = 0.95
_BELOW_START = 0.01      # m: the downward ray starts this far below the face (clears the face itself)


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's unit normal ``(v1 - v0) x (v2 - v0)`` normalised (float64 [n_f, 3]; zero
    for a degenerate triangle) and its area (float64 [n_f], m^2)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    twice = np.linalg.norm(normal, axis=1)
    return np.divide(normal, twice[:, None], out=np.zeros_like(normal), where=twice[:, None] > 0), 0.5 * twice


def steep(normal: np.ndarray) -> np.ndarray:
    """bool [n]: unit normals within :data:`STEEP_DEG` of horizontal (a facade's); zero normals are not."""
    return (np.abs(normal[:, 2]) < math.sin(math.radians(STEEP_DEG))) & np.any(normal != 0, axis=1)


def face_roles(vertices: np.ndarray, faces: np.ndarray, height_below) -> np.ndarray:
    """The role of each triangle (indices into :data:`ROLES`).

    Parameters
    ----------
    vertices : float [n_v, 3], m
    faces : int [n_f, 3]
        Triangles, wound so that their normal ``(v1 - v0) x (v2 - v0)`` points out of the surface
        (the side the surface faces).
    height_below : callable
        ``height_below(points float64 [k, 3]) -> float64 [k]``: the distance straight down from
        each point to the first geometry below it [m], ``inf`` where there is none.

    Returns
    -------
    int8 [n_f]
        Degenerate triangles (no normal) are ``ground``.
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    normal, area = face_normals(v, f)
    nz = np.where(area > 0, normal[:, 2], 1.0)
    limit = math.sin(math.radians(STEEP_DEG))
    role = np.full(len(f), ROLES.index("ground"), np.int8)
    role[steep(normal)] = ROLES.index("facade")
    role[nz <= -limit] = ROLES.index("underside")
    up = np.flatnonzero(nz >= limit)
    if up.size:
        centre = v[f[up]].mean(axis=1)
        centre[:, 2] -= _BELOW_START
        below = np.asarray(height_below(centre), np.float64) + _BELOW_START
        # nothing below (inf): the ground itself, whatever its height
        role[up[np.isfinite(below) & (below >= ROOF_MIN_HEIGHT)]] = ROLES.index("roof")
    return role


@dataclass(frozen=True)
class ShapeRoles:
    """The role of each shape of a scene.

    Attributes
    ----------
    role : tuple of (str or None)
        Per shape of ``scene.shapes()``: its majority role, None for a shape that is not a mesh.
    share : float64 [n_shapes]
        The share of each shape's area that its role holds (1 for a shape without a role).
    """

    role: tuple
    share: np.ndarray

    def counts(self) -> dict[str, int]:
        """Shapes per role, e.g. ``{"roof": 1142, "facade": 1183, "ground": 1, ...}``."""
        return {r: sum(1 for x in self.role if x == r) for r in ROLES}

    def mixed(self) -> np.ndarray:
        """int64 indices of the shapes whose role holds less than :data:`MIXED_SHARE` of their area."""
        return np.flatnonzero(self.share < MIXED_SHARE)


def shape_roles(scene: Any) -> ShapeRoles:
    """The :class:`ShapeRoles` of a loaded Mitsuba scene (module docstring): the roles of every
    mesh's triangles by :func:`face_roles`, with one downward Mitsuba ray per upward triangle,
    and each shape's area-weighted majority."""
    import drjit as dr
    import mitsuba as mi

    def height_below(points: np.ndarray) -> np.ndarray:
        p = points.astype(np.float32)
        ray = mi.Ray3f(mi.Point3f(p[:, 0], p[:, 1], p[:, 2]), mi.Vector3f(0.0, 0.0, -1.0))
        t = scene.ray_intersect(ray, ray_flags=mi.RayFlags.Minimal, coherent=False).t
        dr.eval(t)
        return np.asarray(t).astype(np.float64)      # inf on a miss

    role, share = [], []
    pieces = []                                   # (shape index, vertices, faces) of every mesh
    for index, shape in enumerate(scene.shapes()):
        if shape.is_mesh() and shape.face_count() > 0:
            pieces.append((index, np.array(shape.vertex_positions_buffer(), np.float64).reshape(-1, 3),
                           np.array(shape.faces_buffer(), np.int64).reshape(-1, 3)))
        role.append(None)
        share.append(1.0)
    if pieces:                                    # one cast for every shape's triangles
        base = np.cumsum([0] + [len(v) for _, v, _ in pieces])
        vertices = np.vstack([v for _, v, _ in pieces])
        faces = np.vstack([f + b for (_, _, f), b in zip(pieces, base)])
        owner = np.repeat(np.arange(len(pieces)), [len(f) for _, _, f in pieces])
        codes = face_roles(vertices, faces, height_below)
        area = face_normals(vertices, faces)[1]
        totals = np.zeros((len(pieces), len(ROLES)))
        np.add.at(totals, (owner, codes), area)
        for k, (index, _, _) in enumerate(pieces):
            best = int(np.argmax(totals[k]))
            role[index] = ROLES[best]
            share[index] = float(totals[k, best] / totals[k].sum()) if totals[k].sum() > 0 else 1.0
    return ShapeRoles(tuple(role), np.array(share, np.float64))
