"""Benchmark: Munich in seconds (issues 12 and 56), every figure measured in one run.

1. **Unit of work**: bare Mitsuba casting 279 M closest-hit rays on Sionna's Munich, the primary
   rays of per-pulse tracing before issue 12 (every pulse aims one ray at each lattice cell of its
   beam), cast as that tracer cast them: ``scene.ray_intersect(ray, RayFlags.Minimal,
   coherent=False)``. Timed on the rays of 64 pulses spread over the aperture (about 3 M) and
   scaled to 279 M. Embree alone (``ray_intersect_preliminary``, no surface interaction) is timed
   on the same rays for comparison.
2. **The default render**, ``python -m sarmitsuba render sionna:munich --max-depth 3``
   (:data:`MAX_DEPTH`), start to end in a subprocess, twice back to back (issue 56): first with
   an empty Dr.Jit kernel cache (a fresh ``DRJIT_CACHE_DIR``, the variable Dr.Jit 1.5 reads
   before ``$HOME/.drjit``: every kernel compiles, as on the first run after an install), then
   warm (the same cache, now filled). Wall seconds of both (also in units), the kernels the first
   run compiled (files in the cache), and the warm run's peak memory (the process's maximum
   resident set).
3. **The reference render**: every pulse traced on its own and direct backprojection
   (``--integrator-set pulses_per_trace=1 --focuser bp``), seconds and memory, and the image
   NRMSE between the default and the reference, ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB].
4. ``sarmitsuba info``'s estimate of trace and focus time (no tracing) against the render's.
5. **Backprojection against omega-K** on the default render's raw data (both warm, best of two):
   fast factorised backprojection (the render's focuser) and direct backprojection, on the
   render's ground grid, against omega-K on its slant grid.
6. The same on the built-in ``urban`` scene (no unit of work: it is Munich's).

Memory before issue 12 (commit c4b9c92, the same command, measured with GNU time): 1,136 MB
(:data:`MEMORY_BEFORE_MB`); its render took 168 s on the same machine.

7. **The floor** (issue 56): the default render's casts at the unit's bare rates (closest-hit casts
   at ``ray_intersect``'s, visibility casts at ``ray_test``'s, timed on the same rays) plus its
   seconds outside the trace (process start, load, focus, products), in units: what the render
   would take were all its host geometry free.

Writes ``munich.csv`` (in the output folder, ``_table.output_dir``). Needs Sionna RT (``pip install sionna-rt``); ``--quick``:
urban only; ``--floor``: Munich's unit, one warm render and the floor only (minutes);
``--scaling``: the default render pinned to one core and on every core, the serial fraction
(Amdahl) and its projection to 8, 16 and 64 cores, the raw data's bits, and urban with workers
allowed against one process (about 6 minutes; writes ``munich_scaling.csv``).
Usage: ``python benchmarks/munich.py [--quick | --floor | --scaling]``
"""
from __future__ import annotations

import gc
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import sarmitsuba  # noqa: F401
from _table import bench_main, machine, write_csv
from ffbp import OMEGA_K_BOUND

NAME = "munich"
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3
#: Closest-hit casts of the unit of work (the primary rays of per-pulse tracing before issue 12).
UNIT_RAYS = 279e6
#: Peak memory of the Munich default render before issue 12 [MB] (commit c4b9c92, GNU time).
MEMORY_BEFORE_MB = 1136.0
#: Pulses whose primary rays are timed for the unit.
UNIT_PULSES = 64

#: Runs a CLI command and prints the process's peak resident memory [MB] on exit: VmHWM of
#: /proc/self/status (getrusage's ru_maxrss would carry the parent's peak across fork and exec).
_PROFILED = ("import atexit, re, runpy, sys; sys.argv = ['sarmitsuba'] + sys.argv[1:]; "
             "atexit.register(lambda: print('peak_rss_mb', int(re.search(r'VmHWM:\\s+(\\d+)', "
             "open('/proc/self/status').read()).group(1)) / 1024)); "
             "runpy.run_module('sarmitsuba', run_name='__main__')")


