"""Closed building meshes from outlines in the local frame: walls, roof (flat, gabled, hipped,
pyramidal) and floor.

:func:`building_mesh` is the extruder of :mod:`sarmitsuba.scene.city`. A pitched roof is built on
the outline's minimum rotated rectangle (shapely): its ridge runs along the rectangle's longer side
(``across``: the shorter) at ``roof_height`` above the eaves, and the roof is the lowest of its
planes (docs/physics.md (FP2))::

    gabled     z = e + h (1 - |v| / W)
    hipped     z = e + h min(1 - |v| / W, (A - |u|) / W)
    pyramidal  z = e + h min(1 - |v| / W, 1 - |u| / A)                                          (FP2)

with ``u``, ``v`` the offsets along and across the ridge from the rectangle's centre, ``A``, ``W``
its half-length and half-width, ``e`` the eaves' height. Each plane's part of the outline is cut out
with shapely and triangulated (trimesh's ``triangulate_polygon``, mapbox-earcut); walls stand on
every outline edge, holes included, from ``base`` to the roof above the edge, so a gable end
reaches its ridge. The mesh is closed (a floor at ``base``) and its normals point out.

:func:`flat_building_mesh` is the readable reference for flat roofs: trimesh's
``extrude_polygon``, which the tests compare the extruder with.
"""
from __future__ import annotations

import numpy as np
import trimesh

__all__ = ["building_mesh", "building_parts", "flat_building_mesh", "roof_planes", "roof_height_at"]

#: Shared vertices are merged to 1e-6 m (pieces cut from one outline meet to rounding).
_MERGE_DIGITS = 6


def roof_planes(polygon, shape: str, roof_height: float, across: bool = False) -> np.ndarray:
    """float64 [k, 3]: planes ``z - e = a x + b y + c`` of a roof over ``polygon`` (FP2); the roof is
    their minimum. ``[[0, 0, 0]]`` for a flat roof or ``roof_height`` 0.

    Parameters
    ----------
    polygon : shapely Polygon or MultiPolygon
        The outline in local metres.
    shape : {"flat", "gabled", "hipped", "pyramidal"}
    roof_height : float, m
        Eaves to ridge.
    across : bool
        Ridge across the rectangle's longer side.
    """
    if shape == "flat" or roof_height == 0.0:
        return np.zeros((1, 3))
    rect = np.asarray(polygon.minimum_rotated_rectangle.exterior.coords)[:4]
    centre = rect.mean(axis=0)
    sides = (rect[1] - rect[0], rect[2] - rect[1])
    lengths = np.array([np.linalg.norm(s) for s in sides])
    ridge = int(np.argmax(lengths)) if not across else int(np.argmin(lengths))
    e_u, e_v = sides[ridge] / lengths[ridge], sides[1 - ridge] / lengths[1 - ridge]
    a, w = 0.5 * lengths[ridge], 0.5 * lengths[1 - ridge]
    # each plane as h * (k0 + ku u + kv v) in the rectangle's (u, v)
    coefficients = [(1.0, 0.0, -1.0 / w), (1.0, 0.0, 1.0 / w)]
    if shape == "hipped":
        coefficients += [(a / w, -1.0 / w, 0.0), (a / w, 1.0 / w, 0.0)]
    elif shape == "pyramidal":
        coefficients += [(1.0, -1.0 / a, 0.0), (1.0, 1.0 / a, 0.0)]
    planes = []
    for k0, ku, kv in coefficients:
        gradient = ku * e_u + kv * e_v
        planes.append((*(roof_height * gradient), roof_height * (k0 - gradient @ centre)))
    return np.array(planes)


