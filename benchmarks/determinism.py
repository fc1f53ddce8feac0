"""Benchmark: renders that repeat bit for bit, and what the fixed-point sums cost (docs/physics.md (D7)).

Every sum of the tracer is formed in 128-bit fixed point, so the same render gives the same bits
whatever the threads' timing. Measured in one run:

1. **Cost**: the default render of Sionna's Munich (not with ``--quick``) and of the built-in
   ``urban`` (every surface rough: a clutter scatterer deposited per cell and pulse), their
   trace seconds with the fixed-point sums against the float32 atomic adds they replaced
   (:class:`FloatSums`, the deposit as it was: kept here only as the baseline), alternately,
   ``REPEATS`` times each after one untimed run of each, in this process; the ratio of the
   medians. The check bounds Munich's (the issue's scene), or urban's without Sionna.
2. **Repeats**: ``urban`` rendered ``RUNS`` times while another render (``sarmitsuba render
   urban`` in a subprocess, restarted as it ends) loads the machine: the distinct raw data and
   images among them (1: bit for bit), and the float32 sums' own spread over two runs for
   comparison.
3. **Agreement**: ``urban`` on 1 and on 2 Dr.Jit threads (``dr.set_thread_count``), with one
   launch at a time and with two (``SARMITSUBA_HOST_THREADS``), and traced on a Dask
   ``LocalCluster`` of two workers: raw-data NRMSE against the default render,
   ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB], and whether the bits are the same.

Writes ``determinism.csv`` (in the output folder, ``_table.output_dir``).
Usage: ``python benchmarks/determinism.py [--quick]``
"""
from __future__ import annotations

import contextlib
import gc
import hashlib
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
import threading

import numpy as np

import sarmitsuba  # noqa: F401
import drjit as dr
import mitsuba as mi
from _table import bench_main, machine, write_csv
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.deposit.accumulate import Accumulator, histogram_floats
from sarmitsuba.tracing.driver import distributed
from sarmitsuba.tracing.driver.threads import HOST_THREADS_VARIABLE
from sarmitsuba.tracing.integration import returns

NAME = "determinism"
#: Timed renders of each kind (fixed point, float32) for the cost.
REPEATS = 2
#: Renders of urban under load for the repeats.
RUNS = 10
#: The fixed point's trace time may exceed the float32 sums' by this factor at most (the issue's bound).
COST_BOUND = 1.05
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


class FloatSums(Accumulator):
    """The deposit before fixed point: float32 ``(re, im)`` packets and float32 tallies,
    scatter-added with atomics (or per thread copy, ``ReduceMode.Expand``). Its sums' last bits
    follow the threads' timing; kept as the baseline of the cost only."""

    def open(self, ctx: dict) -> None:
        super().open(ctx)
        if not self.exact:
            ctx["hist"] = dr.zeros(mi.Float, histogram_floats(2 * ctx["hist_entries"]))

    def add(self, ctx, re, im, index, active) -> None:
        dr.scatter_add(ctx["hist"], mi.Array2f(re, im), index, active, mode=self.reduce)

    @staticmethod
    def read_histogram(ctx: dict) -> np.ndarray:
        return ctx["hist"].numpy()[:2 * ctx["hist_entries"]].view(np.complex64).copy()

    def order_done(self, ctx: dict, depth: int) -> None:
        if self.snapshots:
            ctx["orders_read"][depth] = self.read_histogram(ctx)
            ctx["hist"] = dr.zeros(mi.Float, dr.width(ctx["hist"]))

    @staticmethod
    def tallies(max_depth: int) -> dict:
        return dict(energy=dr.zeros(mi.Float, max_depth + 1), carried=dr.zeros(mi.Float, max_depth))

    def tally(self, ctx: dict, name: str, value, slot, active) -> None:
        dr.scatter_add(ctx[name], dr.detach(value), mi.UInt32(slot), active, mode=ctx["tally"])

    @staticmethod
    def read_tallies(ctx: dict) -> dict:
        return {name: ctx[name].numpy().astype(np.float64) for name in ("energy", "carried")}


@contextlib.contextmanager
def float_sums():
    """Renders in this block deposit with :class:`FloatSums`."""
    saved = returns.Accumulator
    returns.Accumulator = FloatSums
    try:
        yield
    finally:
        returns.Accumulator = saved


def nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB] (-inf when identical)."""
    error = float(np.sum(np.abs(a.astype(np.complex128) - b) ** 2))
    return 10.0 * np.log10(error / float(np.sum(np.abs(b.astype(np.complex128)) ** 2))) if error > 0 else float("-inf")


def _digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def _render(scene: str, **kwargs) -> tuple[float, np.ndarray, np.ndarray]:
    """Trace seconds, raw data and image of one in-memory render (``max_depth`` :data:`MAX_DEPTH`)."""
    sim = simulate(scene, integrator_overrides={"max_depth": MAX_DEPTH}, **kwargs)
    out = (sim.timings["trace"], sim.raw.data.copy(), sim.image.data.copy())
    del sim
    gc.collect()
    return out


def cost(scene: str) -> list[dict]:
    """The trace seconds of ``scene``'s default render with fixed-point and with float32 sums."""
    kinds = {"fixed point": contextlib.nullcontext, "float32 atomics": float_sums}
    for make in kinds.values():                       # untimed: each kind's kernels compiled
        with make():
            _render(scene)
    seconds = {kind: [] for kind in kinds}
    for _ in range(REPEATS):
        for kind, make in kinds.items():
            with make():
                seconds[kind].append(_render(scene)[0])
    base = statistics.median(seconds["float32 atomics"])
    return [{"part": "cost", "scene": scene, "setting": kind, "trace_s": round(statistics.median(times), 2),
             "runs": len(times), "ratio": round(statistics.median(times) / base, 4), "distinct": "",
             "nrmse_db": ""} for kind, times in seconds.items()]


