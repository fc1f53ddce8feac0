"""Benchmark: each fused geometry kernel against its NumPy reference on the calls a Munich render
makes, and what the whole geometry would take if every stage gained as much (docs/design.md
section 10.1).

One fused render of Sionna RT's Munich (``N_PULSES`` central pulses, one host thread) records the
arguments of every top-level call of each kernel (a kernel called inside another, such as the
moments inside the pieces, counts with its caller). Each recorded call is then run with the
kernel and with its reference, alternately, ``REPEATS`` times; the fastest of each is kept.
Per kernel: calls, rows (the length of the first output), seconds of the reference and of the
kernel, their ratio, and whether every output is the reference's bit for bit.

The projection: the kernels' seconds together give one speedup ``S`` (reference over kernel);
a reference render of the same scene gives the geometry's host-thread seconds ``G`` (every stage
but the casts, the terms and the deposit) and its trace ``T``. Were every stage of the geometry
``S`` times faster, the trace would take ``T - G + G / S``: the floor of fusing on this machine,
at the speedups the fused kernels reach. (The segment kinds' kernel is a method of the tracer and
is not recorded.)

Checks: every kernel's outputs equal the reference's on every recorded call. Writes
``fused_kernels.csv`` (``_table.output_dir``).
Usage: ``python benchmarks/fused_kernels.py [--quick]``
"""
from __future__ import annotations

import dataclasses
import functools
import importlib.util
import os
import threading
import time

os.environ.setdefault("SARMITSUBA_HOST_THREADS", "1")

import numpy as np  # noqa: E402
from _table import bench_main, machine, report_rows  # noqa: E402

import sarmitsuba  # noqa: E402,F401
from sarmitsuba.pipeline import simulate  # noqa: E402
from sarmitsuba.tracing.integration.term_lanes import kd_tree_pairs  # noqa: E402
from sarmitsuba.tracing.fused import boundary, clipping, matching, moments, pieces, shadows  # noqa: E402
from sarmitsuba.tracing.mesh import piece_cuts, polygons  # noqa: E402
from sarmitsuba.tracing.visibility import cut_outs, occlusion  # noqa: E402

NAME = "fused_kernels"
#: Central pulses of Munich (``--quick``: urban, every pulse).
N_PULSES = 64
#: Timed runs of each recorded call with each pipeline (the fastest kept).
REPEATS = 3
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3
#: The stages that are not the geometry (as ``benchmarks/fused.py``).
NOT_GEOMETRY = ("casts", "terms", "deposit")
#: The projection's columns (the last row's alone).
PROJECTION = ("geometry_s", "kernels_share_of_geometry", "reference_trace_s", "projected_trace_s",
              "projected_trace_ratio")
#: Kernel name: (module, attribute, the reference taking the same arguments).
KERNELS = {
    "cut-outs": (clipping, "cut_outs", cut_outs.cut_outs),
    "lit boundary": (boundary, "lit_boundary", occlusion.lit_boundary),
    "shadow half-planes": (shadows, "shared_shadow_lines", occlusion.shared_shadow_lines),
    "pieces of regions": (pieces, "pieces_of", functools.partial(piece_cuts.pieces_of, moments=polygons.moments)),
    "moments": (moments, "moments", polygons.moments),
    "lone pairs": (matching.RowMatcher, "__call__", lambda matcher, *args: kd_tree_pairs(*args)),
}


def _pairs(rows: np.ndarray) -> np.ndarray:
    """Pairs of rows as one order: each ``(i, j)`` with ``i < j``, sorted (the k-d tree's come in
    its own order)."""
    rows = np.sort(np.asarray(rows).reshape(-1, 2), axis=1)
    return rows[np.lexsort((rows[:, 1], rows[:, 0]))]


def _record(scene: str, sensor: dict) -> dict:
    """One fused render with every kernel's top-level calls recorded: name -> [(args, kwargs)]."""
    calls = {name: [] for name in KERNELS}
    depth = threading.local()
    real = {name: getattr(module, attr) for name, (module, attr, _) in KERNELS.items()}

    def recorder(name):
        def call(*args, **kwargs):
            outer = getattr(depth, "n", 0) == 0
            if outer:
                calls[name].append((args, {k: v for k, v in kwargs.items() if k != "moments"}))
            depth.n = getattr(depth, "n", 0) + 1
            try:
                return real[name](*args, **kwargs)
            finally:
                depth.n -= 1
        return call

    for name, (module, attr, _) in KERNELS.items():
        setattr(module, attr, recorder(name))
    try:
        simulate(scene, sensor_overrides=sensor, integrator_overrides={"max_depth": MAX_DEPTH, "geometry": "fused"})
    finally:
        for name, (module, attr, _) in KERNELS.items():
            setattr(module, attr, real[name])
    return calls


