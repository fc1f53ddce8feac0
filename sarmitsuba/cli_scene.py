"""The ``scene`` commands of the command line: ``scene from-footprints FILE.geojson --out DIR`` (a
scene folder from building footprints, :mod:`sarmitsuba.scene.city`) and ``scene add-windows
SCENE --out DIR`` (a copy of a scene with windows in its plain walls,
:mod:`sarmitsuba.scene.windowed`). Bad input: one line per problem on stderr, exit code 2.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import cli_types

__all__ = ["add_scene_command", "run_scene"]


def add_scene_command(sub) -> None:
    """``scene from-footprints FILE.geojson --out DIR``: a scene folder from building footprints."""
    scene = sub.add_parser("scene", help="make scenes: `scene from-footprints FILE.geojson --out DIR`, "
                                         "`scene add-windows SCENE --out DIR`")
    make = scene.add_subparsers(dest="scene_command", required=True)
    fp = make.add_parser("from-footprints", help="a scene folder (scene.xml, meshes/) from building footprints in "
                                                 "GeoJSON (OpenStreetMap, cadastral, Microsoft/Google footprints)")
    fp.add_argument("footprints", type=Path, help="GeoJSON FeatureCollection of Polygon/MultiPolygon buildings, "
                                                  "WGS84 longitude/latitude")
    fp.add_argument("--out", type=Path, required=True, help="folder for scene.xml and meshes/ (render takes it)")
    fp.add_argument("--default-height", type=float, default=None, metavar="M",
                    help="height of buildings with neither height nor building:levels (default: refuse them)")
    fp.add_argument("--material", default="concrete", help="material of buildings without building:material "
                                                           "(ITU-R P.2040 name; default concrete)")
    fp.add_argument("--ground-material", default="concrete", help="ITU-R P.2040 material of the ground "
                                                                  "(default concrete)")
    fp.add_argument("--dem", type=Path, default=None, help="DEM GeoTIFF for the ground (any CRS; meshed at its "
                                                           "resolution, clipped to the area); default: a flat plane")
    fp.add_argument("--elevation", type=float, default=0.0, metavar="M",
                    help="height of the flat ground above the WGS84 ellipsoid (geo_origin's height; default 0)")
    fp.add_argument("--margin", type=float, default=None, metavar="M",
                    help="ground around the buildings (default: max(10 m, the tallest building))")
    fp.add_argument("--scattering-coefficient", type=float, default=None, metavar="S",
                    help="roughness of the buildings, 0 (smooth) to <1 (default 0.3)")
    fp.add_argument("--ground-scattering-coefficient", type=float, default=None, metavar="S",
                    help="roughness of the ground (default 0.2)")
    fp.add_argument("--repair", action="store_true", help="mend invalid outlines with shapely's make_valid "
                                                          "and report each (default: refuse them)")
    fp.add_argument("--set", dest="sensor_set", type=cli_types.assignment, action="append", default=[],
                    metavar="NAME=VALUE", help="a sar sensor parameter written into scene.xml (repeatable)")
    _add_windows_command(make)
    fp.add_argument("--windows", action="store_true",
                    help="recessed windows of glass (and, with balcony_share, balconies) on every wall: 3 m storeys, "
                         "1.2 m x 1.5 m windows every 3 m, 0.15 m deep, unless --facade-set says otherwise")
    fp.add_argument("--facade-set", dest="facade_set", type=cli_types.assignment, action="append", default=[],
                    metavar="NAME=VALUE", help="a facade setting (implies --windows): floor_height, window_width, "
                                               "window_height, window_spacing, sill_height, recess_depth (m), "
                                               "balcony_share (0-1), balcony_depth (m), seed (repeatable)")


def _add_windows_command(make) -> None:
    aw = make.add_parser("add-windows", help="a copy of a scene whose plain walls get recessed windows (a Sionna "
                                             "city, a scene folder or XML file)")
    aw.add_argument("scene", help="XML file, scene folder, built-in name or sionna:NAME")
    aw.add_argument("--out", type=Path, required=True, help="folder for scene.xml and meshes/ (render takes it)")
    aw.add_argument("--facade-set", dest="facade_set", type=cli_types.assignment, action="append", default=[],
                    metavar="NAME=VALUE", help="a facade setting, as for from-footprints (repeatable)")


def _add_windows(args: argparse.Namespace) -> int:
    """``scene add-windows``: the scene's plain walls with windows, written to a new folder."""
    import time

    from .scene.facades import FacadeError, FacadeLayout
    from .scene.loader import resolve_source
    from .scene.windowed import write_windowed
    start = time.perf_counter()
    try:
        layout = FacadeLayout.from_mapping(dict(args.facade_set))
    except FacadeError as exc:
        print(f"error: --facade-set: {exc}", file=sys.stderr)
        return 2
    source = resolve_source(args.scene)
    written = write_windowed(source, args.out, layout)
    print(f"windows for {args.scene}: {time.perf_counter() - start:.1f} s, {written.summary()} -> {written.path} "
          f"(render it: .venv/bin/python -m sarmitsuba render {written.path})")
    return 0


def run_scene(args: argparse.Namespace) -> int:
    """``scene from-footprints``: build, check and write a footprint scene; one line per bad feature."""
    import time
    if args.scene_command == "add-windows":
        return _add_windows(args)

    from .scene import city
    from .scene.facades import FacadeError, FacadeLayout
    from .scene.footprints import FootprintError
    start = time.perf_counter()
    options = {k: getattr(args, k) for k in ("scattering_coefficient", "ground_scattering_coefficient")
               if getattr(args, k) is not None}
    if args.windows or args.facade_set:
        try:
            options["facade"] = FacadeLayout.from_mapping(dict(args.facade_set))
        except FacadeError as exc:
            print(f"error: --facade-set: {exc}", file=sys.stderr)
            return 2
    try:
        built = city.build_city(args.footprints, default_height=args.default_height, material=args.material,
                                ground_material=args.ground_material, dem=args.dem, elevation=args.elevation,
                                margin=args.margin, repair=args.repair, sensor=dict(args.sensor_set), **options)
    except FootprintError as exc:
        for line in exc.problems:
            print(f"error: {line}", file=sys.stderr)
        return 2
    for line in built.repairs:
        print(f"repaired: {line}", file=sys.stderr)
    path = city.write_city(built, args.out)
    print(f"scene from {args.footprints}: {time.perf_counter() - start:.1f} s, {built.summary()} -> {path} "
          f"(render it: .venv/bin/python -m sarmitsuba render {path})")
    return 0
