"""The command line's tomography: ``stack`` (render N passes), ``tomography`` (focus them in
elevation) and the stack lines of ``info``.

``python -m sarmitsuba stack SCENE --span 12 --passes 10 --out DIR`` renders the passes
(:func:`sarmitsuba.stack.render_stack`); ``python -m sarmitsuba tomography DIR --out DIR2``
writes the products of :func:`sarmitsuba.stacks.tomo_products.write_products`. Bad input ends
with one ``error:`` line naming the flags and exit code 2: a flag outside its range at parsing,
flags that do not describe one stack in :func:`stack_description`, and the library's messages
with their parameters named by the flags that set them (:func:`flag_names`).
"""
from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path
from typing import Any

from . import cli_types

__all__ = ["add_stack_arguments", "add_commands", "stack_description", "run_stack", "run_tomography", "stack_lines",
           "flag_names"]

#: How the library's messages name a parameter (``name = value``) -> the flag of ``stack``, and of
#: ``tomography``, that sets it. Names with an underscore or a space are also replaced where they
#: stand alone.
STACK_FLAGS = {"out_dir": "--out", "count": "--passes", "span": "--span", "seed": "--random-baselines",
               "baselines": "--baselines", "track_offsets": "--track-offsets"}
TOMOGRAPHY_FLAGS = {"region rows": "--rows", "region cols": "--cols", "min_power_db": "--min-power-db",
                    "threshold_db": "--threshold-db", "max_scatterers": "--max-scatterers",
                    "tomogram_row": "--tomogram-row", "calibration_point": "--reference-point", "looks": "--looks",
                    "method": "--method"}


def flag_names(message: str, flags: dict[str, str]) -> str:
    """A library message with its parameters named by their ``flags`` (:data:`STACK_FLAGS`,
    :data:`TOMOGRAPHY_FLAGS`): ``min_power_db = -30`` becomes ``--min-power-db -30``."""
    for name, flag in flags.items():
        message = re.sub(rf"(?<![\w-]){re.escape(name)} = ", f"{flag} ", message)
        if "_" in name or " " in name:
            message = re.sub(rf"(?<![\w-]){re.escape(name)}(?!\w)", flag, message)
    return message


def _whole(low: int, what: str):
    """An argparse type: a whole number >= ``low``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if value < low:
            raise argparse.ArgumentTypeError(f"expected {what}: a whole number >= {low}, got {text!r}")
        return value
    return parse


def _finite(accept, expected: str):
    """An argparse type: a finite number for which ``accept(value)`` holds; else the line
    ``expected ..., got ...``."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and accept(value)):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value
    return parse


_db_below_zero = _finite(lambda v: v < 0, "a finite number of dB < 0, e.g. -10")
_metres_above_zero = _finite(lambda v: v > 0, "a finite span in metres > 0, e.g. 12")


