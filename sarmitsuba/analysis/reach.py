"""The mesh tracer's work in each sub-aperture's reach, and its measured rates
(docs/physics.md (M9)): what :mod:`sarmitsuba.analysis.cost` turns into ``info``'s trace time and
peak memory for ``lit_regions = "patches"``.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.geometry import AcquisitionGeometry
from ..scene.loader import LoadedScene

__all__ = ["reach_work", "SETUP_TRIANGLE_SECONDS", "SUB_PIECE_SECONDS", "SUB_TRIANGLE_SECONDS",
           "CLUTTER_SCATTERER_PULSE_SECONDS", "MESH_TRIANGLE_BYTES", "SUBAPERTURE_BYTES", "REACH_TRIANGLE_BYTES"]

#: Mesh-anchored trace time per sub-aperture: host seconds per first-order piece and
#: per triangle in the sub-aperture's along-track reach (:func:`reach_work`, the tracer's own reach,
#: ``MeshTracer._reach``), for all its bounce orders together (classifying, clipping the mixed
#: ones, motion rates, term lanes), and seconds per clutter scatterer-pulse of the rough area
#: facing the sensor in that reach (``area / scatterer_spacing^2`` times its pulses), plus
#: seconds per triangle of the tracer's set-up (surfaces, wedges, the pieces of every part).
#: Measured as the trace's wall seconds on an otherwise idle 2-core machine (what ``info``'s user
#: compares the prediction with; the kernels use both cores, so CPU seconds run 1.1-1.9x higher)
#: with ``python benchmarks/scaling.py --calibrate`` (renders the generated city of
#: ``benchmarks/city_generator.py`` at 10 k triangles with 19, 38 and 76 pulses, rough and smooth,
#: at 100 k triangles with 19 and 38 pulses, urban and Munich, and fits these four constants);
#: re-run it and paste its output here when the tracer changes.
#: Fitted (non-negative relative least squares on 8 renders, every one within 35 %) on 2026-11-28
#: at commit 2b4de5b (the fused geometry, the default; two launches at once on host threads),
#: trace wall seconds less the casts' share: 10 k city 19 pulses 1.42 s (smooth 1.09 s), 38 pulses
#: 1.65 s, 76 pulses 2.54 s; 100 k city 19 pulses 5.76 s, 38 pulses 6.76 s; urban (779 pulses, 30
#: sub-apertures) 3.78 s; sionna:munich, its whole default acquisition (2,326 pulses, 123
#: sub-apertures: a short run's fixed costs had made the per-sub-aperture terms too large), 77.0 s.
#: The time goes mostly with the parts (triangles) in reach, each at least one piece with its own
#: chain, lanes and clipping, and little with how many whole patches a large face holds (urban,
#: Munich separate the two).
SETUP_TRIANGLE_SECONDS = 3.84e-5
SUB_PIECE_SECONDS = 1.22e-6
SUB_TRIANGLE_SECONDS = 6.74e-5
CLUTTER_SCATTERER_PULSE_SECONDS = 2.06e-8
#: Mesh tracer memory [bytes]: :data:`MESH_TRIANGLE_BYTES` per triangle of the whole scene (its
#: surfaces, wedges and the pieces of every part, cut once per acquisition and held: this part
#: grows with the scene, not with the beam), and :data:`SUBAPERTURE_BYTES` for each sub-aperture
#: of a launch, or :data:`REACH_TRIANGLE_BYTES` per triangle of the largest reach when that is less
#: (urban's 77 triangles: a few large faces). Fitted by hand to the peak RSS of the generated city with one sub-aperture (19
#: pulses: 12.7 k triangles 347 MiB, 107 k 907 MiB, 1.05 M 5,893 MiB: 5.3 kB per triangle in all,
#: the Mitsuba scene's 800 B included) and with several per launch (10 k city: 447, 602 and 1,103
#: MiB with 2, 4 and 19; 1.05 M city: 5,990 MiB with 3): a sub-aperture more in a launch adds 35-55
#: MiB whatever its reach holds (76 k triangles on the 1 M city, 6.4 k on the 10 k one).
#: ``python benchmarks/scaling.py --calibrate`` prints measured and modelled peaks.
MESH_TRIANGLE_BYTES = 4500
SUBAPERTURE_BYTES = 35 * 2**20
REACH_TRIANGLE_BYTES = 6000


def _mesh_triangles(loaded: LoadedScene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every mesh triangle of ``loaded``: centroids float64 [n, 3] m, areas float64 [n] m^2, unit
    normals float64 [n, 3] (zero for a degenerate triangle)."""
    centroids, areas, normals = [np.zeros((0, 3))], [np.zeros(0)], [np.zeros((0, 3))]
    for shape in loaded.scene.shapes():
        if shape.is_mesh():
            v = np.asarray(shape.vertex_positions_buffer(), np.float64).reshape(-1, 3)
            t = v[np.asarray(shape.faces_buffer(), np.int64).reshape(-1, 3)]
            n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            twice = np.sqrt(np.einsum("ij,ij->i", n, n))
            centroids.append(t.mean(axis=1))
            areas.append(0.5 * twice)
            normals.append(n / np.where(twice > 0, twice, 1.0)[:, None])
    return np.concatenate(centroids), np.concatenate(areas), np.concatenate(normals)