@contextlib.contextmanager
def _load(scene: str):
    """Another render of ``scene`` running beside the block, restarted until the block ends."""
    stop = threading.Event()

    def loop():
        with tempfile.TemporaryDirectory() as out:
            while not stop.is_set():
                subprocess.run([sys.executable, "-m", "sarmitsuba", "render", scene, "--out", out, "--no-progress",
                                "--max-depth", str(MAX_DEPTH)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    worker = threading.Thread(target=loop, daemon=True)
    worker.start()
    try:
        yield
    finally:
        stop.set()
        worker.join()


def repeats(runs: int) -> list[dict]:
    """``urban`` ``runs`` times under load: distinct results; and float32 sums twice."""
    with _load("urban"):
        digests = [_digest(*_render("urban")[1:]) for _ in range(runs)]
    with float_sums():
        floats = [_render("urban")[1:] for _ in range(2)]
    return [{"part": "repeats", "scene": "urban", "setting": f"fixed point, {runs} runs under load", "trace_s": "",
             "runs": runs, "ratio": "", "distinct": len(set(digests)), "nrmse_db": float("-inf")},
            {"part": "repeats", "scene": "urban", "setting": "float32 atomics, 2 runs", "trace_s": "", "runs": 2,
             "ratio": "", "distinct": len({_digest(*f) for f in floats}),
             "nrmse_db": round(nrmse_db(floats[1][0], floats[0][0]), 1)}]


def agreement() -> list[dict]:
    """``urban`` under other thread counts and on Dask against the default render."""
    _, raw, image = _render("urban")
    rows = []

    def row(setting, data):
        rows.append({"part": "agreement", "scene": "urban", "setting": setting, "trace_s": "", "runs": 1,
                     "ratio": "", "distinct": 1 if np.array_equal(data, raw) else 2,
                     "nrmse_db": round(nrmse_db(data, raw), 1)})
    before = dr.thread_count()
    try:
        dr.set_thread_count(1)
        row("1 Dr.Jit thread", _render("urban")[1])
    finally:
        dr.set_thread_count(before)
    saved = os.environ.get(HOST_THREADS_VARIABLE)
    os.environ[HOST_THREADS_VARIABLE] = "1"
    try:
        row("one launch at a time", _render("urban")[1])
    finally:
        os.environ.pop(HOST_THREADS_VARIABLE) if saved is None else os.environ.__setitem__(HOST_THREADS_VARIABLE, saved)
    if importlib.util.find_spec("distributed") is not None:
        workers = distributed.LOCAL_WORKERS
        distributed.LOCAL_WORKERS = 2
        try:
            row("Dask LocalCluster, 2 workers", _render("urban", scheduler="local")[1])
        finally:
            distributed.LOCAL_WORKERS = workers
    return rows


def run(quick: bool = False) -> list[dict]:
    """Measure the three parts, print and write the table; returns the rows."""
    print(machine())
    munich = importlib.util.find_spec("sionna") is not None and not quick
    rows = [*(cost("sionna:munich") if munich else []), *cost("urban"), *repeats(3 if quick else RUNS), *agreement()]
    for r in rows:
        print("  ".join(f"{k}={v}" for k, v in r.items()))
    write_csv(f"{NAME}.csv", rows)
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The fixed point within :data:`COST_BOUND` of the float32 sums' trace time; repeats bit for bit;
    1 and 2 Dr.Jit threads bit for bit; every other setting within -120 dB."""
    out = []
    fixed = next(r for r in rows if r["setting"] == "fixed point")      # Munich where measured, else urban
    out.append((f"fixed-point sums cost at most {COST_BOUND - 1:.0%} of the trace ({fixed['scene']})",
                fixed["ratio"] <= COST_BOUND, f"ratio {fixed['ratio']}"))
    same = next(r for r in rows if r["part"] == "repeats")
    out.append(("urban repeats bit for bit under load", same["distinct"] == 1, f"{same['distinct']} distinct results"))
    for r in rows:
        if r["part"] == "agreement":
            if r["setting"] == "1 Dr.Jit thread":
                out.append(("1 and 2 Dr.Jit threads bit for bit", r["distinct"] == 1, f"NRMSE {r['nrmse_db']} dB"))
            else:
                out.append((f"{r['setting']}: within -120 dB", r["nrmse_db"] <= -120.0, f"NRMSE {r['nrmse_db']} dB"))
    return out


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban for the cost, 3 repeats", None)
