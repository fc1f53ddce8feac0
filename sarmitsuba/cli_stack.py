"""The command line's tomography: ``stack`` (render N passes), ``tomography`` (focus them in
elevation) and the stack lines of ``info``.

``python -m sarmitsuba stack SCENE --span 12 --passes 10 --out DIR`` renders the passes
(:func:`sarmitsuba.stack.render_stack`); ``python -m sarmitsuba tomography DIR --out DIR2``
writes the products of :func:`sarmitsuba.stacks.tomo_products.write_products`. Bad input ends
with one ``error:`` line and exit code 2.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from . import cli_types

__all__ = ["add_stack_arguments", "add_commands", "stack_description", "run_stack", "run_tomography", "stack_lines"]


def add_stack_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The passes of a stack (``stack``, and ``info`` for its resolution and cost)."""
    group = parser.add_argument_group("stack passes (one of --span with --passes, --baselines, --track-offsets)")
    group.add_argument("--span", type=float, default=None, metavar="M",
                       help="perpendicular baseline span [m], with --passes")
    group.add_argument("--passes", type=int, default=None, metavar="N", help="number of passes over --span (>= 3)")
    group.add_argument("--random-baselines", type=int, default=None, metavar="SEED",
                       help="place the passes at random within --span (the two ends kept), seeded")
    group.add_argument("--baselines", type=cli_types.numbers, default=None, metavar="B1,B2,...",
                       help="perpendicular baselines [m], one per pass")
    group.add_argument("--track-offsets", type=cli_types.vectors, default=None, metavar="X,Y,Z;X,Y,Z;...",
                       help="track offsets [m], world frame, one per pass")
    return parser


def stack_description(args: argparse.Namespace) -> dict | None:
    """The ``stack_baselines`` keywords of the flags, or None when none is given."""
    if args.span is None and args.passes is None and args.baselines is None and args.track_offsets is None:
        return None
    if args.span is not None or args.passes is not None:
        return {"span": args.span, "count": args.passes,
                "spacing": "uniform" if args.random_baselines is None else "random",
                "seed": args.random_baselines or 0}
    return {"baselines": args.baselines} if args.baselines is not None else {"track_offsets": args.track_offsets}


def add_commands(sub: Any, add_scene_arguments: Any, add_tracer_arguments: Any) -> None:
    """The ``stack`` and ``tomography`` sub-commands (the scene and tracer flags come from the CLI)."""
    stack = add_stack_arguments(add_tracer_arguments(add_scene_arguments(sub.add_parser(
        "stack", help="a tomographic stack: N passes of one scene on one ground grid, each a render folder"))))
    stack.add_argument("--out", type=Path, required=True, help="stack folder (pass-00, pass-01, ..., stack.json)")
    stack.add_argument("--scheduler", default=None, metavar="local|tcp://HOST:PORT",
                       help="render the passes as Dask tasks (a LocalCluster, or a running scheduler)")
    stack.add_argument("--no-truth", action="store_true", help="do not write truth.npz")
    stack.add_argument("--no-progress", action="store_true", help="no progress bar")
    tomo = sub.add_parser("tomography", help="focus a stack in elevation: profiles, scatterers, point cloud, figures")
    tomo.add_argument("stack", type=Path, nargs="+", help="a stack folder, or three or more render folders")
    tomo.add_argument("--out", type=Path, required=True, help="output directory")
    tomo.add_argument("--method", choices=("beamforming", "capon", "sparse"), default="beamforming",
                      help="beamforming (Fourier, default), Capon, or sparse (SL1MMER, few scatterers)")
    tomo.add_argument("--reference-point", type=cli_types.point, default=None, metavar="X,Y,Z",
                      help="calibrate the phases on a surveyed point scatterer (default: the flat earth)")
    tomo.add_argument("--rows", type=cli_types.index_range, default=slice(None), metavar="A:B",
                      help="azimuth rows to invert (default all)")
    tomo.add_argument("--cols", type=cli_types.index_range, default=slice(None), metavar="A:B",
                      help="range columns to invert (default all)")
    tomo.add_argument("--min-power-db", type=float, default=-30.0,
                      help="invert pixels within this many dB (< 0) of the brightest (default -30)")
    tomo.add_argument("--threshold-db", type=float, default=-10.0,
                      help="a scatterer is a profile peak within this many dB (< 0) of the pixel's (default -10)")
    tomo.add_argument("--max-scatterers", type=int, default=3, help="scatterers per pixel at most (default 3)")
    tomo.add_argument("--looks", type=cli_types.looks, default=(3, 3), metavar="AZ,RG",
                      help="Capon's covariance window (default 3,3)")
    tomo.add_argument("--tomogram-row", type=int, default=None, help="azimuth row of tomogram.png")
    tomo.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_stack(args: argparse.Namespace, sensor: dict, integrator: dict) -> int:
    """``stack``: render the passes."""
    from .stack import render_stack
    description = stack_description(args)
    if description is None:
        print("error: give the passes: --span M --passes N, --baselines B1,B2,... or --track-offsets X,Y,Z;...",
              file=sys.stderr)
        return 2
    summary = render_stack(args.scene, args.out, sensor_overrides=sensor, integrator_overrides=integrator,
                           material_overrides=dict(args.material_set), progress=not args.no_progress,
                           scheduler=args.scheduler, truth=not args.no_truth, **description)
    print(summary.line())
    return 0