def unit_of_work(scene: str = "sionna:munich") -> dict:
    """Seconds to cast :data:`UNIT_RAYS` primary rays of per-pulse tracing, as ``ray_intersect``
    (Minimal) and as Embree alone; best of three each."""
    import drjit as dr
    import mitsuba as mi

    from sarmitsuba.scene import planning
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.loader import load_scene
    loaded = load_scene(scene)
    p = loaded.params
    geometry = acquisition_geometry(p)
    fp = planning.ray_footprint(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
    origins, directions = [], []
    for q in np.linspace(0, geometry.positions.shape[0] - 1, UNIT_PULSES).astype(int):
        i, j = np.meshgrid(fp.k0[q] + np.arange(fp.n_azimuth), np.arange(fp.n_range), indexing="ij")
        along = ((i + 0.5) * fp.spacing_azimuth).reshape(-1)
        aim = fp.origin + along[:, None] * fp.track + ((j + 0.5) * fp.spacing_range + fp.range_min).reshape(-1)[:, None] * fp.look
        v = aim - geometry.positions[q]
        r = np.linalg.norm(v, axis=1)
        d = v / r[:, None]
        sine = d @ fp.track
        keep = ((sine >= p.beam_sines[0]) & (sine <= p.beam_sines[1])
                & (along >= fp.along_limits[q, 0]) & (along <= fp.along_limits[q, 1]))
        origins.append(geometry.positions[q] + d[keep] * (r[keep, None] - 500.0))
        directions.append(d[keep])
    o, d = np.concatenate(origins), np.concatenate(directions)
    ray = mi.Ray3f(mi.Point3f(*(o[:, c].astype(np.float32) for c in range(3))),
                   mi.Vector3f(*(d[:, c].astype(np.float32) for c in range(3))))
    seconds = {}
    for name, cast in (("ray_intersect", lambda: loaded.scene.ray_intersect(ray, mi.RayFlags.Minimal, False).t),
                       ("embree", lambda: loaded.scene.ray_intersect_preliminary(ray, coherent=False).t),
                       ("ray_test", lambda: loaded.scene.ray_test(ray))):
        best = float("inf")
        for _ in range(3):
            start = time.perf_counter()
            dr.eval(cast())
            dr.sync_thread()
            best = min(best, time.perf_counter() - start)
        seconds[name] = best * UNIT_RAYS / o.shape[0]
    del loaded, ray
    gc.collect()
    return {"unit_s": seconds["ray_intersect"], "embree_unit_s": seconds["embree"], "test_unit_s": seconds["ray_test"],
            "unit_sample_rays": o.shape[0]}


def floor(unit: dict, default: dict) -> dict:
    """What a render would take with its host geometry free (issue 56's closing note): its casts at
    the unit's bare rates (closest-hit casts at ``ray_intersect``'s, visibility casts at
    ``ray_test``'s) plus every stage but the trace (process start, load, focus, products), in
    units. The half-unit target is out of reach while this alone exceeds it."""
    summary, seconds = default["summary"], default["seconds"]
    closest, shadow = float(sum(summary["rays_per_order"])), float(summary["shadow_rays"])
    casts_s = (closest * unit["unit_s"] + shadow * unit["test_unit_s"]) / UNIT_RAYS
    outside_s = seconds - default["timings"]["trace"]
    return {"casts_units": round(casts_s / unit["unit_s"], 3), "outside_trace_units": round(outside_s / unit["unit_s"], 3),
            "floor_units": round((casts_s + outside_s) / unit["unit_s"], 3)}


def render(scene: str, out: Path, *args: str, kernel_cache: Path | None = None, pin: str | None = None,
           env: dict | None = None) -> dict:
    """``sarmitsuba render`` in a subprocess (``--max-depth`` :data:`MAX_DEPTH`): wall seconds, CPU
    seconds (the process and its workers), peak memory [MB] (the render process's own), summary.json.
    ``kernel_cache``: Dr.Jit's kernel cache folder for the run (``DRJIT_CACHE_DIR``; default: the
    user's, ``~/.drjit``); ``pin``: the cores to pin it to (``taskset -c``); ``env``: variables to set."""
    import resource
    env = {**os.environ, **(env or {})}
    if kernel_cache is not None:
        env["DRJIT_CACHE_DIR"] = str(kernel_cache)
    command = [sys.executable, "-c", _PROFILED, "render", scene, "--out", str(out), "--no-progress",
               "--max-depth", str(MAX_DEPTH), *args]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run((["taskset", "-c", pin] if pin else []) + command, capture_output=True, text=True,
                          check=True, env=env)
    seconds = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    peak = float(next(line.split()[1] for line in done.stdout.splitlines() if line.startswith("peak_rss_mb")))
    summary = json.loads((out / "summary.json").read_text())
    return {"seconds": seconds, "cpu_s": cpu, "peak_mb": peak, "timings": summary["timings"], "summary": summary}


def nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB]."""
    return float(10.0 * np.log10(np.sum(np.abs(a - b) ** 2) / np.sum(np.abs(b) ** 2)))


def focusing(raw_path: Path) -> dict:
    """Fast and direct backprojection of a render's raw data onto its ground grid, and omega-K on
    its slant grid: seconds (best of two, after a warm-up), the fast image's NRMSE against direct."""
    from sarmitsuba.pipeline import refocus
    from sarmitsuba.core.raw import RawData
    raw = RawData.load(raw_path)
    out, images = {}, {}
    for name in ("omegak", "ffbp", "bp"):
        refocus(raw, name, window_range="taylor", window_azimuth="taylor")          # warm-up
        best = float("inf")
        for _ in range(1 if name == "bp" else 2):
            start = time.perf_counter()
            images[name] = refocus(raw, name, window_range="taylor", window_azimuth="taylor").data
            best = min(best, time.perf_counter() - start)
        out[f"{name}_s"] = best
    out["ffbp_nrmse_db"] = nrmse_db(images["ffbp"], images["bp"])
    return out


