"""Command-line interface: ``python -m sarmitsuba render [SCENE] [--out DIR] [...]``.

Sub-commands: ``render``, ``preview``, ``info`` (plan only, no tracing), ``focus``, ``analyze``,
``interferogram`` (repeat-pass InSAR of two renders), ``stack`` and ``tomography`` (a stack of
passes focused in elevation, :mod:`sarmitsuba.cli_stack`), ``scene from-footprints`` and ``scene add-windows``
(scene folders, :mod:`sarmitsuba.cli_scene`).

Exit codes: 0 success, 2 bad input (scene, parameter, material, output directory), 130
interrupted (Ctrl-C; outputs are written under temporary names and renamed, so nothing
truncated is left looking complete).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import warnings
from pathlib import Path

from . import cli_scene, cli_stack, cli_types

__all__ = ["main", "build_parser"]


def _add_scene_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the scene and sar sensor flags shared by render, preview and info: SCENE, --pulses, --set."""
    parser.add_argument("scene", nargs="?", default=None,
                        help="XML path (or a folder holding scene.xml), built-in name (urban, dihedral, "
                             "trihedral) or sionna:NAME; default: urban")
    parser.add_argument("--pulses", type=int, default=None, help="number of pulses (sar n_pulses)")
    parser.add_argument("--set", dest="sensor_set", type=cli_types.assignment, action="append", default=[],
                        metavar="NAME=VALUE", help="override a sar sensor parameter (repeatable)")
    return parser


