"""Facades with windows and balconies as geometry: the regular grid of corner reflectors that the
walls of real cities show in X-band images (the persistent scatterers of PSI and TomoSAR studies of
buildings).

A wall of length ``L`` between the ground ``g`` and the eaves ``e`` is cut into floors of
``floor_height`` and bays of ``window_spacing`` (centred on the wall). Each bay of each floor gets a
window ``window_width`` x ``window_height`` whose sill lies ``sill_height`` above the floor,
where it fits whole with :data:`EDGE_MARGIN` of wall around it. A window is a rectangular hole
in the wall and a recess ``recess_depth`` deep behind it: the sill (facing up), the head (facing
down), two reveals (facing each other) and the pane at the back (facing out, a separate
shape of glass). Seen across the wall, the pane and the sill form a dihedral whose
double bounce returns from every incidence whose ray enters the recess: its RCS is
``4 pi (w 2 d cos(theta))^2 / lambda^2`` while ``2 d cot(theta)`` is below the window's height
(docs/physics.md (FA1)).

A seeded share ``balcony_share`` of the bays of the upper floors gets a balcony: a slab
``balcony_depth`` deep and :data:`BALCONY_THICKNESS` thick, a bay wide less
:data:`EDGE_MARGIN` each side, whose floor is the storey's floor. Its top and the wall above
it form another dihedral. The same ``seed`` and wall give the same balconies.

:func:`wall_with_windows` builds one wall; :class:`FacadeLayout` holds the settings and checks
them.
"""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, fields

import numpy as np

__all__ = ["FacadeLayout", "wall_with_windows", "wall_rectangles", "add_windows", "EDGE_MARGIN", "BALCONY_THICKNESS",
           "FacadeError"]

#: m: wall left around every window (to the wall's ends, its foot and its eaves) and beside balconies.
EDGE_MARGIN = 0.3
#: m: thickness of a balcony slab.
BALCONY_THICKNESS = 0.2


class FacadeError(ValueError):
    """A facade setting outside its valid range (the message names it, its range and the fix)."""


#: (name, low, high, unit): the valid range of each setting.
_RANGES = {"floor_height": (2.0, 10.0, "m"), "window_width": (0.3, 10.0, "m"), "window_height": (0.3, 8.0, "m"),
           "window_spacing": (0.6, 50.0, "m"), "sill_height": (0.0, 5.0, "m"), "recess_depth": (0.01, 2.0, "m"),
           "balcony_share": (0.0, 1.0, ""), "balcony_depth": (0.3, 5.0, "m")}


@dataclass(frozen=True)
class FacadeLayout:
    """Windows and balconies of every facade (module docstring). Lengths in metres.

    Defaults: an apartment block's 3 m storeys, 1.2 m x 1.5 m windows every 3 m with their sills
    0.9 m above the floor, recessed 0.15 m (assumptions: typical of European masonry; the
    user sets them); no balconies.

    Raises
    ------
    FacadeError
        A setting outside its range, a window wider than its bay, or taller than its storey.
    """

    floor_height: float = 3.0
    window_width: float = 1.2
    window_height: float = 1.5
    window_spacing: float = 3.0
    sill_height: float = 0.9
    recess_depth: float = 0.15
    balcony_share: float = 0.0
    balcony_depth: float = 1.2
    seed: int = 0

    def __post_init__(self):
        for f in fields(self):
            if f.name == "seed":
                if not isinstance(self.seed, (int, np.integer)) or isinstance(self.seed, bool) or self.seed < 0:
                    raise FacadeError(f"facade seed = {self.seed!r} must be a whole number >= 0")
                continue
            low, high, unit = _RANGES[f.name]
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and low <= value <= high):
                raise FacadeError(f"facade {f.name} = {value!r} is outside [{low:g}, {high:g}] {unit}".rstrip())
        if self.window_width + 2 * EDGE_MARGIN > self.window_spacing:
            raise FacadeError(f"facade window_width = {self.window_width:g} m does not fit its bay: window_spacing "
                              f"{self.window_spacing:g} m must exceed it by {2 * EDGE_MARGIN:g} m; widen the spacing")
        if self.sill_height + self.window_height + EDGE_MARGIN > self.floor_height:
            raise FacadeError(f"facade sill_height + window_height = {self.sill_height + self.window_height:g} m "
                              f"does not fit a {self.floor_height:g} m storey with {EDGE_MARGIN:g} m above; "
                              "lower the window or raise floor_height")

    @classmethod
    def from_mapping(cls, values) -> "FacadeLayout":
        """A layout from ``{"floor_height": "3.2", ...}`` (strings or numbers); FacadeError names an
        unknown key."""
        known = {f.name: f.type for f in fields(cls)}
        out = {}
        for key, value in dict(values).items():
            if key not in known:
                raise FacadeError(f"unknown facade setting {key!r}; valid: {', '.join(known)}")
            try:
                out[key] = int(value) if key == "seed" else float(value)
            except (TypeError, ValueError):
                raise FacadeError(f"facade {key} = {value!r} is not a number") from None
        return cls(**out)