def scene_rows(scene: str, folder: Path, with_unit: bool) -> list[dict]:
    """The default and reference renders of one scene, their NRMSE, and (Munich) the unit and focusing."""
    from sarmitsuba.core.image import SarImage
    cache = folder / "drjit_cache"                       # empty: the first render compiles every kernel
    cache.mkdir(parents=True)
    first = render(scene, folder / "first", kernel_cache=cache)
    kernels = sum(1 for _ in cache.iterdir())
    default = render(scene, folder / "default", kernel_cache=cache)     # warm, back to back
    reference = render(scene, folder / "reference", "--integrator-set", "pulses_per_trace=1", "--focuser", "bp")
    error = nrmse_db(SarImage.load(folder / "default" / "image.npz").data,
                     SarImage.load(folder / "reference" / "image.npz").data)
    row = {"scene": scene, "first_render_s": round(first["seconds"], 2), "kernels_compiled": kernels,
           "render_s": round(default["seconds"], 2), "peak_mb": round(default["peak_mb"]),
           **{f"{k}_s": round(v, 2) for k, v in default["timings"].items() if k != "total"},
           "pulses_per_trace": default["summary"]["pulses_per_trace"],
           "pulse_paths_per_s": default["summary"].get("pulse_paths_per_second"),
           "reference_render_s": round(reference["seconds"], 2), "reference_peak_mb": round(reference["peak_mb"]),
           "nrmse_vs_reference_db": round(error, 1)}
    from sarmitsuba.info import scene_info
    estimate = scene_info(scene, integrator_overrides={"max_depth": MAX_DEPTH}).cost
    measured = default["timings"]["trace"] + default["timings"]["focus"]
    row.update({"info_trace_focus_s": round(estimate.trace_time_s + estimate.focus_time_s, 2),
                "info_over_measured": round((estimate.trace_time_s + estimate.focus_time_s) / measured, 2)})
    focus = focusing(folder / "default" / "raw.npz")
    row.update({k: round(v, 2) for k, v in focus.items()})
    row["ffbp_over_omegak"] = round(focus["ffbp_s"] / focus["omegak_s"], 1)
    if with_unit:
        unit = unit_of_work(scene)
        row.update({k: round(v, 2) if isinstance(v, float) else v for k, v in unit.items()})
        row["render_units"] = round(default["seconds"] / unit["unit_s"], 3)
        row["first_render_units"] = round(first["seconds"] / unit["unit_s"], 3)
        row["render_embree_units"] = round(default["seconds"] / unit["embree_unit_s"], 3)
        row.update(floor(unit, default))
    return [row]