def _add_tracer_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the sbr integrator and material flags shared by render and info."""
    parser.add_argument("--max-depth", type=cli_types.depth, default=None, metavar="N|auto",
                        help="bounce orders traced (sbr max_depth): a number, or auto (the default: the depth the "
                             "scene calls for, chosen by a probe)")
    parser.add_argument("--ray-spacing", type=float, default=None, help="ray-tube width at the scene centre [m]")
    parser.add_argument("--range-kernel", choices=("nearest", "linear", "sinc", "exact"), default=None,
                        help="fast-time deposit kernel")
    parser.add_argument("--seed", type=int, default=None, help="speckle seed (sbr seed)")
    parser.add_argument("--integrator-set", type=cli_types.assignment, action="append", default=[],
                        metavar="NAME=VALUE", help="override an sbr integrator parameter (repeatable)")
    parser.add_argument("--material-set", type=cli_types.assignment, action="append", default=[], metavar="NAME=VALUE",
                        help="make every material rough: gamma_db=DB (constant gamma) or scattering_coefficient=S")
    return parser


def _sensor_overrides(args: argparse.Namespace) -> dict:
    """sar sensor overrides from --set and --pulses (which wins)."""
    sensor = dict(args.sensor_set)
    if args.pulses is not None:
        sensor["n_pulses"] = args.pulses
    return sensor


def _integrator_overrides(args: argparse.Namespace) -> dict:
    """sbr integrator overrides from --integrator-set and the dedicated flags (which win)."""
    integrator = dict(args.integrator_set)
    for key in ("max_depth", "ray_spacing", "range_kernel", "seed"):
        if getattr(args, key) is not None:
            integrator[key] = getattr(args, key)
    return integrator


def _add_format_arguments(parser: argparse.ArgumentParser, cphd: bool) -> None:
    """The standard-format flags of ``render`` and ``focus`` (``--cphd``, ``--cphd-domain``, ``--sicd``,
    ``--geotiff``)."""
    if cphd:
        parser.add_argument("--cphd", action="store_true",
                            help="also write the raw data as CPHD 1.1 (raw.cphd; NGA standard, through sarkit)")
        parser.add_argument("--cphd-domain", default="toa", choices=("toa", "fx"),
                            help="with --cphd: the signal domain, toa (default: the range-compressed fast-time "
                                 "samples) or fx (their spectrum along fast time, the form vendors deliver and "
                                 "FastSAR reads; needs range-compressed data)")
    parser.add_argument("--sicd", action="store_true",
                        help="also write the complex image as SICD in NITF (image.nitf; NGA standard, through sarkit)")
    parser.add_argument("--sicd-plane", default="slant", choices=("slant", "image"),
                        help="with --sicd: the slant plane at the scene centre (default, as producers write SICDs) or "
                             "the image's own ground plane")
    parser.add_argument("--sicd-weighting", default="uniform", choices=("uniform", "image"),
                        help="with --sicd: the focusing weighting divided out (default; every reader, sarpy's RCS "
                             "tool included, reads one RCS) or kept (then sarpy's TotalRCS reads the weighting "
                             "factors high)")
    parser.add_argument("--geotiff", action="store_true",
                        help="also write the ground-plane intensity as a GeoTIFF in UTM (image.tif: dB and "
                             "linear bands), placed by the sensor's geo_origin")
    parser.add_argument("--geotiff-rotated", action="store_true",
                        help="with --geotiff: keep the image's own grid, unresampled, with a rotated geotransform "
                             "(default: resampled onto a north-up UTM grid, which every GIS and web map reads)")


#: Windows of ``--window``, ``--window-range`` and ``--window-azimuth`` (render and focus): every window
#: of :mod:`sarmitsuba.focus.windows` with its default parameters (Taylor nbar 4 / -35 dB, Kaiser beta 2.5).
FOCUS_WINDOWS = ("rect", "taylor", "hamming", "hann", "kaiser")


def _add_window_arguments(parser: argparse.ArgumentParser) -> None:
    """The focusing-window flags of ``render`` and ``focus``: one default (Taylor), one set of flags."""
    parser.add_argument("--window", default="taylor", choices=FOCUS_WINDOWS, metavar="NAME",
                        help="focusing window in range and azimuth (default taylor: nbar 4, -35 dB sidelobes; "
                             f"rect for none); one of {', '.join(FOCUS_WINDOWS)}")
    for axis, where in (("range", "over the band"),
                        ("azimuth", "bp, ffbp: over the beam; omegak, rda: over the Doppler band")):
        parser.add_argument(f"--window-{axis}", default=None, choices=FOCUS_WINDOWS, metavar="NAME",
                            help=f"{axis} window only ({where}; default: --window)")


def _windows(args: argparse.Namespace) -> dict:
    """``window``, ``window_range``, ``window_azimuth`` keywords of render and refocus from the flags."""
    return {"window": args.window, "window_range": args.window_range, "window_azimuth": args.window_azimuth}


def _formats(args: argparse.Namespace) -> tuple[str, ...]:
    """The standard formats asked for by ``--cphd``, ``--sicd``, ``--geotiff``."""
    return tuple(f for f in ("cphd", "sicd", "geotiff") if getattr(args, f, False))


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser of all sub-commands."""
    from . import __version__
    parser = argparse.ArgumentParser(
        prog="sarmitsuba", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Ray-traced SAR simulation of urban scenes: trace a scene into raw data, focus it into an "
                    "image, analyse it.",
        epilog="examples:\n"
               "  .venv/bin/python -m sarmitsuba render                  the built-in urban scene -> out/urban\n"
               "  .venv/bin/python -m sarmitsuba info sionna:munich      radar summary and cost, no tracing\n"
               "  .venv/bin/python -m sarmitsuba render dihedral --set frequency=5.4e9 --out out/c-band\n"
               "  .venv/bin/python -m sarmitsuba focus out/urban/raw.npz --algorithm omegak --out out/urban-wk\n"
               "  .venv/bin/python -m sarmitsuba scene from-footprints city.geojson --out city   then: render city\n"
               "  .venv/bin/python -m sarmitsuba COMMAND --help          the options of one command\n"
               "exit codes: 0 success, 2 bad input (the message names it and the fix), 130 interrupted")
    parser.add_argument("--version", action="version", version=f"sarmitsuba {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    render = _add_tracer_arguments(_add_scene_arguments(
        sub.add_parser("render", help="trace a scene into raw data and a focused SAR image")))
    render.add_argument("--out", type=Path, default=None, help="output directory (default: out/<scene name>)")
    render.add_argument("--split-bounces", action="store_true",
                        help="also write raw data and images per bounce order (*_order1, *_order2, ...)")
    render.add_argument("--scatterers", action="store_true",
                        help="also write the scatterer catalogue: scatterers.csv, scatterers.geojson and "
                             "fig_scatterers.png (each bright point's phase centre, bounce order, shapes and RCS)")
    render.add_argument("--scatterers-share", type=float, default=0.9, metavar="F",
                        help="list the strongest scatterers that hold this share of the image's RCS (default 0.9)")
    render.add_argument("--scatterers-db", type=float, default=None, metavar="DB",
                        help="instead, list every scatterer within this many dB of the strongest (a number in "
                             "(-200, 0], e.g. -30)")
    render.add_argument("--no-progress", action="store_true", help="no progress bars")
    render.add_argument("--figures", action="store_true",
                        help="also draw explanatory figures (fig_*.png, figures.json) from the files written")
    _add_window_arguments(render)
    render.add_argument("--focuser", default="ffbp", choices=("ffbp", "bp"),
                        help="fast factorised backprojection (default) or direct backprojection (its reference, "
                             "slower)")
    _add_format_arguments(render, cphd=True)
    render.add_argument("--scheduler", default=None, metavar="local|tcp://HOST:PORT",
                        help="trace the pulse batches on Dask: 'local' starts a LocalCluster of processes, "
                             "tcp://HOST:PORT uses a running `dask scheduler` with its `dask worker`s")
    preview = _add_scene_arguments(
        sub.add_parser("preview", help="optical preview of the scene and the acquisition geometry (no tracing)"))
    preview.add_argument("--out", type=Path, default=None,
                         help="output directory (default: out/<scene name>); receives preview.png")
    preview.add_argument("--spp", type=cli_types.positive_int, default=16, help="samples per pixel (default 16)")
    preview.add_argument("--resolution", type=cli_types.resolution, default=(960, 720), metavar="WxH",
                         help="PNG size in pixels (default 960x720)")
    info = _add_tracer_arguments(_add_scene_arguments(sub.add_parser(
        "info", help="radar summary, scene size, active effects and estimated cost, without tracing; "
                     "of a render folder (or its summary.json): the energy each bounce order holds")))
    info.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    cli_stack.add_stack_arguments(info)
    cli_stack.add_commands(sub, _add_scene_arguments, _add_tracer_arguments)
    _add_focus_command(sub)
    from .analysis.point_target import add_arguments as analysis_arguments
    analyze = analysis_arguments(sub.add_parser("analyze", help="point-target analysis of a focused image (JSON)"))
    analyze.add_argument("--explain", type=_image_point, default=None, metavar="AZ,RG",
                         help="instead of a point-target analysis: the catalogue's scatterers within one resolution "
                              "cell of image coordinates AZ,RG [m], with their shares of its power (JSON)")
    analyze.add_argument("--scatterers", type=Path, default=None, metavar="CSV",
                         help="the catalogue --explain reads (default: scatterers.csv beside the image)")
    analyze.add_argument("--figure", type=Path, default=None, metavar="PNG",
                         help="also draw the point-target figure (chip, cuts, IRW, PSLR) to this file")
    analyze.add_argument("--raw", type=Path, default=None,
                         help="the RawData that were focused (default: raw.npz beside the image, if any): gives "
                              "the exact carrier ramp, so the peak phase is right between pixels")
    ifg = sub.add_parser("interferogram", help="repeat-pass InSAR of two renders on one ground grid: "
                                              "interferogram, coherence, height (npz) and a figure")
    ifg.add_argument("primary", type=Path, help="render directory of the primary pass (image.npz, raw.npz)")
    ifg.add_argument("secondary", type=Path, help="render directory of the secondary pass (same ground grid)")
    ifg.add_argument("--out", type=Path, required=True, help="output directory")
    ifg.add_argument("--looks", type=cli_types.looks, default=(4, 4), metavar="AZ,RG",
                     help="boxcar window for coherence and height, azimuth,range pixels (default 4,4)")
    ifg.add_argument("--no-progress", action="store_true", help="no progress bar")
    cli_scene.add_scene_command(sub)
    bench = sub.add_parser("bench", help="benchmark suite: accuracy against time for each fidelity knob "
                                         "(needs the source checkout's benchmarks/ folder)", add_help=False)
    bench.add_argument("bench_args", nargs="*", metavar="...",
                       help="arguments of benchmarks/run.py (--quick, --only NAME ...; --help for all)")
    return parser


