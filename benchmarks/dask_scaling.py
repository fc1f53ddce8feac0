"""Benchmark: tracing on Dask (``render --scheduler``) against one process, on this machine (issue 17).

For the built-in ``urban`` scene (default pulses; ``--quick``: 256 pulses; ``--tiny``: the
trihedral, 32 pulses) it measures, in one run, the trace seconds of

* one process (the default: Dr.Jit's LLVM backend already uses every core);
* a Dask ``LocalCluster`` of 1 and of 2 worker processes (``scheduler="local"``), each worker
  loading the scene once (its load and kernel compilation are inside the trace time, since a
  fresh cluster starts for every run), cluster start-up included in ``total_s``;
* a running 2-worker cluster (started beforehand, reached by its ``tcp://`` address as
  ``--scheduler tcp://HOST:PORT`` would), twice: cold (each worker loads the scene and compiles
  its kernel) and warm (the workers kept the scene from the cold run: tracing and transfer only);

and the raw data's NRMSE against the one-process run, ``10 log10(sum |a - b|^2 / sum |b|^2)``
[dB]. The speed-up a cluster can give depends on the cores it adds: on a 2-core machine two
local workers share the cores the one process already used, so this measures what the
distribution costs; on a cluster of machines each worker adds its own cores.

Writes ``dask_scaling.csv`` (in the output folder, ``_table.output_dir``).

Usage: ``python benchmarks/dask_scaling.py [--quick] [--tiny]``
"""
from __future__ import annotations

import gc
import time

import numpy as np

import sarmitsuba  # noqa: F401
from _table import bench_main, machine, write_csv
from sarmitsuba.tracing.driver import distributed
from sarmitsuba.pipeline import simulate

NAME = "dask_scaling"
#: The integrator overrides of every render here: ``max_depth`` 3, the default render's depth
#: before ``max_depth = auto``, so that the speed figures stay comparable (``bounce_depth``
#: measures ``auto``).
INTEGRATOR = {"max_depth": 3}


def nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB] (-inf when identical)."""
    error = float(np.sum(np.abs(a - b) ** 2))
    return 10.0 * np.log10(error / float(np.sum(np.abs(b) ** 2))) if error > 0 else float("-inf")


def _one(scene: str, sensor: dict, workers: int | str | None) -> tuple[dict, np.ndarray]:
    """One simulation (``workers`` None: one process; int: a fresh LocalCluster of that many;
    str: the running cluster at that address), its seconds and raw samples."""
    start = time.perf_counter()
    if workers is None:
        sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=INTEGRATOR)
    elif isinstance(workers, str):
        sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=INTEGRATOR, scheduler=workers)
    else:
        distributed.LOCAL_WORKERS = workers
        sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=INTEGRATOR, scheduler="local")
    total = time.perf_counter() - start
    setting = ("one process" if workers is None else f"LocalCluster, {workers} worker(s)" if isinstance(workers, int)
               else "running cluster, 2 workers")
    row = {"scene": scene, "pulses": sim.raw.n_pulses, "setting": setting, "trace_s": round(sim.timings["trace"], 3),
           "total_s": round(total, 3)}
    data = sim.raw.data.copy()
    del sim
    gc.collect()
    return row, data


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Measure the settings, print and write the table; returns the rows."""
    print(machine())
    scene, sensor = ("trihedral", {"n_pulses": 32}) if tiny else ("urban", {"n_pulses": 256} if quick else {})
    simulate(scene, sensor_overrides=sensor, integrator_overrides=INTEGRATOR)   # warm-up: kernel compilation in this process
    gc.collect()
    saved = distributed.LOCAL_WORKERS
    rows, reference = [], None
    try:
        for workers in (None, 1, 2):
            row, data = _one(scene, sensor, workers)
            reference = data if reference is None else reference
            row["nrmse_db"] = round(nrmse_db(data, reference), 1)
            rows.append(row)
        from distributed import LocalCluster
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            for state in ("cold", "warm"):
                row, data = _one(scene, sensor, cluster.scheduler_address)
                row["setting"] += f", {state}"
                row["nrmse_db"] = round(nrmse_db(data, reference), 1)
                rows.append(row)
    finally:
        distributed.LOCAL_WORKERS = saved
    for row in rows:
        row["trace_speedup"] = round(rows[0]["trace_s"] / row["trace_s"], 3)
        row["total_speedup"] = round(rows[0]["total_s"] / row["total_s"], 3)
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    write_csv(f"{NAME}{'_tiny' if tiny else ''}.csv", rows)
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The Dask runs give the one-process raw data (NRMSE <= -100 dB)."""
    return [(f"{r['setting']}: raw data as one process", r["nrmse_db"] <= -100.0, f"NRMSE {r['nrmse_db']} dB")
            for r in rows[1:]]


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban, 256 pulses", "trihedral, 32 pulses (smoke test)")