def floor_rows(scene: str = "sionna:munich") -> list[dict]:
    """``--floor``: the unit and one warm default render only (minutes): the render in units and
    :func:`floor`."""
    with tempfile.TemporaryDirectory() as tmp:
        render(scene, Path(tmp) / "warm-up")
        default = render(scene, Path(tmp) / "default")
    unit = unit_of_work(scene)
    row = {"scene": scene, "render_s": round(default["seconds"], 2),
           **{f"{k}_s": round(v, 2) for k, v in default["timings"].items() if k != "total"},
           "rays_per_order": default["summary"]["rays_per_order"],
           "shadow_rays": default["summary"]["shadow_rays"],
           **{k: round(v, 2) if isinstance(v, float) else v for k, v in unit.items()},
           "render_units": round(default["seconds"] / unit["unit_s"], 3), **floor(unit, default)}
    print("  ".join(f"{k}={v}" for k, v in row.items()))
    return [row]


#: The default render's targets, in units of the bare cast timed in the same run (warm), and the
#: first run's (empty kernel cache) over the warm run's.
WARM_UNITS, FIRST_OVER_WARM = 3.5, 1.2
#: The floor's target (the render's casts at the bare rates plus its seconds outside the trace).
FLOOR_UNITS = 1.0
#: ``--scaling``: the trace on two cores over one (serial fraction at most 8 %), urban's render
#: with workers allowed over one process, and the core counts of the projection.
SPEEDUP_2, URBAN_RATIO, PROJECTED_CORES = 1.85, 1.1, (8, 16, 64)


def amdahl(one: float, two: float) -> dict:
    """The serial fraction ``f`` that a speed-up ``S = one / two`` on two cores implies
    (Amdahl: ``S = 1 / (f + (1 - f) / 2)``, so ``f = 2 / S - 1``), and the trace seconds it
    projects at :data:`PROJECTED_CORES`, ``one (f + (1 - f) / n)``."""
    speedup = one / two
    f = 2.0 / speedup - 1.0
    return {"speedup_2": round(speedup, 3), "serial_fraction": round(f, 3),
            **{f"projected_trace_{n}_s": round(one * (f + (1.0 - f) / n), 1) for n in PROJECTED_CORES}}


def scaling_rows(scene: str = "sionna:munich") -> list[dict]:
    """``--scaling``: the default render pinned to one core and on every core, back to back after
    a warm-up (the kernel cache filled), with its trace and CPU seconds, the serial fraction and
    projection (:func:`amdahl`), whether the raw data are equal bit for bit, the render in units;
    and urban's render with workers allowed against one process (``SARMITSUBA_WORKERS=1``)."""
    from sarmitsuba.core.raw import RawData
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        render(scene, folder / "warm-up")
        one = render(scene, folder / "one", pin="0")
        every = render(scene, folder / "every")
        same = bool(np.array_equal(RawData.load(folder / "one" / "raw.npz").data,
                                   RawData.load(folder / "every" / "raw.npz").data))
        render("urban", folder / "urban-warm-up")
        urban_one, urban = float("inf"), float("inf")
        for k in range(3):                   # alternated, best of three each: a render's time scatters 15 %
            urban_one = min(urban_one, render("urban", folder / f"urban-one{k}",
                                              env={"SARMITSUBA_WORKERS": "1"})["seconds"])
            urban = min(urban, render("urban", folder / f"urban{k}")["seconds"])
    unit = unit_of_work(scene)
    row = {"scene": scene, "cores": os.cpu_count(), "load_average": round(os.getloadavg()[0], 2),
           "trace_1_s": round(one["timings"]["trace"], 2), "trace_2_s": round(every["timings"]["trace"], 2),
           "render_1_s": round(one["seconds"], 2), "render_2_s": round(every["seconds"], 2),
           "cpu_1_s": round(one["cpu_s"], 1), "cpu_2_s": round(every["cpu_s"], 1),
           "processes": every["summary"].get("workers", 1),
           **amdahl(one["timings"]["trace"], every["timings"]["trace"]),
           "raw_equal": same, "unit_s": round(unit["unit_s"], 2),
           "render_units": round(every["seconds"] / unit["unit_s"], 3),
           "urban_s": round(urban, 2), "urban_one_process_s": round(urban_one, 2),
           "urban_ratio": round(urban / urban_one, 3)}
    print("  ".join(f"{k}={v}" for k, v in row.items()))
    write_csv(f"{NAME}_scaling.csv", [row])
    return [row]


