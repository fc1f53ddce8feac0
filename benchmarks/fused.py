"""Benchmark: the fused geometry kernels against the NumPy stages they replace (docs/design.md
section 10.1), on the same scenes, in one process.

For each scene, the render with ``geometry = reference`` and with ``geometry = fused``, each run
once untimed (its kernels compiled), then ``REPEATS`` times alternately; reported per scene:

* trace seconds (medians) and their ratio, fused over reference, and the same for every stage
  of ``trace_stages`` (host-thread seconds);
* the geometry's host-thread seconds: every stage but the ray casts, the terms and the deposit
  (the part of the trace the design moves to the device);
* the raw data's NRMSE of fused against reference, ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB],
  and whether the bits are the same;
* the mesh tracer's counts per bounce order (chains, lit pieces, term lanes) of both, whether
  they are equal, and the rows the fused kernels left to the reference (``overflow_rows``).

Scenes: Sionna RT's Munich (128 central pulses; not with ``--quick``), ``urban``, ``traffic``
(moving cars) and urban received on a drone (bistatic), one launch at a time; and Munich again
with the default two host threads (``SARMITSUBA_HOST_THREADS`` unset), as a render runs.

Checks: the fused raw data within -50 dB of the reference's, and the counts equal, on every
scene. Writes ``fused.csv`` (``_table.output_dir``).
Usage: ``python benchmarks/fused.py [--quick]``
"""
from __future__ import annotations

import importlib.util
import os
import statistics

os.environ.setdefault("SARMITSUBA_HOST_THREADS", "1")     # stage seconds of one launch at a time
THREADS = os.environ["SARMITSUBA_HOST_THREADS"]

import numpy as np  # noqa: E402
from _table import bench_main, machine, report_rows  # noqa: E402

import sarmitsuba  # noqa: E402,F401
from sarmitsuba.pipeline import simulate  # noqa: E402
from sarmitsuba.tracing.driver import mesh_trace  # noqa: E402

NAME = "fused"
#: Timed renders of each pipeline per scene (after one untimed render of each; 1: traffic alone takes
#: minutes a render on 2 cores).
REPEATS = 1
#: Scene, sensor overrides and host threads (``SARMITSUBA_HOST_THREADS``; None: the default).
SCENES = {
    "munich (128 pulses)": ("sionna:munich", {"n_pulses": 128}, THREADS),
    "urban": ("urban", {}, THREADS),
    "traffic": ("traffic", {}, THREADS),
    "bistatic urban (drone)": ("urban", {"receiver_altitude": 300.0, "receiver_heading": 90.0,
                                         "receiver_velocity": 15.0}, THREADS),
    "munich (128 pulses, two host threads)": ("sionna:munich", {"n_pulses": 128}, None),
}
#: The stages that are not the geometry (docs/design.md section 10.1).
NOT_GEOMETRY = ("casts", "terms", "deposit")
#: Largest NRMSE [dB] of the fused raw data against the reference's.
NRMSE_BOUND_DB = -50.0
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


def _render(scene: str, sensor: dict, geometry: str, threads: str | None = THREADS) -> dict:
    """One render on ``threads`` host threads (None: the default): trace seconds, stage seconds,
    raw data, overflow rows and the mesh tracer's counts."""
    if threads is None:
        os.environ.pop("SARMITSUBA_HOST_THREADS", None)
    else:
        os.environ["SARMITSUBA_HOST_THREADS"] = threads
    counts: dict = {"chains": [], "pieces": [], "lanes": []}
    real = mesh_trace.MeshTracer.__call__

    def call(self, ctx, launch):
        stats = real(self, ctx, launch)
        for name in counts:
            counts[name].append(list(stats[name]))
        return stats

    mesh_trace.MeshTracer.__call__ = call
    try:
        sim = simulate(scene, sensor_overrides=sensor,
                       integrator_overrides={"max_depth": MAX_DEPTH, "geometry": geometry})
    finally:
        mesh_trace.MeshTracer.__call__ = real
        os.environ["SARMITSUBA_HOST_THREADS"] = THREADS
    return {"trace_s": sim.trace.seconds, "stages": dict(sim.trace.stage_seconds), "raw": sim.raw.data,
            "overflow": sim.trace.overflow_rows, "counts": counts}


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    error = float(np.sum(np.abs(a - b) ** 2)) / max(float(np.sum(np.abs(b) ** 2)), 1e-300)
    return 10.0 * np.log10(error) if error > 0 else float("-inf")


def run(quick: bool = False) -> list[dict]:
    """Each scene with both pipelines (module docstring); returns one row per scene."""
    print(machine(), flush=True)
    scenes = dict(SCENES)
    if quick or importlib.util.find_spec("sionna") is None:
        scenes = {name: spec for name, spec in scenes.items() if not name.startswith("munich")}
    rows = []
    for name, (scene, sensor, threads) in scenes.items():
        runs = {"reference": [], "fused": []}
        for geometry in runs:                                   # untimed: kernels compiled
            _render(scene, sensor, geometry, threads)
        for _ in range(REPEATS):
            for geometry in runs:
                runs[geometry].append(_render(scene, sensor, geometry, threads))
        ref, fused = runs["reference"][-1], runs["fused"][-1]
        row = {"scene": name}
        for geometry, found in runs.items():
            row[f"{geometry}_trace_s"] = round(statistics.median(r["trace_s"] for r in found), 3)
        row["trace_ratio"] = round(row["fused_trace_s"] / row["reference_trace_s"], 3)
        for geometry, found in runs.items():
            row[f"{geometry}_geometry_s"] = round(statistics.median(
                sum(t for stage, t in r["stages"].items() if stage not in NOT_GEOMETRY) for r in found), 3)
        row["nrmse_db"] = round(_nrmse_db(fused["raw"], ref["raw"]), 1)
        row["bit_identical"] = bool(np.array_equal(fused["raw"], ref["raw"]))
        row["counts_equal"] = fused["counts"] == ref["counts"]
        row["overflow_rows"] = fused["overflow"]
        for stage in ref["stages"]:
            r = statistics.median(x["stages"].get(stage, 0.0) for x in runs["reference"])
            f = statistics.median(x["stages"].get(stage, 0.0) for x in runs["fused"])
            row[f"{stage}_ratio"] = round(f / r, 3) if r > 0 else None
        rows.append(row)
    return report_rows(NAME + ".csv", rows)


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    out = []
    for row in rows:
        out.append((f"fused raw data of {row['scene']} within {NRMSE_BOUND_DB:g} dB of the reference's",
                    row["nrmse_db"] <= NRMSE_BOUND_DB, f"{row['nrmse_db']} dB, bit identical: {row['bit_identical']}"))
        out.append((f"chains, lit pieces and lanes of {row['scene']} equal to the reference's", row["counts_equal"],
                    f"overflow rows {row['overflow_rows']}, trace {row['trace_ratio']}x the reference's"))
    return out


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban, traffic and bistatic urban only (no Munich)")
