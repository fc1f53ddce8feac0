"""Whether a render fits in memory, checked before any tracing: the memory available
(:func:`available_memory`), why a render's estimated peak would not fit and what to change
(:func:`memory_problem`), and the check a render runs first (:func:`check_memory`).

The peak itself is the cost model's (:class:`~sarmitsuba.analysis.cost.CostEstimate`,
``peak_memory_bytes``): the whole render process's peak resident set, from measured constants.
"""
from __future__ import annotations

import os

from ..core.radar import ParameterError, RadarParameters
from ..core.geometry import AcquisitionGeometry
from ..scene.effects import EffectSet
from ..scene.loader import LoadedScene
from ..scene.trace_inputs import FastTimeWindow, RayFootprint
from .cost import (HISTOGRAM_DEVICE_BYTES, HISTOGRAM_ENTRY_BYTES, LANE_BYTES, RUNTIME_BYTES, CostEstimate,
                   cost_estimate, format_bytes)

__all__ = ["MEMORY_LIMIT_ENV", "available_memory", "memory_problem", "check_memory"]


# ============================================================================ memory
#: Environment variable that sets the memory [bytes] a render may use (tests, batch jobs); without
#: it :func:`available_memory` reads the machine's.
MEMORY_LIMIT_ENV = "SARMITSUBA_MEMORY_LIMIT"


def available_memory() -> int:
    """Bytes of memory a render may use: ``$SARMITSUBA_MEMORY_LIMIT`` when set, else ``MemAvailable``
    of ``/proc/meminfo`` (Linux), else the physical memory (``os.sysconf``).

    Raises
    ------
    ParameterError
        ``SARMITSUBA_MEMORY_LIMIT`` is not a whole number of bytes > 0.
    """
    text = os.environ.get(MEMORY_LIMIT_ENV)
    if text is not None:
        try:
            limit = int(float(text))
        except ValueError:
            limit = 0
        if limit <= 0:
            raise ParameterError(f"{MEMORY_LIMIT_ENV} = {text!r} must be a number of bytes > 0 (e.g. 8e9)")
        return limit
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def memory_problem(cost: CostEstimate, params: RadarParameters, available: int | None = None) -> str | None:
    """Why a render of estimated ``cost`` cannot fit in ``available`` bytes (default
    :func:`available_memory`) and what to change, led by the term that dominates; None when it fits."""
    available = available_memory() if available is None else available
    if cost.peak_memory_bytes <= available:
        return None
    n = cost.n_products
    terms = {"runtime and scene": cost.runtime_bytes, "tracer's working set": cost.trace_working_bytes,
             "spectra": cost.deposit_bytes, "path list": cost.path_list_bytes, "raw data": n * cost.raw_bytes,
             "image": n * cost.image_bytes, "focusing": cost.focus_working_bytes}
    parts = ", ".join(f"{name} {format_bytes(size)}" for name, size in terms.items() if size)
    text = (f"the render would need about {format_bytes(cost.peak_memory_bytes)} of memory ({parts}; not all "
            f"held at once) but {format_bytes(available)} is available ({MEMORY_LIMIT_ENV} overrides it)")
    return f"{text}: {_memory_fix(cost, params, available, max(terms, key=terms.get))}"


def _memory_fix(cost: CostEstimate, params: RadarParameters, available: int, largest: str) -> str:
    """What to change when the term ``largest`` of :func:`memory_problem` dominates."""
    if largest in ("image", "focusing"):
        return (f"the image grid {cost.image_shape[0]} x {cost.image_shape[1]} pixels dominates; its pixels "
                "are half the finer resolution: lower bandwidth, narrow the beam or use a smaller scene")
    if largest == "runtime and scene":
        return (f"the runtime (Python, Mitsuba, Dr.Jit and LLVM: {format_bytes(RUNTIME_BYTES)}) and the scene "
                "dominate: use a smaller scene (fewer triangles and shapes) or a machine with more memory")
    if largest == "tracer's working set":
        lanes = (available - cost.peak_memory_bytes) // LANE_BYTES + cost.lanes_per_launch   # the lanes that fit
        return (f"the tracer's working set dominates ({cost.lanes_per_launch:,} ray tubes per launch x "
                f"{LANE_BYTES} B, a fine-grid histogram of {cost.histogram_entries:,} entries x "
                f"({HISTOGRAM_ENTRY_BYTES} + {HISTOGRAM_DEVICE_BYTES}) B): launch fewer "
                f"tubes at once (--integrator-set max_batch_rays={max(1024, lanes)} or fewer; at least 1024)")
    fixed = cost.peak_memory_bytes - cost.pulse_memory_bytes
    per_pulse = cost.pulse_memory_bytes / max(cost.n_pulses, 1)
    if available <= fixed + per_pulse:
        fix = (f"even one pulse would not fit: the runtime, scene, tracer and image alone need about "
               f"{format_bytes(fixed)}")
    else:
        fix = (f"use fewer pulses (--pulses {int((available - fixed) // per_pulse)} or fewer; sar n_pulses = "
               f"{cost.n_pulses} now) or a shorter fast-time window ({cost.fast_time_samples} samples: a smaller "
               f"scene, or --set sampling_rate=... closer to bandwidth = {params.bandwidth / 1e6:g} MHz)")
    if largest == "path list":
        fix = f"the exact range kernel's path list dominates: use --range-kernel linear, or {fix}"
    else:
        fix = f"the {largest} (pulses x fast-time samples) dominate: {fix}"
    if cost.n_products > 1:
        fix += f", or drop split_bounces ({cost.n_products} raw data sets and images)"
    return fix


def check_memory(loaded: LoadedScene, geometry: AcquisitionGeometry, window: FastTimeWindow,
                 footprint: RayFootprint, available: int | None = None,
                 effects: EffectSet | None = None) -> CostEstimate:
    """The cost of rendering ``loaded`` (:func:`cost_estimate`, with its ``effects``), checked
    against the memory ``available`` [bytes] (default :func:`available_memory`) before any tracing.

    Raises
    ------
    ParameterError
        The estimated peak memory exceeds it (:func:`memory_problem` says what to change), or the
        image grid would be too large.
    """
    cost = cost_estimate(loaded, geometry, window, footprint, effects)
    problem = memory_problem(cost, loaded.params, available)
    if problem is not None:
        raise ParameterError(problem)
    return cost