def _quad(corners: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two triangles of the planar quad ``corners`` [4, 3] (in order around it), wound so that
    their normal points along ``normal``."""
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    if np.cross(corners[1] - corners[0], corners[2] - corners[0]) @ normal < 0:
        faces = faces[:, ::-1]
    return corners, faces


def _box_faces(corners: list, normals: list) -> tuple[np.ndarray, np.ndarray]:
    vertices, faces = [], []
    for quad, normal in zip(corners, normals):
        v, f = _quad(np.asarray(quad, np.float64), np.asarray(normal, np.float64))
        faces.append(f + 4 * len(vertices))
        vertices.append(v)
    return np.vstack(vertices), np.vstack(faces)


def wall_with_windows(start, end, base: float, top_start: float, top_end: float, ground: float, eaves: float,
                      layout: FacadeLayout, key: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One wall from ``start`` to ``end`` (x, y in m; the building's interior on the left, so the
    wall faces right) between ``base`` and its top (``top_start`` at ``start``, ``top_end`` at
    ``end``), with the windows and balconies of ``layout`` between ``ground`` and ``eaves``.

    ``key`` (the building's and edge's name) seeds the balconies with ``layout.seed``.

    Returns
    -------
    wall_vertices float64 [n, 3], wall_faces int64 [m, 3], pane_vertices float64 [k, 3], pane_faces int64 [j, 3]
        The wall (with its recesses and balconies) and the panes, normals facing out.
    """
    import shapely
    import trimesh
    p0, p1 = np.asarray(start, np.float64), np.asarray(end, np.float64)
    length = float(np.linalg.norm(p1 - p0))
    along = (p1 - p0) / length
    out = np.array([along[1], -along[0], 0.0])          # to the right of the edge: out of the building
    t3 = np.array([along[0], along[1], 0.0])
    up = np.array([0.0, 0.0, 1.0])

    def world(u, z, depth=0.0):
        return np.array([p0[0], p0[1], 0.0]) + u * t3 + z * up - depth * out

    w, h, d = layout.window_width, layout.window_height, layout.recess_depth
    n_bays = max(0, int((length - 2 * EDGE_MARGIN + layout.window_spacing - w) // layout.window_spacing))
    centres = length / 2 + (np.arange(n_bays) - (n_bays - 1) / 2) * layout.window_spacing
    n_floors = int(max(0.0, eaves - ground) // layout.floor_height)
    limit = min(eaves, top_start, top_end) - EDGE_MARGIN
    holes = []
    for floor in range(n_floors):
        z0 = ground + floor * layout.floor_height + layout.sill_height
        if z0 - EDGE_MARGIN < base or z0 + h > limit:
            continue
        holes += [(c - w / 2, z0, c + w / 2, z0 + h) for c in centres]
    outline = shapely.Polygon([(0.0, base), (length, base), (length, top_end), (0.0, top_start)],
                              holes=[[(a, b), (c, b), (c, e), (a, e)] for a, b, c, e in holes])
    uv, tri = trimesh.creation.triangulate_polygon(outline)
    uv, tri = np.asarray(uv, np.float64), np.asarray(tri, np.int64)
    e1, e2 = uv[tri[:, 1]] - uv[tri[:, 0]], uv[tri[:, 2]] - uv[tri[:, 0]]
    flip = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0.0       # counter-clockwise in (u, z): facing out
    tri[flip] = tri[flip][:, ::-1]
    vertices = [np.array([world(u, z) for u, z in uv])]
    faces = [tri]
    count = len(vertices[0])
    panes_v, panes_f = [], []
    for a, b, c, e in holes:
        quads = [[world(a, b), world(c, b), world(c, b, d), world(a, b, d)],       # sill, facing up
                 [world(a, e), world(c, e), world(c, e, d), world(a, e, d)],       # head, facing down
                 [world(a, b), world(a, e), world(a, e, d), world(a, b, d)],       # reveal at a, facing +u
                 [world(c, b), world(c, e), world(c, e, d), world(c, b, d)]]       # reveal at c, facing -u
        v, f = _box_faces(quads, [up, -up, t3, -t3])
        vertices.append(v)
        faces.append(f + count)
        count += len(v)
        v, f = _quad(np.array([world(a, b, d), world(c, b, d), world(c, e, d), world(a, e, d)]), out)
        panes_f.append(f + 4 * len(panes_v))
        panes_v.append(v)
    if layout.balcony_share > 0 and n_floors > 1:
        rng = np.random.default_rng([layout.seed, zlib.crc32(key.encode())])
        draws = rng.random((n_floors, n_bays))
        half = layout.window_spacing / 2 - EDGE_MARGIN
        for floor in range(1, n_floors):
            zf = ground + floor * layout.floor_height
            if zf - BALCONY_THICKNESS < base or zf > limit:
                continue
            for bay in np.flatnonzero(draws[floor] < layout.balcony_share):
                a, c, b, e, depth = centres[bay] - half, centres[bay] + half, zf - BALCONY_THICKNESS, zf, -layout.balcony_depth
                quads = [[world(a, e), world(c, e), world(c, e, depth), world(a, e, depth)],      # top
                         [world(a, b), world(c, b), world(c, b, depth), world(a, b, depth)],      # underside
                         [world(a, b, depth), world(c, b, depth), world(c, e, depth), world(a, e, depth)],  # front
                         [world(a, b), world(a, e), world(a, e, depth), world(a, b, depth)],      # side at a
                         [world(c, b), world(c, e), world(c, e, depth), world(c, b, depth)]]      # side at c
                v, f = _box_faces(quads, [up, -up, out, -t3, t3])
                vertices.append(v)
                faces.append(f + count)
                count += len(v)
    pane_v = np.vstack(panes_v) if panes_v else np.zeros((0, 3))
    pane_f = np.vstack(panes_f) if panes_f else np.zeros((0, 3), np.int64)
    return np.vstack(vertices), np.vstack(faces), pane_v, pane_f


def wall_rectangles(vertices: np.ndarray, faces: np.ndarray) -> list:
    """The plain walls of a mesh: pairs of coplanar vertical triangles (normal within
    :data:`sarmitsuba.scene.roles.STEEP_DEG` of horizontal) that share an edge and make a rectangle
    with a horizontal bottom and top, as extruded city models build their walls.

    Returns
    -------
    list of (i, j, start, end, bottom, top)
        The two triangles' indices, and the wall from ``start`` to ``end`` (x, y; the wall faces
        to their right, as :func:`wall_with_windows` takes it) between heights ``bottom`` and ``top``.
    """
    from .roles import face_normals, steep
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if len(f) == 0:
        return []
    normal = face_normals(v, f)[0]
    upright = steep(normal)
    scale = max(1.0, float(np.abs(v).max()))
    key = np.round(v / (1e-6 * scale)).astype(np.int64)          # vertices equal to rounding
    _, vid = np.unique(key, axis=0, return_inverse=True)
    vid = vid.ravel()
    edges: dict = {}
    for t in np.flatnonzero(upright):
        for a, b in ((0, 1), (1, 2), (2, 0)):
            edges.setdefault(tuple(sorted((vid[f[t, a]], vid[f[t, b]]))), []).append(t)
    out, used = [], set()
    tolerance = 1e-4 * scale
    for pair in edges.values():
        if len(pair) != 2 or pair[0] in used or pair[1] in used:
            continue
        i, j = pair
        if normal[i] @ normal[j] < 1.0 - 1e-6:
            continue
        corners = {vid[x]: v[x] for x in np.concatenate([f[i], f[j]])}
        if len(corners) != 4:
            continue
        p = np.array(list(corners.values()))
        low = p[:, 2] < p[:, 2].min() + tolerance
        high = p[:, 2] > p[:, 2].max() - tolerance
        if low.sum() != 2 or high.sum() != 2 or np.any(low & high):
            continue
        bottom, top = p[low], p[high]
        if not np.allclose(np.sort(bottom[:, :2], axis=0), np.sort(top[:, :2], axis=0), atol=tolerance):
            continue
        a, b = bottom[0, :2], bottom[1, :2]
        right = np.array([b[1] - a[1], a[0] - b[0]])               # to the right of a -> b
        if right @ normal[i, :2] < 0:
            a, b = b, a
        used |= {i, j}
        out.append((i, j, a, b, float(bottom[0, 2]), float(top[0, 2])))
    return out


def add_windows(vertices: np.ndarray, faces: np.ndarray, layout: FacadeLayout, key: str = ""):
    """A mesh with windows in its plain walls (:func:`wall_rectangles`): each such wall's two
    triangles replaced by :func:`wall_with_windows` from its bottom (the ground its storeys count
    from) to its top; other faces kept as they are.

    Returns
    -------
    vertices float64 [n, 3], faces int64 [m, 3], pane_vertices float64 [k, 3], pane_faces int64 [j, 3], windows int
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    walls = wall_rectangles(v, f)
    keep = np.ones(len(f), bool)
    parts_v, parts_f, panes_v, panes_f = [v], [f], [], []
    count, pane_count, windows = len(v), 0, 0
    for n, (i, j, a, b, bottom, top) in enumerate(walls):
        wall_v, wall_f, pane_v, pane_f = wall_with_windows(a, b, bottom, top, top, bottom, top, layout, f"{key}/{n}")
        if not len(pane_f):
            continue                                               # no window fits: the wall as it was
        keep[[i, j]] = False
        parts_v.append(wall_v)
        parts_f.append(wall_f + count)
        count += len(wall_v)
        panes_v.append(pane_v)
        panes_f.append(pane_f + pane_count)
        pane_count += len(pane_v)
        windows += len(pane_f) // 2
    parts_f[0] = f[keep]
    pane_v = np.vstack(panes_v) if panes_v else np.zeros((0, 3))
    pane_f = np.vstack(panes_f) if panes_f else np.zeros((0, 3), np.int64)
    return np.vstack(parts_v), np.vstack(parts_f), pane_v, pane_f, windows