def roof_height_at(planes: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Roof height above the eaves [m] at points ``xy`` float64 [n, 2]: the lowest plane (FP2)."""
    xy = np.atleast_2d(xy)
    return np.min(xy @ planes[:, :2].T + planes[:, 2], axis=1)


def _half_plane(plane: np.ndarray, bounds: tuple, sign: float = 1.0):
    """shapely Polygon of ``sign (a x + b y + c) <= 0`` over a box 10 times ``bounds`` (x0, y0, x1, y1)."""
    from shapely.geometry import Polygon
    normal, offset = sign * plane[:2], sign * plane[2]
    norm = float(np.linalg.norm(normal))
    normal, offset = normal / norm, offset / norm
    middle = 0.5 * np.array([bounds[0] + bounds[2], bounds[1] + bounds[3]])
    size = 10.0 * (np.hypot(bounds[2] - bounds[0], bounds[3] - bounds[1]) + 1.0)
    foot = middle - (normal @ middle + offset) * normal           # on the line
    along = np.array([-normal[1], normal[0]])
    return Polygon([foot - size * along, foot + size * along, foot + size * along - size * normal,
                    foot - size * along - size * normal])


def _pieces(polygon, planes: np.ndarray) -> list:
    """(plane index, shapely Polygon) parts of ``polygon`` where each plane is the lowest."""
    from shapely.geometry.polygon import orient
    if len(planes) == 1:
        return [(0, orient(p, 1.0)) for p in getattr(polygon, "geoms", [polygon])]
    pieces = []
    for k, plane in enumerate(planes):
        region = polygon
        for j, other in enumerate(planes):
            difference = plane - other
            if j != k and np.linalg.norm(difference[:2]) > 0.0:
                region = region.intersection(_half_plane(difference, polygon.bounds))
        for part in getattr(region, "geoms", [region]):
            if part.geom_type == "Polygon" and part.area > 1e-9:
                pieces.append((k, orient(part, 1.0)))
    return pieces


def _cap(piece, z_of) -> tuple[np.ndarray, np.ndarray]:
    """Triangulated ``piece`` lifted to ``z_of(xy)``: (vertices [n, 3], faces [m, 3]) wound with +z normals."""
    xy, faces = trimesh.creation.triangulate_polygon(piece)
    xy = np.asarray(xy, np.float64)
    faces = np.asarray(faces, np.int64)
    edge1, edge2 = xy[faces[:, 1]] - xy[faces[:, 0]], xy[faces[:, 2]] - xy[faces[:, 0]]
    flip = edge1[:, 0] * edge2[:, 1] - edge1[:, 1] * edge2[:, 0] < 0.0
    faces[flip] = faces[flip][:, ::-1]
    return np.column_stack([xy, z_of(xy)]), faces


def _walls(piece, outline, base: float, top) -> tuple[np.ndarray, np.ndarray]:
    """Wall quads under the edges of ``piece`` (oriented: interior on the left) that lie on the
    boundary of ``outline``, from ``base`` up to ``top(xy)``; normals point out (to the right)."""
    import shapely
    rings = [piece.exterior, *piece.interiors]
    starts = np.vstack([np.asarray(r.coords)[:-1] for r in rings])
    ends = np.vstack([np.asarray(r.coords)[1:] for r in rings])
    middle = shapely.points(0.5 * (starts + ends))
    scale = 1e-7 * max(1.0, float(np.abs(np.asarray(outline.bounds)).max()))
    on_boundary = shapely.distance(outline.boundary, middle) <= scale
    starts, ends = starts[on_boundary], ends[on_boundary]
    n = len(starts)
    corners = np.concatenate([np.column_stack([starts, np.full(n, base)]), np.column_stack([ends, np.full(n, base)]),
                              np.column_stack([ends, top(ends)]), np.column_stack([starts, top(starts)])])
    i = np.arange(n)
    faces = np.concatenate([np.column_stack([i, i + n, i + 2 * n]), np.column_stack([i, i + 2 * n, i + 3 * n])])
    return corners, faces


def building_mesh(polygon, base: float, eaves: float, roof_shape: str = "flat", roof_height: float = 0.0,
                  across: bool = False) -> trimesh.Trimesh:
    """Closed mesh of one building (module docstring).

    Parameters
    ----------
    polygon : shapely Polygon or MultiPolygon
        Valid outline in local metres (x east, y north), holes allowed.
    base : float, m
        Height of the floor (walls start here).
    eaves : float, m
        Height of the roof's eaves (of a flat roof: the roof), above ``base``.
    roof_shape, roof_height, across
        As :func:`roof_planes`.

    Returns
    -------
    trimesh.Trimesh
        Float64 vertices [n, 3] in m, faces [m, 3], outward normals, watertight.

    Raises
    ------
    ValueError
        ``eaves`` not above ``base``.
    """
    if not eaves > base:
        raise ValueError(f"eaves {eaves:g} m must lie above the base {base:g} m")
    planes = roof_planes(polygon, roof_shape, roof_height, across)

    def top(xy):
        return eaves + roof_height_at(planes, xy)

    parts = []
    for k, piece in _pieces(polygon, planes):
        floor = _cap(piece, lambda xy: np.full(len(xy), base))
        parts += [_cap(piece, lambda xy, k=k: eaves + xy @ planes[k, :2] + planes[k, 2]),
                  (floor[0], floor[1][:, ::-1]), _walls(piece, polygon, base, top)]     # the floor faces down
    return _joined(parts)


def _joined(parts: list) -> trimesh.Trimesh:
    """One mesh of ``(vertices, faces)`` pieces: shared vertices merged (to :data:`_MERGE_DIGITS`),
    degenerate faces and unused vertices dropped."""
    vertices, faces, count = [], [], 0
    for v, f in parts:
        vertices.append(v)
        faces.append(f + count)
        count += len(v)
    mesh = trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=False)
    mesh.merge_vertices(digits_vertex=_MERGE_DIGITS)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def building_parts(polygon, base: float, eaves: float, roof_shape: str = "flat", roof_height: float = 0.0,
                   across: bool = False, ground: float | None = None, facade=None, key: str = "") -> dict:
    """One building as the meshes of its parts, so that each is one surface to a radar
    (:mod:`sarmitsuba.scene.roles`): ``"roof"`` (the roof's planes), ``"walls"`` (the walls and
    the floor; with ``facade``, their window recesses and balconies) and, with ``facade``,
    ``"windows"`` (the panes). Together they close the building as :func:`building_mesh` does
    (balconies stand on the wall).

    Parameters
    ----------
    polygon, base, eaves, roof_shape, roof_height, across
        As :func:`building_mesh`.
    ground : float, m, optional
        Height of the ground the storeys count from (default ``base``).
    facade : sarmitsuba.scene.facades.FacadeLayout, optional
        Windows and balconies (:func:`sarmitsuba.scene.facades.wall_with_windows`); None: plain walls.
    key : str
        The building's name: seeds its balconies.

    Returns
    -------
    dict of str -> trimesh.Trimesh
        Float64 vertices, outward normals; ``"windows"`` only where a window fits.
    """
    from .facades import wall_with_windows
    if not eaves > base:
        raise ValueError(f"eaves {eaves:g} m must lie above the base {base:g} m")
    planes = roof_planes(polygon, roof_shape, roof_height, across)

    def top(xy):
        return eaves + roof_height_at(planes, xy)

    groups: dict = {"roof": [], "walls": [], "windows": []}
    for k, piece in _pieces(polygon, planes):
        roof = _cap(piece, lambda xy, k=k: eaves + xy @ planes[k, :2] + planes[k, 2])
        floor = _cap(piece, lambda xy: np.full(len(xy), base))
        groups["roof"].append(roof)
        groups["walls"].append((floor[0], floor[1][:, ::-1]))          # the floor faces down
        corners, faces = _walls(piece, polygon, base, top)
        if facade is None:
            groups["walls"].append((corners, faces))
            continue
        n = len(corners) // 4
        for i in range(n):
            a, b = corners[i, :2], corners[i + n, :2]
            wall_v, wall_f, pane_v, pane_f = wall_with_windows(
                a, b, base, corners[i + 3 * n, 2], corners[i + 2 * n, 2], base if ground is None else ground,
                eaves, facade, f"{key}/{k}/{i}")
            groups["walls"].append((wall_v, wall_f))
            if len(pane_f):
                groups["windows"].append((pane_v, pane_f))
    return {name: _joined(parts) for name, parts in groups.items() if parts}


def flat_building_mesh(polygon, base: float, height: float) -> trimesh.Trimesh:
    """Reference flat-roofed building: trimesh's ``extrude_polygon`` of each part, moved to ``base``."""
    meshes = []
    for part in getattr(polygon, "geoms", [polygon]):
        mesh = trimesh.creation.extrude_polygon(part, height)
        mesh.apply_translation((0.0, 0.0, base))
        meshes.append(mesh)
    return trimesh.util.concatenate(meshes)