def _add_focus_command(sub) -> None:
    """The ``focus`` subcommand's arguments."""
    focus = sub.add_parser("focus", help="focus raw data (raw.npz, any RawData, or a CPHD file) into image.npz/.exr/.png")
    focus.add_argument("raw", type=Path, help="RawData file (.npz) or one-channel CPHD file (.cphd)")
    focus.add_argument("--algorithm", choices=("bp", "ffbp", "omegak", "rda"), default="ffbp",
                       help="fast factorised backprojection (default) or direct backprojection (any track), "
                            "omega-K or range-Doppler (straight track)")
    _add_window_arguments(focus)
    focus.add_argument("--track", choices=("true", "nominal"), default="true",
                       help="antenna positions to focus with: the true track (default) or the nominal one of data "
                            "simulated with motion_error (what a processor without precise navigation has)")
    focus.add_argument("--autofocus", choices=("none", "pga"), default="none",
                       help="phase gradient autofocus of the focused image (straight tracks; it warns where its "
                            "assumptions do not fit)")
    focus.add_argument("--pga-reference", type=cli_types.point, default=None, metavar="X,Y,Z",
                       help="with --autofocus pga: world position [m] of a surveyed point-like scatterer (a corner "
                            "reflector), from which PGA also removes the along-track shift it cannot see")
    focus.add_argument("--out", type=Path, required=True, help="output directory")
    focus.add_argument("--no-progress", action="store_true", help="no progress bars")
    _add_format_arguments(focus, cphd=True)


