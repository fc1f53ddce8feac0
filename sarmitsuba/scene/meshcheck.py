"""Geometry checks on loaded meshes: defects are reported; a scene that cannot scatter is refused.

The tracer is robust to all of these (a zero-area triangle's undefined normal is treated as
a miss; open and non-manifold meshes simply reflect what they have); duplicate triangles and
the winding are repaired at load (:mod:`sarmitsuba.scene.meshrepair`, docs/physics.md (M0)).
They usually mean a modelling error, so :func:`warn_mesh_defects` says which shapes have which
defects and what was done. A shape
whose every triangle has zero area (collinear vertices, a flattened export) can neither scatter
nor shadow: it is missing from the image, which the warning says; when no shape of the scene can
scatter, the products would be all zero, and :func:`silent_scene` gives the loader's refusal.

:func:`check_meshes` checks all meshes of a scene at once with NumPy (Munich's 2,367 meshes in
0.1 s); :func:`check_mesh` is the readable per-mesh reference with trimesh (1.2 s for Munich),
which the tests compare it with.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import numpy as np
import trimesh

from ..core.arrays import unique_rows

__all__ = ["MeshReport", "check_meshes", "check_all", "check_mesh", "warn_mesh_defects", "MeshDefectWarning",
           "shape_label", "shape_points", "silent_scene"]

#: Triangles with area below this [m^2] count as degenerate (zero-area).
DEGENERATE_AREA = 1e-12


class MeshDefectWarning(UserWarning):
    """A mesh has degenerate, duplicated, non-manifold or inconsistently wound triangles."""


@dataclass(frozen=True)
class MeshReport:
    """Defects of one mesh.

    Attributes
    ----------
    shape : str
        Scene id of the shape.
    degenerate_faces, duplicate_faces, non_manifold_edges : int
        Zero-area triangles, triangles repeating another's vertices, edges shared by more
        than two triangles (after merging coincident vertices).
    inconsistent_winding : bool
        Neighbouring triangles disagree on orientation (normals flip across an edge).
    open : bool
        Not watertight (expected for planes and sheet-like reflectors).
    faces : int
        Number of triangles (-1: not counted).
    """

    shape: str
    degenerate_faces: int
    duplicate_faces: int
    non_manifold_edges: int
    inconsistent_winding: bool
    open: bool
    faces: int = -1

    @property
    def cannot_scatter(self) -> bool:
        """Whether every triangle has zero area (or there is none): the shape neither scatters
        nor shadows."""
        return self.faces >= 0 and self.degenerate_faces == self.faces

    @property
    def defective(self) -> bool:
        """Whether the mesh has a defect worth a warning (being open is not one)."""
        return bool(self.degenerate_faces or self.duplicate_faces or self.non_manifold_edges
                    or self.inconsistent_winding)


#: The file a Mitsuba mesh was loaded from, in its description: ``name = "flat.ply"``.
_MESH_NAME = re.compile(r'^\s*name = "(?P<name>[^"]+)"', re.M)


def shape_label(shape, index: int) -> str:
    """How messages name a Mitsuba shape: its id, else (a mesh without one) the file it was
    loaded from, else ``#shape<index>``, its place in the scene."""
    if shape.id():
        return shape.id()
    found = _MESH_NAME.search(str(shape)) if shape.is_mesh() else None
    return found["name"] if found else f"#shape{index}"


def shape_points(scene) -> list[tuple[str, np.ndarray]]:
    """Every shape's :func:`shape_label` and points, float64 [n, 3] (m): a mesh's vertices, an
    analytic shape's (sphere, disk) bounding-box corners; for the planner's geometry checks."""
    points = []
    for index, shape in enumerate(scene.shapes()):
        if shape.is_mesh():
            vertices = np.array(shape.vertex_positions_buffer(), np.float64).reshape(-1, 3)
        else:
            lo, hi = np.array(shape.bbox().min, np.float64), np.array(shape.bbox().max, np.float64)
            vertices = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        points.append((shape_label(shape, index), vertices))
    return points


