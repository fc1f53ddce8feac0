"""The benchmark suite: what each fidelity knob costs and buys, measured in one run.

Runs, in order (each a module of this folder with ``run(quick) -> rows`` and, where it
asserts ratios, ``checks(rows)``):

============== =========================================================================
bounce_depth   max_depth 1..6 on the urban scene and Sionna's Munich: time, energy per
               order, image NRMSE against the deepest setting
range_kernel   nearest / linear / sinc / exact: PSLR, IRW and raw NRMSE against exact,
               against time
ray_density    rays per resolution cell: canonical-target RCS error and speckle statistics
               against time
focus          backprojection, omega-K, range-Doppler: point-target quality and time
scaling        time against buildings (1..1000), pulses and image size; the 16-building
               512 x 512 case against Franceschetti et al. (2003)
subaperture    pulses per trace 1..64 on urban and Munich: image NRMSE against per-pulse
               tracing (and the ray lattice's own), trace time, casts, returns
rims           where the ground merely stops: each free rim's intensity above the
               ground beside it, rims as truncations (default) and as edges
subaperture_orders
               the mesh tracer's automatic sub-aperture against per-pulse tracing on
               Munich: raw-data NRMSE by bounce order, each order's power share
ffbp           fast factorised backprojection's knobs: NRMSE against direct
               backprojection and seconds, omega-K's time in the same run
munich         Munich in seconds: default render in units of bare Mitsuba casting,
               memory, NRMSE against the per-pulse/direct reference,
               backprojection against omega-K, info's estimate against the render
polarimetry    VV, HH, HV and quad on urban and Munich: seconds, casts, quad's cost
               over single-channel renders, quad's HH and VV against the single ones
dask_scaling   tracing on a Dask LocalCluster of 1 and 2 workers against one process:
               trace seconds, speed-up, raw NRMSE against one process
invariance     what the tracer's lattices leave in the image: NRMSE against the default
               render with the ray lattice moved, with dense rays and with one pulse per
               trace, on urban, a smooth oblique block and Munich, with trace seconds
trajectory     what no stop-and-hop costs (trace, focus) and the error it removes (the
               v R / c shift, airborne and spaceborne); PGA against motion-error amplitude
footprints     Munich's meshes back to GeoJSON footprints and rebuilt: double-bounce and
               single-bounce overlap with the original, heights against the mesh tops,
               seconds of deriving, building, writing and rendering
diffraction    edge currents against the full-wave tables (plates' patterns and image RCS,
               a dihedral, a cube), and their cost and effect on urban and Munich
gradients      forward- and reverse-mode derivatives of urban against its forward render:
               seconds and peak memory
inverse        a brick building's permittivity and height recovered from its image by
               L-BFGS-B with the simulator's gradients, from 30 % off
inverse_city   the heights of ten buildings of a footprint city recovered from its image
               by L-BFGS-B with the simulator's geometric gradients, from 20 % off
moving         three moving cars on urban: the sub-apertures' rates (differenced, rigid)
               against one pulse per trace, and what motion costs over the still scene
bistatic       urban received on a drone and on a second aircraft: the sub-apertures
               against one pulse per trace, and what the receiver costs
determinism    renders that repeat bit for bit: the fixed-point sums' cost against float32
               atomic adds (Munich), urban repeated under load, other thread counts and Dask
fused          the fused geometry kernels against the NumPy stages on Munich, urban,
               traffic and bistatic urban: raw NRMSE, counts, seconds by stage
fused_kernels  each fused kernel against its reference on the calls of a Munich render,
               and the trace were every geometry stage as much faster
pga_sweep      phase gradient autofocus over sway periods 10-200 m and amplitudes 0.5-5 cm,
               with and without clutter, on FFBP, backprojection and omega-K
rough_city     rough surfaces: a rough plate's HH, VV and HV against the I2EM at 25-60 deg;
               Munich with the city preset: seconds against the smooth render, each class's
               median sigma nought against info's
tomography     stacks of 10 and 20 urban passes against single renders; a building's roof,
               facade and ground separated by beamforming and SL1MMER against the geometry;
               beamforming's and SL1MMER's two-point resolution
scatterers     the scatterer catalogue: seconds and peak memory with it over without (urban,
               Munich), and the share of Munich's 20 brightest pixels it explains
============== =========================================================================

Each writes ``<name>.csv`` and ``<name>.png`` into the output folder (``--out DIR``, default
``out/bench`` under the current directory) (accuracy against seconds, one
point per setting). The suite prints the machine, every table, and PASS/FAIL for the ratio
checks, writes ``checks.csv`` there (after each benchmark), and exits 1 if a check fails. It also writes
``machine.json`` there: the machine, the package versions, the UTC start and end of the run, the
command line, ``--quick`` or not, each benchmark's seconds and the git commit of the checkout. Absolute times
depend on the machine (and on what else runs on it); ratios measured in one run do not.

Usage: ``python benchmarks/run.py [--quick] [--only NAME ...] [--out DIR]`` or ``python -m sarmitsuba bench ...``.
"""
from __future__ import annotations