def benchmarks_dir() -> Path:
    """The source checkout's ``benchmarks/`` folder (beside the package); raises OSError naming the fix."""
    folder = Path(__file__).resolve().parent.parent / "benchmarks"
    if not (folder / "run.py").is_file():
        raise OSError(f"benchmarks not found at {folder}: the suite lives in the source checkout; "
                      "install with `pip install -e .` from a clone, or run `python benchmarks/run.py` there")
    return folder


def _bench(args: argparse.Namespace) -> int:
    import importlib.util
    folder = benchmarks_dir()
    sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location("sarmitsuba_benchmarks_run", folder / "run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.main(args.bench_args)


def _focus(args: argparse.Namespace) -> int:
    import time

    from .core.outputs import OutputDirectory, check_output_dir
    from .pipeline import check_formats, refocus, window_title, write_exports, write_image_products
    start = time.perf_counter()
    check_output_dir(args.out)
    raw = load_raw(args.raw)
    check_formats(_formats(args), args.sicd_plane, args.sicd_weighting, cphd_domain=args.cphd_domain, raw=raw)
    try:
        image = refocus(raw, args.algorithm, **_windows(args), progress=not args.no_progress, track=args.track,
                        autofocus=None if args.autofocus == "none" else args.autofocus,
                        autofocus_reference=args.pga_reference)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    extra = ("  nominal track" if args.track == "nominal" else "") + ("  PGA" if args.autofocus == "pga" else "")
    title = f"{raw.metadata.get('scene', args.raw.name)}  {args.algorithm}{extra}  {window_title(image)}"
    with OutputDirectory(args.out, products="add") as out:      # joins a render folder's products
        paths = write_image_products(out, image, title)
        paths.update(write_exports(out, raw, image, _formats(args), geotiff_north_up=not args.geotiff_rotated,
                                   sicd_plane=args.sicd_plane, sicd_weighting=args.sicd_weighting,
                                   cphd_domain=args.cphd_domain))
    from .focus.autofocus_pulses import outcome_line
    note = "" if image.metadata.get("autofocus") is None else ", " + outcome_line(image.metadata["autofocus"])
    print(f"focused {args.raw} with {args.algorithm}{' on the nominal track' if args.track == 'nominal' else ''}: "
          f"{time.perf_counter() - start:.1f} s, {raw.n_pulses} pulses, image {image.data.shape[0]}x"
          f"{image.data.shape[1]}{note} -> {paths['png'].parent}")
    return 0


def load_raw(path: Path):
    """RawData from ``path``: a ``.cphd`` file through :func:`sarmitsuba.formats.cphd.read_cphd`, anything
    else through :meth:`RawData.load`. Raises RawDataError naming the file."""
    from .core.raw import RawData, RawDataError
    if Path(path).suffix.lower() != ".cphd":
        return RawData.load(path)
    from .formats.cphd import CphdError, read_cphd
    try:
        return read_cphd(path)
    except CphdError as exc:
        raise RawDataError(str(exc)) from None


def _default_out(scene: str | None) -> Path:
    path = Path("urban" if scene is None else scene.split(":", 1)[-1])
    name = path.parent.name if path.name == "scene.xml" and path.parent.name else path.stem
    return Path("out") / re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def _render(args: argparse.Namespace) -> int:
    from .pipeline import render
    sensor, integrator = _sensor_overrides(args), _integrator_overrides(args)
    if args.split_bounces:
        integrator["split_bounces"] = True
    summary = render(args.scene, args.out or _default_out(args.scene), sensor_overrides=sensor,
                     integrator_overrides=integrator, material_overrides=dict(args.material_set),
                     progress=not args.no_progress, **_windows(args), focuser=args.focuser,
                     formats=_formats(args), scheduler=args.scheduler, geotiff_north_up=not args.geotiff_rotated,
                     sicd_plane=args.sicd_plane, sicd_weighting=args.sicd_weighting, cphd_domain=args.cphd_domain,
                     scatterers=_scatterers(args))
    print(summary.line())
    if summary.scatterers:
        print(f"scatterers: {summary.scatterers['line']} -> {summary.outputs['scatterers_csv']}")
    if summary.depth_warning:
        print(f"warning: {summary.depth_warning}", file=sys.stderr)
    if args.figures:
        from .products.figures import redraw
        paths = redraw(args.out or _default_out(args.scene), scene=args.scene or "urban")
        print(f"figures: {', '.join(str(p) for p in paths.values())}")
    return 0


def _scatterers(args: argparse.Namespace) -> dict | None:
    """``render``'s catalogue options (None without ``--scatterers``); the share and floor given
    without it are refused (ParameterError)."""
    from .analysis.scatterers import check_selection
    from .core.radar import ParameterError
    if not args.scatterers:
        if args.scatterers_db is not None or args.scatterers_share != 0.9:
            raise ParameterError("--scatterers-db and --scatterers-share choose the catalogue's rows: add --scatterers")
        return None
    share, floor = check_selection(args.scatterers_share, args.scatterers_db)
    return {"scatterers": True, "scatterers_share": share, "scatterers_db": floor}


def _preview(args: argparse.Namespace) -> int:
    from .core.outputs import OutputDirectory
    from .products.preview import render_preview
    from .scene.loader import load_scene
    with OutputDirectory(args.out or _default_out(args.scene)) as out:
        loaded = load_scene(args.scene, sensor_overrides=_sensor_overrides(args))
        path = out.write("preview.png", lambda staged: render_preview(
            loaded, staged, spp=args.spp, resolution=args.resolution))
    print(f"preview of {loaded.source} -> {path}")
    return 0


def _interferogram(args: argparse.Namespace) -> int:
    """Interferogram, coherence, height and figure of two render directories."""
    from .stacks.insar_products import write_products
    from .stacks.interferometry import InterferometryError
    try:
        products = write_products(args.out, args.primary, args.secondary, looks=args.looks,
                                  progress=not args.no_progress)
    except InterferometryError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.primary} x {args.secondary}: {products.line()}")
    return 0


