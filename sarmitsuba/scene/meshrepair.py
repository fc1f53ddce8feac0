"""Meshes as they come from CAD, repaired at load (docs/physics.md (M0)).

Two defects of exported meshes change the image, so the loader repairs them in the Mitsuba
scene itself, before anything is traced (the tracer's tables and Mitsuba's primitive indices
then agree by construction):

- *duplicate triangles* (the same three vertex positions, in any order or winding) would each
  scatter, doubling the field of their surface (+6 dB): all but the first are dropped;
- *winding*: every closed body (watertight after merging coincident vertices) is wound
  consistently with its normals outward (trimesh's ``fix_normals``, per body); an open mesh
  whose winding is inconsistent is wound consistently, but which of its sides is outside
  cannot be decided, which :func:`repair_meshes` reports (:attr:`MeshRepair.undecided`).

:func:`repaired_faces` is the per-mesh step on arrays; :func:`repair_meshes` applies it to the
meshes of a scene that need it (duplicates, inconsistent winding, or a closed body of negative
volume) and writes their faces back through ``mi.traverse``.
"""
from __future__ import annotations

from dataclasses import dataclass

import mitsuba as mi
import numpy as np
import trimesh

from .meshcheck import DEGENERATE_AREA, MeshReport, shape_label

__all__ = ["MeshRepair", "repaired_faces", "repair_meshes", "signed_volume"]


@dataclass(frozen=True)
class MeshRepair:
    """What :func:`repair_meshes` did to one mesh.

    Attributes
    ----------
    shape : str
        The shape's label (:func:`~sarmitsuba.scene.meshcheck.shape_label`).
    dropped : int
        Duplicate triangles removed.
    rewound : int
        Triangles whose winding (and so normal) was reversed.
    inconsistent : bool
        The winding was inconsistent (neighbouring triangles' normals disagreed).
    undecided : bool
        The winding was inconsistent and the mesh is open: wound consistently, but its outside
        could not be decided.
    """

    shape: str
    dropped: int
    rewound: int
    inconsistent: bool
    undecided: bool


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The divergence-theorem volume ``sum a . (b x c) / 6`` [m^3] of a triangle mesh: positive
    for a closed body wound with its normals outward, negative for one wound inward."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


def repaired_faces(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, int, int, bool]:
    """``(faces, dropped, rewound, undecided)``: ``faces`` int64 [m, 3] (rows of the given
    ``faces``, in their order) without duplicate triangles and wound outward where closed
    (:class:`MeshRepair` for the counts). Vertices merge where their coordinates agree to
    1e-8 m, as in :func:`~sarmitsuba.scene.meshcheck.check_all`; zero-area triangles are kept
    as they are (the tracer ignores them)."""
    vertices = np.asarray(vertices, np.float64).reshape(-1, 3)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    if not len(faces):
        return faces, 0, 0, False
    _, first, merged = np.unique(np.round(vertices * 1e8).astype(np.int64), axis=0, return_index=True,
                                 return_inverse=True)
    merged = merged.reshape(-1)
    position = vertices[first]
    m = merged[faces]
    a, b, c = position[m[:, 0]], position[m[:, 1]], position[m[:, 2]]
    solid = np.flatnonzero(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1) >= DEGENERATE_AREA)
    _, once = np.unique(np.sort(m[solid], axis=1), axis=0, return_index=True)
    keep = np.ones(len(faces), bool)
    keep[solid] = False
    keep[solid[once]] = True
    faces, m, dropped = faces[keep], m[keep], int(len(faces) - keep.sum())
    solid = np.flatnonzero(np.isin(np.flatnonzero(keep), solid))        # rows of the kept faces
    body = trimesh.Trimesh(position, m[solid], process=False)
    consistent = body.is_winding_consistent
    trimesh.repair.fix_normals(body, multibody=True)                    # consistent, closed bodies outward
    after = np.asarray(body.faces, np.int64)
    before = m[solid]
    same = np.any([np.all(np.roll(before, r, axis=1) == after, axis=1) for r in range(3)], axis=0)
    flip = solid[~same]
    faces = faces.copy()
    faces[flip] = faces[flip, ::-1]
    return faces, dropped, len(flip), bool(not consistent and not body.is_watertight)


def repair_meshes(scene, reports: list[MeshReport]) -> list[MeshRepair]:
    """Repair (:func:`repaired_faces`) every mesh of the Mitsuba ``scene`` that needs it: its
    report (:func:`~sarmitsuba.scene.meshcheck.check_meshes`, same order) has duplicates or an
    inconsistent winding, or it is closed with a negative volume (wound inward; a consistently
    wound mesh of several closed bodies is judged by their total volume, which keeps the check
    linear and cheap: one inside-out body among outward ones is missed). The faces are written
    back in place (the scene's acceleration structure is rebuilt). Returns one
    :class:`MeshRepair` per mesh changed or undecided."""
    meshes = [(index, shape) for index, shape in enumerate(scene.shapes()) if shape.is_mesh()]
    changed = []
    for (index, shape), report in zip(meshes, reports):
        vertices = np.array(shape.vertex_positions_buffer(), np.float64).reshape(-1, 3)
        faces = np.array(shape.faces_buffer(), np.int64).reshape(-1, 3)
        inward = not report.open and not report.inconsistent_winding and signed_volume(vertices, faces) < 0
        if not (report.duplicate_faces or report.inconsistent_winding or inward):
            continue
        fixed, dropped, rewound, undecided = repaired_faces(vertices, faces)
        if dropped or rewound or undecided:
            changed.append((shape, fixed, MeshRepair(shape_label(shape, index), dropped, rewound,
                                                     report.inconsistent_winding, undecided)))
    if not changed:
        return []
    params = mi.traverse(scene)
    written = set()
    for key in [k for k in params.keys() if k.endswith(".faces")]:
        node = params.properties[key][2]
        for shape, fixed, repair in changed:
            if node is shape and (repair.dropped or repair.rewound):
                params[key] = mi.UInt32(fixed.astype(np.uint32).ravel())
                written.add(id(shape))
    params.update()
    # a mesh whose faces Mitsuba does not expose is traced as it is, and not said to be repaired
    return [repair for shape, _, repair in changed
            if id(shape) in written or not (repair.dropped or repair.rewound)]