def check_meshes(scene) -> list[MeshReport]:
    """Check every mesh shape of a Mitsuba scene; returns one report per mesh (scene order),
    named by :func:`shape_label`."""
    meshes = [(shape_label(shape, index), np.array(shape.vertex_positions_buffer(), np.float64).reshape(-1, 3),
               np.array(shape.faces_buffer(), np.int64).reshape(-1, 3))
              for index, shape in enumerate(scene.shapes()) if shape.is_mesh()]
    return check_all(meshes)


def check_all(meshes: list) -> list[MeshReport]:
    """:func:`check_mesh` of many meshes ``(name, vertices [n, 3], faces [m, 3])`` at once: the
    meshes are stacked with their index as a key of every vertex, face and edge, so one sort per
    step serves them all. Same definitions as :func:`check_mesh`: vertices merged where their
    coordinates agree to 1e-8 m (trimesh's ``merge_vertices``); watertight when every edge has
    exactly two faces; consistent winding when every such edge runs both ways (trimesh's
    ``is_watertight``)."""
    if not meshes:
        return []
    n = len(meshes)
    n_v = np.array([len(v) for _, v, _ in meshes])
    n_f = np.array([len(f) for _, _, f in meshes])
    vertices = np.concatenate([v for _, v, _ in meshes]) if n_v.sum() else np.zeros((0, 3))
    faces = np.concatenate([f + o for (_, _, f), o in zip(meshes, np.r_[0, np.cumsum(n_v)[:-1]])]) \
        if n_f.sum() else np.zeros((0, 3), np.int64)
    face_mesh = np.repeat(np.arange(n), n_f)
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    degenerate = np.bincount(face_mesh[area < DEGENERATE_AREA], minlength=n)
    # ---- merge coincident vertices within each mesh (key: mesh, rounded coordinates) ----
    vertex_mesh = np.repeat(np.arange(n), n_v)
    keys = np.column_stack([vertex_mesh, np.round(vertices * 1e8).astype(np.int64)])
    _, merged = unique_rows(keys, return_inverse=True)
    faces = merged[faces]
    position = np.zeros((merged.max() + 1 if merged.size else 0, 3))
    position[merged] = vertices
    # ---- the faces whose merged area is not zero ----
    a, b, c = position[faces[:, 0]], position[faces[:, 1]], position[faces[:, 2]]
    keep = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1) >= DEGENERATE_AREA
    kept, kept_mesh = faces[keep], face_mesh[keep]
    unique_faces = unique_rows(np.sort(kept, axis=1))
    duplicates = np.bincount(kept_mesh, minlength=n) - np.bincount(_mesh_of(unique_faces[:, 0], merged, vertex_mesh),
                                                                   minlength=n)
    # ---- edges: counts per undirected edge, and the direction of each twice-used edge ----
    directed = np.concatenate([kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]])
    edge_mesh = np.tile(kept_mesh, 3)
    undirected = np.sort(directed, axis=1)
    _, inverse, counts = unique_rows(undirected, return_inverse=True, return_counts=True)
    per_edge = counts[inverse]
    edge_of = np.zeros(counts.size, np.int64)
    edge_of[inverse] = edge_mesh
    non_manifold = np.bincount(edge_of[counts > 2], minlength=n)
    open_ = np.bincount(edge_mesh[per_edge != 2], minlength=n) > 0
    twice = np.flatnonzero(per_edge == 2)
    order = twice[np.argsort(inverse[twice], kind="stable")]
    pairs = directed[order].reshape(-1, 4)                   # (a1, b1, a2, b2) of each shared edge
    same_way = pairs[:, 1] != pairs[:, 2]
    inconsistent = np.bincount(edge_mesh[order[0::2]][same_way], minlength=n) > 0
    empty = np.bincount(kept_mesh, minlength=n) == 0
    return [MeshReport(name, int(degenerate[i]), int(duplicates[i]), int(non_manifold[i]),
                       bool(inconsistent[i] or empty[i]), bool(open_[i] or empty[i]), int(n_f[i]))
            for i, (name, _, _) in enumerate(meshes)]


def _mesh_of(vertex: np.ndarray, merged: np.ndarray, vertex_mesh: np.ndarray) -> np.ndarray:
    """The mesh of merged vertices (each merged vertex belongs to one mesh)."""
    owner = np.zeros(merged.max() + 1 if merged.size else 0, np.int64)
    owner[merged] = vertex_mesh
    return owner[vertex]


