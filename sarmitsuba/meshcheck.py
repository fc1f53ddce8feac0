"""Geometry checks on loaded meshes (with trimesh): degenerate input is reported, never fatal.

The tracer is robust to all of these (a zero-area triangle's undefined normal is treated as
a miss; open and non-manifold meshes simply reflect what they have). They usually mean a
modelling error, so :func:`warn_mesh_defects` says which shapes have which defects.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import trimesh

__all__ = ["MeshReport", "check_meshes", "warn_mesh_defects", "MeshDefectWarning"]

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
    """

    shape: str
    degenerate_faces: int
    duplicate_faces: int
    non_manifold_edges: int
    inconsistent_winding: bool
    open: bool

    @property
    def defective(self) -> bool:
        """Whether the mesh has a defect worth a warning (being open is not one)."""
        return bool(self.degenerate_faces or self.duplicate_faces or self.non_manifold_edges
                    or self.inconsistent_winding)


def check_meshes(scene) -> list[MeshReport]:
    """Check every mesh shape of a Mitsuba scene; returns one report per mesh."""
    reports = []
    for shape in scene.shapes():
        if not shape.is_mesh():
            continue
        vertices = np.array(shape.vertex_positions_buffer(), np.float64).reshape(-1, 3)
        faces = np.array(shape.faces_buffer(), np.int64).reshape(-1, 3)
        reports.append(_check(shape.id(), vertices, faces))
    return reports


def _check(name: str, vertices: np.ndarray, faces: np.ndarray) -> MeshReport:
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
                      not clean.is_winding_consistent, not clean.is_watertight)


def warn_mesh_defects(reports: list[MeshReport], source: str) -> None:
    """One :class:`MeshDefectWarning` summarising the defective meshes of a scene, if any."""
    bad = [r for r in reports if r.defective]
    if not bad:
        return
    listed = "; ".join(
        f"{r.shape}: " + ", ".join(part for part in (
            f"{r.degenerate_faces} zero-area triangles" if r.degenerate_faces else "",
            f"{r.duplicate_faces} duplicate triangles" if r.duplicate_faces else "",
            f"{r.non_manifold_edges} non-manifold edges" if r.non_manifold_edges else "",
            "inconsistent normals" if r.inconsistent_winding else "") if part)
        for r in bad[:10])
    more = f" (and {len(bad) - 10} more meshes)" if len(bad) > 10 else ""
    warnings.warn(f"{source}: {len(bad)} mesh(es) with defects, traced anyway: {listed}{more}",
                  MeshDefectWarning, stacklevel=3)