def run_tomography(args: argparse.Namespace) -> int:
    """``tomography``: the products of a stack."""
    from .stacks.tomo_products import write_products
    from .stacks.tomography import TomographyError
    try:
        products = write_products(args.out, args.stack, progress=not args.no_progress, method=args.method,
                                  calibration_point=args.reference_point, region=(args.rows, args.cols),
                                  min_power_db=args.min_power_db, threshold_db=args.threshold_db,
                                  max_scatterers=args.max_scatterers, looks=args.looks,
                                  tomogram_row=args.tomogram_row)
    except TomographyError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(products.line())
    return 0


def stack_lines(info: Any, loaded: Any, description: dict) -> str:
    """The ``Stack`` section of ``info``: baselines, ``rho_s``, ambiguity against the scene's
    heights, and the time and memory of N renders (``info.cost``'s estimates of one)."""
    from .stack import plan_stack
    plan = plan_stack(loaded, **description)
    b, cost = plan.baselines, info.cost
    n = len(b.perpendicular)
    seconds = n * (cost.trace_time_s + cost.focus_time_s)
    disk = n * (cost.raw_bytes + 2 * cost.image_bytes)
    sin_theta = math.sin(math.radians(b.incidence))
    return "\n".join([
        "Stack",
        f"  {n} passes, perpendicular baselines {b.perpendicular.min():.3f} .. {b.perpendicular.max():.3f} m "
        f"(span Delta b {b.span:.3f} m, mean spacing d_b {b.mean_spacing:.3f} m), reference pass {b.reference}",
        f"  elevation resolution rho_s = lambda R / (2 Delta b) = {b.elevation_resolution:.3f} m "
        f"({b.elevation_resolution * sin_theta:.3f} m of height)",
        f"  elevation ambiguity lambda R / (2 d_b) = {b.elevation_ambiguity:.2f} m ({b.height_range():.2f} m of "
        f"height); the scene spans {plan.heights[1] - plan.heights[0]:.2f} m of height: inverted over "
        f"s = {plan.interval[0]:.2f} .. {plan.interval[1]:.2f} m",
        f"  cost: about {seconds:.0f} s for {n} renders (passes one after another), peak memory "
        f"{cost.peak_memory_bytes / 2**30:.2f} GiB (one pass at a time), about {disk / 2**30:.2f} GiB of raw data "
        "and images on disk", ""])