def check_mesh(name: str, vertices: np.ndarray, faces: np.ndarray) -> MeshReport:
    """The defects of one mesh, with trimesh: the readable reference of :func:`check_all`."""
    raw = trimesh.Trimesh(vertices, faces, process=False)
    degenerate = int(np.count_nonzero(raw.area_faces < DEGENERATE_AREA))
    merged = trimesh.Trimesh(vertices, faces, process=False)
    merged.merge_vertices()
    kept = merged.faces[merged.area_faces >= DEGENERATE_AREA]
    duplicates = len(kept) - len(np.unique(np.sort(kept, axis=1), axis=0))
    edges = np.sort(np.concatenate([kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    clean = trimesh.Trimesh(merged.vertices, kept, process=False)
    return MeshReport(name, degenerate, int(duplicates), int(np.count_nonzero(counts > 2)),
                      not clean.is_winding_consistent, not clean.is_watertight, len(raw.faces))


def silent_scene(reports: list[MeshReport], n_shapes: int, source: str) -> str | None:
    """The loader's refusal of a scene none of whose ``n_shapes`` shapes can scatter (all are
    meshes whose every triangle has zero area: the products would be all zero), naming them;
    None when some shape can scatter."""
    silent = [r for r in reports if r.cannot_scatter]
    if not silent or len(silent) < n_shapes:
        return None
    named = ", ".join(repr(r.shape) for r in silent[:10]) + (f" and {len(silent) - 10} more" if len(silent) > 10 else "")
    shapes, it = ("shape " + named + " has", "it") if len(silent) == 1 else ("shapes " + named + " have", "they")
    return (f"{source}: {shapes} only triangles of zero area (below {DEGENERATE_AREA:g} m^2: collinear or "
            f"coincident vertices): {it} cannot scatter and the scene has nothing else, so every product would be "
            "zero; check the mesh export (a flattened axis, units) and the shape's to_world transform (a scale of 0)")


def warn_mesh_defects(reports: list[MeshReport], source: str, repairs: tuple | list = ()) -> None:
    """One :class:`MeshDefectWarning` summarising the defective meshes of a scene, if any, with
    what the loader did: ``repairs`` are the :class:`~sarmitsuba.scene.meshrepair.MeshRepair` of
    the meshes it repaired (duplicates traced once, winding made consistent) and ``reports``
    the checks after repair. A mesh whose every triangle has zero area is said to be missing
    from the image."""
    done = {fix.shape: fix for fix in repairs if fix.dropped or fix.inconsistent}
    bad = [r for r in reports if r.defective or r.shape in done]
    if not bad:
        return
    listed = "; ".join(_defects(r, done.get(r.shape)) for r in bad[:10])
    more = f" (and {len(bad) - 10} more meshes)" if len(bad) > 10 else ""
    warnings.warn(f"{source}: {len(bad)} mesh(es) with defects: {listed}{more}", MeshDefectWarning, stacklevel=3)


def _defects(r: MeshReport, fix) -> str:
    """One mesh's clauses of :func:`warn_mesh_defects`."""
    if r.cannot_scatter:
        return (f"{r.shape}: " + (f"all {r.faces} triangles have zero area" if r.faces else "no triangles")
                + ": it cannot scatter and is missing from the image")
    clauses = []
    if fix is not None and fix.dropped:
        clauses.append(f"{fix.dropped} duplicate triangles in {r.shape}: traced once")
    if fix is not None and fix.inconsistent:
        clauses.append(f"inconsistent normals in {r.shape}: " + (
            "made consistent, but it is open, so its outside cannot be decided (either side may be seen)"
            if fix.undecided else "closed: wound consistently, outward"))
    rest = ", ".join(part for part in (
        f"{r.degenerate_faces} zero-area triangles" if r.degenerate_faces else "",
        f"{r.duplicate_faces} duplicate triangles" if r.duplicate_faces else "",
        f"{r.non_manifold_edges} non-manifold edges" if r.non_manifold_edges else "",
        "inconsistent normals" if r.inconsistent_winding else "") if part)
    if rest:
        clauses.append(f"{r.shape}: {rest}: traced anyway")
    return "; ".join(clauses)