def _info(args: argparse.Namespace) -> int:
    """Print the radar summary, scene size, effects and estimated cost, without tracing; of a
    render's folder (or its summary.json), the energy each bounce order holds."""
    from .analysis.orders import format_render, render_summary
    from .info import format_text, scene_info, to_json
    done = render_summary(args.scene)
    if done is not None:
        print(json.dumps(done, indent=2) if args.json else format_render(done), end="\n" if args.json else "")
        return 0
    info = scene_info(args.scene, sensor_overrides=_sensor_overrides(args),
                      integrator_overrides=_integrator_overrides(args), material_overrides=dict(args.material_set))
    print(to_json(info) if args.json else format_text(info), end="\n" if args.json else "")
    stack = cli_stack.stack_description(args)
    if stack is not None:                      # the stack's resolution, ambiguity and cost
        from .scene.loader import load_scene
        print(cli_stack.stack_lines(info, load_scene(args.scene, _sensor_overrides(args)), stack))
    return 0


def _analyze(args: argparse.Namespace) -> int:
    """Point-target analysis. A world target is looked for at its layover position on the image
    plane, and the energy widths for the RCS come from the image's metadata (windows, pattern,
    geometry) when not given: :func:`sarmitsuba.analysis.point_target.energy_widths` for backprojected
    images; for others (omega-K, RDA) the unweighted widths of its radar parameters
    (``c / (2 B sin(theta))`` and the azimuth resolution)."""
    from .analysis.point_target import run
    if args.explain is not None:
        return _explain(args)
    if args.target is None:
        print("error: analyze needs --target X,Y,Z|AZ,RG (a point-target analysis) or --explain AZ,RG (what "
              "made that point, from the render's scatterers.csv)", file=sys.stderr)
        return 2
    if args.resolution is None:
        args.resolution = _resolution_from_metadata(args.image)
    if args.carrier is None and len(args.target) == 3:
        args.carrier = _carrier_from_raw(args)

    def figure(image, report):
        from .products.figures import point_target_figure
        print(f"point-target figure -> {point_target_figure(image, report, args.figure)}", file=sys.stderr)

    return run(args, figure=figure if args.figure is not None else None)


