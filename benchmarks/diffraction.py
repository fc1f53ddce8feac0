"""Benchmark: what edge diffraction costs and what it changes (issue 54), in one run.

For the built-in ``urban`` scene and Sionna's Munich (512 central pulses; skipped without
Sionna RT or with ``--quick``), each rendered warm with ``sbr`` ``diffraction`` true and false,
alternately, best of two each:

* **seconds**: the trace and the whole render, and their ratio (the issue's bound for switching
  it on by default: at most 1.2 times the render time without it);
* **what it changes**: the image NRMSE of PO alone against PO plus edge currents,
  ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB], and the share of the diffraction's power
  (the image difference) that the bounce orders after the first carry: edges lit through a
  mirror (a roof edge in the ground's mirror), per order, from ``split_bounces``.

Writes ``diffraction.csv`` in the output folder (``_table.output_dir``).
Usage: ``python benchmarks/diffraction.py [--quick]``
"""
from __future__ import annotations

import gc
import importlib.util
import math
import time

import numpy as np

import sarmitsuba  # noqa: F401
from _table import bench_main, machine, write_csv
from sarmitsuba.pipeline import simulate

NAME = "diffraction"


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    return 10.0 * math.log10(float(np.sum(np.abs(a - b) ** 2)) / max(float(np.sum(np.abs(b) ** 2)), 1e-300))


def _render(source: str, diffraction: bool, pulses: int | None):
    sensor = {"n_pulses": pulses} if pulses else None
    start = time.perf_counter()
    sim = simulate(source, sensor_overrides=sensor,
                   integrator_overrides={"diffraction": diffraction, "split_bounces": True})
    total = time.perf_counter() - start
    return sim, total, float(sim.timings.get("trace", float("nan")))


def measure(source: str, pulses: int | None = None) -> dict:
    """Seconds with and without diffraction (best of two, alternating), the image change and the
    share of the diffraction's power per bounce order."""
    times = {True: [], False: []}
    sims = {}
    for _ in range(2):
        for on in (True, False):
            sim, total, trace = _render(source, on, pulses)
            times[on].append((total, trace))
            sims[on] = sim
            gc.collect()
    (t_on, tr_on), (t_off, tr_off) = (min(times[k]) for k in (True, False))
    on, off = sims[True], sims[False]
    row = dict(scene=source, pulses=int(on.raw.data.shape[0]), render_on_s=round(t_on, 2), render_off_s=round(t_off, 2),
               render_ratio=round(t_on / t_off, 3), trace_on_s=round(tr_on, 2), trace_off_s=round(tr_off, 2),
               image_change_db=round(_nrmse_db(off.image.data, on.image.data), 1))
    powers = [float(np.sum(np.abs(a.data - b.data) ** 2)) for a, b in zip(on.images_per_order, off.images_per_order)]
    total = sum(powers) or 1.0
    for k, p in enumerate(powers, start=1):
        row[f"order{k}_share_db"] = round(10 * math.log10(max(p / total, 1e-30)), 1)
    return row


def run(quick: bool = False) -> list[dict]:
    """Measure, print and write the rows."""
    print(machine())
    rows = [measure("urban")]
    if not quick and importlib.util.find_spec("sionna") is not None:
        rows.append(measure("sionna:munich", pulses=512))
    for row in rows:
        print(row)
    write_csv(f"{NAME}.csv", rows)
    return rows


def checks(rows):
    """The issue's bound for switching diffraction on by default."""
    for row in rows:
        yield (f"{row['scene']}: render with diffraction <= 1.2 x without", row["render_ratio"] <= 1.2,
               f"{row['render_on_s']} s / {row['render_off_s']} s = {row['render_ratio']}")


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban only (no Munich)")