def add_stack_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The passes of a stack (``stack``, and ``info`` for its resolution and cost)."""
    group = parser.add_argument_group("stack passes (one of --span with --passes, --baselines, --track-offsets)")
    group.add_argument("--span", type=_metres_above_zero, default=None, metavar="M",
                       help="perpendicular baseline span [m], with --passes")
    group.add_argument("--passes", type=_whole(3, "the number of passes over --span (tomography resolves elevation "
                                                  "from 3 or more; 2 passes: use `interferogram`)"),
                       default=None, metavar="N", help="number of passes over --span (>= 3)")
    group.add_argument("--random-baselines", type=_whole(0, "the seed of the random baselines"), default=None,
                       metavar="SEED", help="place the passes at random within --span (the two ends kept), seeded "
                                            "(a whole number >= 0)")
    group.add_argument("--baselines", type=cli_types.numbers, default=None, metavar="B1,B2,...",
                       help="perpendicular baselines [m], one per pass")
    group.add_argument("--track-offsets", type=cli_types.vectors, default=None, metavar="X,Y,Z;X,Y,Z;...",
                       help="track offsets [m], world frame, one per pass")
    return parser


def stack_description(args: argparse.Namespace) -> dict | None:
    """The ``stack_baselines`` keywords of the flags, or None when none is given.

    Raises
    ------
    ParameterError
        More than one description, ``--span`` without ``--passes`` (or the reverse), or
        ``--random-baselines`` without them; naming the flags.
    """
    from .core.radar import ParameterError
    given = [flag for flag, value in (("--span/--passes", args.span is not None or args.passes is not None),
                                      ("--baselines", args.baselines is not None),
                                      ("--track-offsets", args.track_offsets is not None)) if value]
    if not given:
        if args.random_baselines is not None:
            raise ParameterError("--random-baselines places the passes at random within --span: give --span M and "
                                 "--passes N with it")
        return None
    if len(given) > 1:
        raise ParameterError(f"{' and '.join(given)} both describe the passes: give one of --span M with --passes N, "
                             "--baselines B1,B2,... or --track-offsets X,Y,Z;...")
    if given[0] == "--span/--passes":
        if args.span is None or args.passes is None:
            raise ParameterError(f"{'--span' if args.span is None else '--passes'} is missing: --span M and --passes N "
                                 "go together (N passes over a perpendicular baseline span of M metres), e.g. "
                                 "--span 12 --passes 10")
        return {"span": args.span, "count": args.passes,
                "spacing": "uniform" if args.random_baselines is None else "random",
                "seed": args.random_baselines or 0}
    if args.random_baselines is not None:
        raise ParameterError(f"--random-baselines places the passes within --span, not with {given[0]}: drop it, "
                             "or give --span M and --passes N instead")
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
    tomo.add_argument("--min-power-db", type=_db_below_zero, default=None, metavar="DB",
                      help="invert pixels within DB (< 0) of the window's brightest (default: those at most 15 dB "
                           "below its clutter level, the mode of its power in dB)")
    tomo.add_argument("--threshold-db", type=_db_below_zero, default=-10.0, metavar="DB",
                      help="a scatterer is a profile peak within DB (< 0) of the pixel's (default -10)")
    tomo.add_argument("--max-scatterers", type=_whole(1, "scatterers per pixel"), default=3, metavar="K",
                      help="scatterers per pixel at most (default 3)")
    tomo.add_argument("--looks", type=cli_types.looks, default=(3, 3), metavar="AZ,RG",
                      help="Capon's covariance window (default 3,3)")
    tomo.add_argument("--tomogram-row", type=_whole(0, "an azimuth row of the image"), default=None, metavar="ROW",
                      help="azimuth row of tomogram.png (default: the row with most scatterers)")
    tomo.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_stack(args: argparse.Namespace, sensor: dict, integrator: dict) -> int:
    """``stack``: render the passes. Bad input: one ``error:`` line naming the flags, exit code 2."""
    from .core.radar import ParameterError
    from .stack import render_stack
    description = stack_description(args)
    if description is None:
        print("error: give the passes: --span M --passes N, --baselines B1,B2,... or --track-offsets X,Y,Z;...",
              file=sys.stderr)
        return 2
    if "track_offset" in sensor:
        print(f"error: --set track_offset={sensor['track_offset']}: the stack sets each pass's track offset; give the "
              "passes as --span M with --passes N, --baselines B1,B2,... or --track-offsets X,Y,Z;... instead",
              file=sys.stderr)
        return 2
    try:
        summary = render_stack(args.scene, args.out, sensor_overrides=sensor, integrator_overrides=integrator,
                               material_overrides=dict(args.material_set), progress=not args.no_progress,
                               scheduler=args.scheduler, truth=not args.no_truth, **description)
    except ParameterError as exc:
        raise ParameterError(flag_names(str(exc), STACK_FLAGS)) from None
    print(summary.line())
    return 0


def run_tomography(args: argparse.Namespace) -> int:
    """``tomography``: the products of a stack. Bad input: one ``error:`` line naming the flags
    (:func:`flag_names`), exit code 2."""
    from .stacks.tomo_products import write_products
    from .stacks.tomography import TomographyError
    try:
        products = write_products(args.out, args.stack, progress=not args.no_progress, method=args.method,
                                  calibration_point=args.reference_point, region=(args.rows, args.cols),
                                  min_power_db=args.min_power_db, threshold_db=args.threshold_db,
                                  max_scatterers=args.max_scatterers, looks=args.looks,
                                  tomogram_row=args.tomogram_row)
    except TomographyError as exc:
        print(f"error: {flag_names(str(exc), TOMOGRAPHY_FLAGS)}", file=sys.stderr)
        return 2
    print(products.line())
    return 0


def stack_lines(info: Any, loaded: Any, description: dict) -> str:
    """The ``Stack`` section of ``info``: baselines, ``rho_s``, ambiguity against the scene's
    heights, and the time and memory of N renders (``info.cost``'s estimates of one)."""
    from .stack import plan_stack, stack_cost
    plan = plan_stack(loaded, **description)
    b, cost = plan.baselines, info.cost
    n = len(b.perpendicular)
    estimate = stack_cost(cost, n)
    seconds, disk = estimate.seconds, estimate.bytes
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
        f"{cost.peak_memory_bytes / 2**30:.2f} GiB (one pass at a time), about {disk / 2**30:.2f} GiB on disk (raw "
        "data, images and truth)", ""])