def _image_point(text: str) -> tuple[float, float]:
    """``AZ,RG``: two finite numbers [m] (argparse type)."""
    values = cli_types.numbers(text)
    if len(values) != 2:
        raise argparse.ArgumentTypeError(f"{text!r}: give two numbers AZ,RG, image coordinates in metres")
    return values[0], values[1]


def _explain(args: argparse.Namespace) -> int:
    """``analyze IMAGE --explain AZ,RG``: the scatterers of the catalogue beside the image (or
    ``--scatterers``) within one resolution cell of the point, as JSON."""
    from .analysis.scatterers import explain
    from .formats.sicd import load_image
    from .products.scatterer_files import read_csv
    image = load_image(args.image)
    columns = read_csv(args.scatterers or Path(args.image).with_name("scatterers.csv"))
    print(json.dumps(explain(image, columns, *args.explain, resolution=args.resolution), indent=2))
    return 0


def raw_beside(image_path: Path) -> Path:
    """The raw data a render wrote beside an image: ``raw.npz`` for ``image.npz``,
    ``raw_HV.npz`` for a quad-pol ``image_HV.npz``, ``raw_order2.npz`` for ``image_order2.npz``."""
    name = image_path.name
    return image_path.with_name("raw" + name[len("image"):] if name.startswith("image") else "raw.npz")


def _carrier_from_raw(args: argparse.Namespace) -> list[float] | None:
    """Carrier ramp [rad/m] at the target's layover position, from ``args.raw`` (default: the
    raw data beside the image, :func:`raw_beside`, if any). None without raw data, or when the image or target is
    bad (``run`` reports those). Raises RawDataError, naming the file, when the raw data are
    damaged: a damaged file is never silently skipped."""
    from .analysis.point_target import carrier_ramp, image_coordinates
    from .core.image import SarImageError
    from .formats.sicd import load_image
    from .core.raw import RawDataError
    raw_path = args.raw or raw_beside(Path(args.image))
    if args.raw is None and not raw_path.is_file():
        return None
    try:
        image = load_image(args.image)
        position = image_coordinates(image, args.target)           # the target's layover position
    except (SarImageError, ValueError):
        return None
    try:
        raw = load_raw(raw_path)
    except RawDataError as exc:
        source = "--raw" if args.raw is not None else f"{raw_path.name} beside the image"
        raise RawDataError(f"{exc} (analyze reads {source} for the carrier ramp: give --raw an intact RawData "
                           "file, or move the damaged one away to analyse without it)") from None
    world = image.origin + position[0] * image.azimuth_direction + position[1] * image.range_direction
    try:
        return list(carrier_ramp(raw, image, world))
    except ValueError:
        return None