def reach_work(loaded: LoadedScene, geometry: AcquisitionGeometry, patch: float, size: int,
               straight: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order pieces, triangles and the area facing the sensor in each sub-aperture's reach.

    The reach is the mesh tracer's (``MeshTracer._reach`` at the first order, straight track):
    along the track, from the sub-aperture's first to its last antenna position, widened by the
    beam's sines (``params.beam_sines``) times the distance to the scene's farthest corner and by
    ``REACH_MARGIN`` and one patch; every part whose centroid lies in it is cut into pieces. A
    triangle of area ``a`` counts ``(sqrt(a) / P + 1)^2`` pieces (its patches, plus a row and a
    column of border pieces), one when it is no wider than the patch ``P``. Not ``straight`` (spotlight mode or a curved
    track) every sub-aperture reaches the whole scene.

    Parameters
    ----------
    loaded : LoadedScene
    geometry : AcquisitionGeometry
        The pulses' antenna positions [m] and track direction.
    patch : float, m
        Patch size (``RayFootprint.patch_size``).
    size : int
        Pulses per sub-aperture.
    straight : bool, default True
        The tracer limits each sub-aperture to its reach (False: spotlight or a curved track).

    Returns
    -------
    pieces, triangles, area : float64 [n_subapertures]
        Estimated first-order pieces, triangles, and m^2 of triangles whose normal faces the
        antenna (the rough area clutter scatterers are drawn on), in each sub-aperture's reach.
    """
    from ..tracing.driver.mesh_trace import REACH_MARGIN
    p = loaded.params
    n_pulses = len(geometry.positions)
    n_subs = math.ceil(n_pulses / size)
    centroid, area, normal = _mesh_triangles(loaded)
    weight = (np.sqrt(area) / patch + 1.0) ** 2
    if len(area):
        # a triangle no wider than a patch is one piece (piece_cuts.pieces_of's small regions)
        weight = np.where(np.sqrt(area * 2.0) <= patch, 1.0, weight)
    to_sensor = geometry.positions[min(n_pulses - 1, n_pulses // 2)] - centroid
    facing = np.einsum("ij,ij->i", normal, to_sensor) > 0
    track = np.asarray(geometry.track_direction, np.float64)
    along = centroid @ track
    order = np.argsort(along, kind="stable")
    along = along[order]
    pieces_cum = np.concatenate([[0.0], np.cumsum(weight[order])])
    area_cum = np.concatenate([[0.0], np.cumsum(np.where(facing, area, 0.0)[order])])
    if not straight or not len(area):
        return np.full(n_subs, pieces_cum[-1]), np.full(n_subs, float(len(area))), np.full(n_subs, area_cum[-1])
    lo_b, hi_b = p.beam_sines
    corners = np.array(np.meshgrid(*zip(loaded.bbox_lo, loaded.bbox_hi), indexing="ij")).reshape(3, -1).T
    far = float(np.max(np.linalg.norm(corners[None] - geometry.positions[:, None], axis=2)))
    antenna = geometry.positions @ track
    first = antenna[np.arange(n_subs) * size]
    last = antenna[np.minimum(np.arange(n_subs) * size + size, n_pulses) - 1]
    lo = np.minimum(first, last) + lo_b * far - REACH_MARGIN - patch
    hi = np.maximum(first, last) + hi_b * far + REACH_MARGIN + patch
    i0, i1 = np.searchsorted(along, lo), np.searchsorted(along, hi)
    return pieces_cum[i1] - pieces_cum[i0], (i1 - i0).astype(np.float64), area_cum[i1] - area_cum[i0]