def scaling_checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The acceptance of ``--scaling``, as ratios of one run."""
    out = []
    for r in rows:
        out += [(f"{r['scene']}: trace on 2 cores >= {SPEEDUP_2}x its trace on one", r["speedup_2"] >= SPEEDUP_2,
                 f"{r['trace_1_s']} s / {r['trace_2_s']} s = {r['speedup_2']}x, serial fraction "
                 f"{r['serial_fraction']:.1%} ({r['processes']} processes)"),
                (f"{r['scene']}: default render <= {WARM_UNITS} units", r["render_units"] <= WARM_UNITS,
                 f"{r['render_2_s']} s = {r['render_units']} units of {r['unit_s']} s"),
                (f"{r['scene']}: raw data equal bit for bit on one core and on every core", r["raw_equal"], ""),
                (f"urban: render with workers allowed <= {URBAN_RATIO}x one process", r["urban_ratio"] <= URBAN_RATIO,
                 f"{r['urban_s']} s against {r['urban_one_process_s']} s (best of three each, alternated)")]
    return out


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Issues 12's and 56's acceptance, as ratios of this run."""
    out = []
    for row in rows:
        scene = row["scene"]
        if "info_over_measured" in row:                  # (not in --floor's row)
            out.append((f"{scene}: info's trace + focus estimate within a factor 2 of the render's",
                        bool(0.5 <= row["info_over_measured"] <= 2.0), f"estimate / measured = {row['info_over_measured']}"))
            out.append((f"{scene}: image NRMSE against per-pulse tracing and direct backprojection <= -30 dB",
                        bool(row["nrmse_vs_reference_db"] <= -30.0), f"{row['nrmse_vs_reference_db']} dB"))
        if "render_units" in row and "first_render_units" in row:
            out.append((f"{scene}: default render, first run (empty kernel cache) <= {FIRST_OVER_WARM:g}x the warm run",
                        bool(row["first_render_s"] <= FIRST_OVER_WARM * row["render_s"]),
                        f"{row['first_render_s']} s against {row['render_s']} s = {row['first_render_units']} units "
                        f"of {row['unit_s']} s, {row['kernels_compiled']} kernels compiled"))
        if "render_units" in row:
            out.append((f"{scene}: default render, warm <= {WARM_UNITS:g} units", bool(row["render_units"] <= WARM_UNITS),
                        f"{row['render_s']} s = {row['render_units']} units of {row['unit_s']} s "
                        f"({row['render_embree_units']} Embree-only units of {row['embree_unit_s']} s)"
                        if "render_embree_units" in row else f"{row['render_s']} s = {row['render_units']} units"))
            out.append((f"{scene}: its casts at the bare rates plus the stages outside the trace <= {FLOOR_UNITS:g} units",
                        bool(row["floor_units"] <= FLOOR_UNITS),
                        f"{row['floor_units']} units = casts {row['casts_units']} + outside the trace "
                        f"{row['outside_trace_units']}"))
        if "ffbp_over_omegak" in row and "render_units" in row:
            out.append((f"{scene}: backprojection <= {OMEGA_K_BOUND:g}x omega-K", bool(row["ffbp_over_omegak"] <= OMEGA_K_BOUND),
                        f"ffbp {row['ffbp_s']} s, omega-K {row['omegak_s']} s, direct {row['bp_s']} s"))
            out.append((f"{scene}: peak memory <= before issue 12 ({MEMORY_BEFORE_MB:.0f} MB)",
                        bool(row["peak_mb"] <= MEMORY_BEFORE_MB), f"{row['peak_mb']} MB"))
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Run the renders and timings, print and write the table; returns the rows."""
    print(machine())
    scenes = ["urban"] if quick or tiny or importlib.util.find_spec("sionna") is None else ["sionna:munich", "urban"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes:
            rows += scene_rows(scene, Path(tmp) / scene.replace(":", "_"), with_unit=scene == "sionna:munich")
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    write_csv(f"{NAME}.csv", rows)
    return rows


if __name__ == "__main__":
    if sys.argv[1:] == ["--scaling"]:
        print(machine())
        for check, ok, detail in scaling_checks(scaling_rows()):
            print(f"{'PASS' if ok else 'FAIL'}  {check}  {detail}")
    elif sys.argv[1:] == ["--floor"]:
        for check, ok, detail in checks(floor_rows()):
            print(f"{'PASS' if ok else 'FAIL'}  {check}  {detail}")
    else:
        bench_main(__doc__, run, checks, "urban only")
