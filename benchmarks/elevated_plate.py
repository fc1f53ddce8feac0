"""Sub-aperture sidelobes of a small plate high above the aim plane (issue 26, part 2; not in the suite).

A 0.3 m plate (concrete, smooth or rough: its return is the PO of its edges either way) lies
35 m above a smooth 300 m ground, with the scene centre, and so the ray lattice's aim plane, on
the ground. For each number of pulses per trace it prints the plate's azimuth and range PSLR
(``sarmitsuba.analysis.point_target.analyze_point_target``). The rays from two reference positions to one aim
point cross the plate's plane ``h / H`` of their separation apart: tiles projected from each pulse's own
antenna slid over the plate while the tubes meeting it stayed the reference position's, so the
sub-aperture period showed as sidelobes (docs/physics.md (T3)). Measured on the 2-core VM with
the tiles fixed on the surface for the sub-aperture (the fix): -36.3 dB per pulse, -36.6 dB with
4 pulses per trace, -37.7 dB at the default (19); before it -29.7 and -19.5 dB. With
``--lit-regions cells``: -35.0 dB at the default (before: -15.9 dB). ``--no-ground`` puts the
scene centre at the plate's height (-58 dB for every setting).

Usage: ``python benchmarks/elevated_plate.py [--height M] [--rough] [--no-ground] [--pulses-per-trace 1,4,0]
[--lit-regions tiles|cells]``
"""
from __future__ import annotations

import argparse
import gc

import trimesh

import sarmitsuba
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.pipeline import simulate


def plate_scene(height: float, rough: bool, ground: bool, width: float = 0.3) -> sarmitsuba.Scene:
    """The plate ``width`` m square at ``height`` m, on a 300 m smooth ground (scene centre on it)
    or alone (scene centre at the plate, the default)."""
    w = width / 2
    plate = trimesh.Trimesh([[-w, -w, height], [w, -w, height], [w, w, height], [-w, w, height]], [[0, 1, 2], [0, 2, 3]])
    meshes = [(plate, {"material": "concrete", **({"gamma_db": -8} if rough else {})}, "plate")]
    sensor = {}
    if ground:
        g = trimesh.Trimesh([[-150, -150, 0], [150, -150, 0], [150, 150, 0], [-150, 150, 0]], [[0, 1, 2], [0, 2, 3]])
        meshes.append((g, {"material": "medium_dry_ground"}, "ground"))
        sensor = {"scene_center": (0.0, 0.0, 0.0)}
    return sarmitsuba.Scene(meshes=meshes, sensor=sensor, integrator={"max_depth": 1}, name="elevated_plate")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--height", type=float, default=35.0, help="plate height above the ground [m] (default 35)")
    parser.add_argument("--rough", action="store_true", help="a rough plate (gamma -8 dB)")
    parser.add_argument("--no-ground", action="store_true", help="the plate alone (aim plane at its height)")
    parser.add_argument("--pulses-per-trace", default="1,4,0", help="comma-separated settings (0 = default)")
    parser.add_argument("--lit-regions", default="patches", choices=("patches", "tiles"),
                        help="the integrator's lit_regions (docs/physics.md (M1)-(M7), (T3); default patches)")
    args = parser.parse_args()
    scene = plate_scene(args.height, args.rough, not args.no_ground)
    for n in (int(x) for x in args.pulses_per_trace.split(",")):
        sim = simulate(scene, integrator_overrides={"pulses_per_trace": n, "lit_regions": args.lit_regions})
        report = analyze_point_target(sim.image, (0.0, 0.0, args.height))
        print(f"pulses_per_trace {sim.trace.pulses_per_trace:3d}: azimuth PSLR {report.pslr_azimuth_db:6.1f} dB, "
              f"range PSLR {report.pslr_range_db:6.1f} dB", flush=True)
        del sim
        gc.collect()


if __name__ == "__main__":
    main()