def _leaves(value) -> list:
    """The arrays of an output (tuples, lists, dataclasses), in order."""
    if isinstance(value, (tuple, list)):
        return [x for v in value for x in _leaves(v)]
    if dataclasses.is_dataclass(value):
        return [x for f in dataclasses.fields(value) for x in _leaves(getattr(value, f.name))]
    return [np.asarray(value)]


def _same(a, b) -> bool:
    left, right = _leaves(a), _leaves(b)
    return len(left) == len(right) and all(x.shape == y.shape and np.array_equal(x, y, equal_nan=True)
                                           for x, y in zip(left, right))


def _first_rows(out) -> int:
    return len(_leaves(out)[0]) if _leaves(out) else 0


def _time(function, args, kwargs) -> tuple[float, object]:
    start = time.perf_counter()
    out = function(*args, **kwargs)
    return time.perf_counter() - start, out


def _kernel_rows(calls: dict) -> list[dict]:
    rows = []
    for name, recorded in calls.items():
        module, attr, reference = KERNELS[name]
        kernel = getattr(module, attr)
        if name == "pieces of regions":
            kernel = functools.partial(kernel, moments=moments.moments)
        best = {"reference": 0.0, "fused": 0.0}
        same, n_rows = True, 0
        for args, kwargs in recorded:
            kernel(*args, **kwargs)                               # compiled, cached
            times = {"reference": [], "fused": []}
            for _ in range(REPEATS):
                t, want = _time(reference, args, kwargs)
                times["reference"].append(t)
                t, got = _time(kernel, args, kwargs)
                times["fused"].append(t)
            for k in best:
                best[k] += min(times[k])
            same &= _same(_pairs(got), _pairs(want)) if name == "lone pairs" else _same(got, want)
            n_rows += _first_rows(got)
        rows.append({"kernel": name, "calls": len(recorded), "rows": n_rows,
                     "reference_s": round(best["reference"], 4), "fused_s": round(best["fused"], 4),
                     "speedup": round(best["reference"] / best["fused"], 2) if best["fused"] > 0 else None,
                     "bit_identical": bool(same), **dict.fromkeys(PROJECTION)})
    return rows


def run(quick: bool = False) -> list[dict]:
    """The kernels on a render's calls, and the projection (module docstring)."""
    print(machine(), flush=True)
    if quick or importlib.util.find_spec("sionna") is None:
        scene, sensor = "urban", {}
    else:
        scene, sensor = "sionna:munich", {"n_pulses": N_PULSES}
    _record(scene, sensor)                                      # untimed: every kernel compiled
    rows = _kernel_rows(_record(scene, sensor))
    reference = simulate(scene, sensor_overrides=sensor,
                         integrator_overrides={"max_depth": MAX_DEPTH, "geometry": "reference"})
    geometry = sum(t for stage, t in reference.trace.stage_seconds.items() if stage not in NOT_GEOMETRY)
    total_ref = sum(r["reference_s"] for r in rows)
    total_fused = sum(r["fused_s"] for r in rows)
    speedup = total_ref / total_fused if total_fused > 0 else 1.0
    trace = reference.trace.seconds
    rows.append({"kernel": f"all ({scene}, projection)", "calls": sum(r["calls"] for r in rows),
                 "rows": sum(r["rows"] for r in rows), "reference_s": round(total_ref, 4),
                 "fused_s": round(total_fused, 4), "speedup": round(speedup, 2),
                 "bit_identical": all(r["bit_identical"] for r in rows),
                 "geometry_s": round(geometry, 3), "kernels_share_of_geometry": round(total_ref / geometry, 3),
                 "reference_trace_s": round(trace, 3),
                 "projected_trace_s": round(trace - geometry + geometry / speedup, 3),
                 "projected_trace_ratio": round((trace - geometry + geometry / speedup) / trace, 3)})
    return report_rows(NAME + ".csv", rows)


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    return [(f"the {row['kernel']} kernel's outputs are the reference's on every recorded call", row["bit_identical"],
             f"{row['calls']} calls, {row['speedup']}x") for row in rows[:-1]]


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban instead of Munich")
