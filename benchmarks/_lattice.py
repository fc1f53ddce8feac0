"""Shared by the benchmarks that compare images: NRMSE in dB, and the ray lattice moved for one run."""
from __future__ import annotations

import contextlib
import dataclasses

import numpy as np

from sarmitsuba.scene import planning
def nrmse_db(image: np.ndarray, reference: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB] (-inf when identical)."""
    error = float(np.sum(np.abs(image - reference) ** 2))
    return 10.0 * np.log10(error / float(np.sum(np.abs(reference) ** 2))) if error > 0 else float("-inf")


@contextlib.contextmanager
def moved_lattice(shift):
    """Within the block, :func:`sarmitsuba.scene.planning.ray_footprint` anchors the ray lattice
    ``shift = (along track, ground range)`` cells from the scene centre (nothing moved for
    ``None``): the same change as moving every mesh by that fraction of a cell."""
    real = planning.ray_footprint

    def footprint(params, geometry, *args, **kwargs):
        # the lattice is anchored at the scene centre: anchor it ``shift`` cells away, before the
        # refinement around small objects is laid out on it (so the refined cells follow it)
        track, look = geometry.track_direction, geometry.look_direction
        s, spacing_range = planning.ray_spacing(params, args[2] if len(args) > 2 else kwargs["settings"])
        centre = np.asarray(params.scene_center, float) + shift[0] * s * track + shift[1] * spacing_range * look
        return real(dataclasses.replace(params, scene_center=tuple(centre)), geometry, *args, **kwargs)
    if shift is not None:
        planning.ray_footprint = footprint
    try:
        yield
    finally:
        planning.ray_footprint = real


def trace_numbers(sim) -> tuple[dict, np.ndarray]:
    """A render's trace numbers (``trace_s``, ``pulses_per_trace``, ``pulses``) and its image data,
    the simulation released (its raw data and image otherwise stay in memory until the next one)."""
    import gc
    numbers = {"trace_s": round(sim.timings["trace"], 3), "pulses_per_trace": sim.trace.pulses_per_trace,
               "pulses": sim.raw.n_pulses}
    image = sim.image.data
    del sim
    gc.collect()
    return numbers, image