def _resolution_from_metadata(path) -> list[float] | None:
    """The resolutions :func:`sarmitsuba.api.unweighted_widths` gives for the image at ``path``
    (None when the image cannot be read: the analysis then reports it)."""
    from .api import unweighted_widths
    from .core.image import SarImageError
    from .formats.sicd import load_image
    try:
        widths = unweighted_widths(load_image(path))
    except (SarImageError, OSError):
        return None
    return None if widths is None else list(widths)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one line, like the errors: ``warning: MESSAGE`` (no ``file:line:``, no source)."""
    print(f"warning: {message}", file=sys.stderr if file is None else file)


def run() -> int:
    """The process's entry point (``python -m sarmitsuba`` and the ``sarmitsuba`` script): :func:`main`
    on the process's arguments. Interrupted, it ends the process at once with code 130: CPython
    ends a ``python -m`` process with SIGINT at exit (return code -2) once a KeyboardInterrupt has
    left code run by ``exec`` on a string (``dataclasses`` and ``namedtuple`` build their methods
    so while modules import), even though :func:`main` handled it (3 of 120 SIGINTs 1.5-2.1 s into
    a render, on a loaded machine)."""
    code = main()
    if code == 130:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(130)
    return code


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code. Warnings print as one ``warning: ...`` line each."""
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["bench"]:            # everything after `bench` belongs to benchmarks/run.py
        args = argparse.Namespace(command="bench", bench_args=argv[1:])
    else:
        args = build_parser().parse_args(argv)
    try:
        import sarmitsuba  # libLLVM check, variant, plugins
        if sarmitsuba.STARTUP_ERROR is not None:     # kept by the package so that --help and --version work
            raise sarmitsuba.STARTUP_ERROR
        from .scene.materials import MaterialError
        from .core.radar import ParameterError
        from .core.image import SarImageError
        from .core.raw import RawDataError
        from .scene.loader import SceneError
    except (RuntimeError, ImportError) as exc:          # LibLLVMError and variant problems (VariantError)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    interrupts = _Interrupts()
    try:
        with interrupts, _output_folder(args):
            code = {"render": _render, "analyze": _analyze, "focus": _focus, "preview": _preview,
                    "info": _info, "bench": _bench, "interferogram": _interferogram, "scene": cli_scene.run_scene,
                    "stack": lambda a: cli_stack.run_stack(a, _sensor_overrides(a), _integrator_overrides(a)),
                    "tomography": cli_stack.run_tomography}[args.command](args)
        if not interrupts.caught:
            return code
        raise KeyboardInterrupt              # one that an optional import swallowed: Ctrl-C still ends in 130
    except BaseException as exc:
        if interrupts.caught or isinstance(exc, KeyboardInterrupt) or _dr_jit_interrupt(exc):
            print("interrupted: no output file was left half-written", file=sys.stderr)
            return 130
        if not isinstance(exc, (SceneError, ParameterError, MaterialError, RawDataError, SarImageError, OSError)):
            raise
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _output_folder(args: argparse.Namespace):
    """Refuse inputs inside a killed run's staging folder; hold the lock of the folder the command
    writes into for the whole command (a render and its figures), before anything is traced."""
    from contextlib import nullcontext
    from .core.folder_lock import hold_folder, refuse_staging
    refuse_staging(*(getattr(args, name, None) for name in ("scene", "raw", "image", "primary", "secondary")))
    if args.command in ("render", "preview"):
        return hold_folder(args.out or _default_out(args.scene))
    return hold_folder(args.out) if args.command in ("focus", "interferogram", "stack", "tomography") else nullcontext()


def _dr_jit_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` is a Ctrl-C that Dr.Jit wrapped in a RuntimeError while tracing a loop."""
    if not isinstance(exc, RuntimeError):
        return False
    from .tracing.driver.trace import caused_by_interrupt
    return caused_by_interrupt(exc)


class _Interrupts:
    """While a command runs: SIGINT raises KeyboardInterrupt (outputs are written under temporary
    names and cleaned up) and is remembered in :attr:`caught`, so that a Ctrl-C which an extension
    module turns into another exception while it is being imported (an AttributeError of a half
    initialised module, a SystemError), or that an optional import swallows, still ends in the one
    ``interrupted`` line and code 130.
    Only in the main thread (where Python delivers signals); elsewhere it changes nothing."""

    def __init__(self) -> None:
        self.caught = False
        self._previous = None

    def __enter__(self) -> "_Interrupts":
        import signal
        import threading
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum, frame) -> None:
        self.caught = True
        raise KeyboardInterrupt

    def __exit__(self, *exc) -> bool:
        if self._previous is not None:
            import signal
            signal.signal(signal.SIGINT, self._previous)
        return False