import argparse
import datetime
import importlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _table import machine, machine_info, output_dir, write_csv  # noqa: E402

#: Suite name -> module of this folder.
SUITE = {"bounce_depth": "bounce_depth", "range_kernel": "range_kernel", "ray_density": "ray_density",
         "focus": "focus_algorithms", "scaling": "scaling", "subaperture": "subaperture",
         "subaperture_orders": "subaperture_orders", "rims": "rims", "ffbp": "ffbp",
         "munich": "munich", "polarimetry": "polarimetry",
         "dask_scaling": "dask_scaling", "invariance": "invariance", "trajectory": "trajectory",
         "footprints": "footprints", "diffraction": "diffraction", "gradients": "gradients",
         "inverse": "inverse", "inverse_city": "inverse_city", "moving": "moving",
         "bistatic": "bistatic", "determinism": "determinism", "fused": "fused",
         "fused_kernels": "fused_kernels", "pga_sweep": "pga_sweep",
         "rough_city": "rough_city", "tomography": "tomography", "scatterers": "scatterers"}


def _utc_now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def _command_line(argv: list[str] | None) -> str:
    """The command as typed: ``python -m sarmitsuba bench ...`` or ``python benchmarks/run.py ...``."""
    args = sys.argv[1:] if argv is None else argv
    head = "python -m sarmitsuba bench" if Path(sys.argv[0]).name == "__main__.py" else "python benchmarks/run.py"
    return " ".join([head, *args])


def _git_commit() -> str | None:
    """The checkout's commit (with ``-dirty`` for uncommitted changes), ``None`` outside git."""
    try:
        return subprocess.run(["git", "describe", "--always", "--dirty", "--abbrev=12"], capture_output=True,
                              text=True, check=True, cwd=Path(__file__).resolve().parent).stdout.strip() or None
    except (OSError, subprocess.CalledProcessError):
        return None


def _write_run_info(info: dict) -> None:
    """Write ``machine.json`` (the machine, the command, the dates, each benchmark's seconds) into the output."""
    with open(output_dir() / "machine.json", "w") as f:
        json.dump(info, f, indent=1)
        f.write("\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="sarmitsuba bench", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small settings (about a minute per benchmark)")
    parser.add_argument("--only", nargs="+", choices=list(SUITE), default=None, metavar="NAME",
                        help=f"run only these ({', '.join(SUITE)})")
    parser.add_argument("--out", type=Path, default=Path("out") / "bench", metavar="DIR",
                        help="folder for the CSV tables, plots and checks.csv (default: out/bench in the current "
                             "directory)")
    args = parser.parse_args(argv)
    if args.out.exists() and not args.out.is_dir():
        parser.error(f"--out {args.out} is an existing file, not a directory: give a folder path")
    os.environ["SARMITSUBA_BENCH_OUT"] = str(args.out)
    print(machine())
    names = args.only or list(SUITE)
    run_info = {**machine_info(), "started_utc": _utc_now(), "finished_utc": None,
                "command": _command_line(argv), "quick": args.quick, "benchmarks": names,
                "seconds": {}, "commit": _git_commit()}
    _write_run_info(run_info)
    results = []
    start = time.perf_counter()
    for name in names:
        print(f"\n=== {name} ===")
        module = importlib.import_module(SUITE[name])
        t0 = time.perf_counter()
        rows = module.run(quick=args.quick)
        for check, ok, detail in getattr(module, "checks", lambda rows: [])(rows):
            results.append({"benchmark": name, "check": check, "ok": ok, "detail": detail})
            print(f"{'PASS' if ok else 'FAIL'}  {check}  {detail}")
        print(f"{name}: {time.perf_counter() - t0:.1f} s")
        run_info["seconds"][name] = round(time.perf_counter() - t0, 1)
        _write_run_info(run_info)
        if results:                      # after each benchmark: an interrupted run keeps its checks
            write_csv("checks.csv", results)
    run_info["finished_utc"] = _utc_now()
    _write_run_info(run_info)
    failed = [r for r in results if not r["ok"]]
    print(f"\nsuite: {time.perf_counter() - start:.1f} s, {len(results)} checks, {len(failed)} failed; "
          f"outputs in {output_dir()}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
