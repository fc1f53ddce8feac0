"""Study: how many corners, occluders and boundary segments the mesh tracer's pieces carry, the
measured histograms from which a fixed-capacity device layout takes its capacities
(docs/design.md section 10, "A fused device pipeline").

One render per scene, on one host thread, with the mesh tracer's stages wrapped (their results
unchanged). Per bounce order it records, per row of the quantity a device kernel would give one
lane:

* ``corners``: the corners of every piece classified (whole pieces: 4);
* ``occluders``: the mesh occluders of every mixed piece (its rows of ``LitPieces.blockers``);
* ``shadow_planes``: the half-planes of every occluder's shadow on a piece (the rows of
  :func:`~sarmitsuba.tracing.visibility.occlusion.shared_shadow_lines` that are not padding);
* ``cutout_corners``: the corners of every cut-out (a piece clipped to one shadow);
* ``boundary``: the lit boundary segments of every piece cut against its occluders;
* ``lanes``: the term lanes of every lit piece (whole, border and cut);
* ``pieces_per_sub`` and ``chains_per_sub``: the pieces classified and the chains of each
  sub-aperture.

For each it writes the count of rows, the mean, the 50th, 99th, 99.9th and 99.99th percentiles,
the largest, and the share of rows above 8, 16, 32 and 64: the rows a capacity would send to
the NumPy reference.

Scenes: Sionna RT's Munich (``--pulses``, default 128), the built-in ``urban`` (its own pulses),
and the footprint city of ``benchmarks/city_generator.py`` (``--city-triangles``, default 1e6;
``--city-pulses``, default 64; 0 leaves it out).

Writes ``capacities.csv`` (``_table.output_dir``).
Usage: ``python benchmarks/capacities.py [--pulses N] [--city-triangles T] [--city-pulses N]``
"""
from __future__ import annotations

import argparse
import collections
import os
import tempfile
import time

os.environ["SARMITSUBA_HOST_THREADS"] = "1"      # one launch at a time: the records follow the stages

import numpy as np  # noqa: E402
from _table import machine, write_csv  # noqa: E402

import sarmitsuba  # noqa: E402,F401
from sarmitsuba.pipeline import simulate  # noqa: E402
from sarmitsuba.tracing.driver import mesh_trace  # noqa: E402
from sarmitsuba.tracing.mesh.polygons import EVERYTHING  # noqa: E402
from sarmitsuba.tracing.visibility import occlusion  # noqa: E402

NAME = "capacities"
#: The capacities whose overflow share is reported.
CAPACITIES = (8, 16, 32, 64)
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3
QUANTITIES = ("corners", "occluders", "shadow_planes", "cutout_corners", "boundary", "lanes", "pieces_per_sub",
              "chains_per_sub")


def record(scene: str, overrides: dict) -> dict:
    """{(order, quantity): [int64 arrays]} of one render (the stages wrapped, their results unchanged)."""
    records: dict = collections.defaultdict(list)
    state = {"order": 0}
    real_lanes, real_clip, real_shadow = (mesh_trace.MeshTracer._lanes, occlusion.clip,
                                          occlusion.shared_shadow_lines)

    def lanes(self, lit, views, depth, reference, clock=None, rx=None, match=None):
        state["order"] = depth
        chains = lit.chains
        out = real_lanes(self, lit, views, depth, reference, clock, rx, match)
        lane_set, _, clipped, cut_lit = out
        add = records[depth, "corners"].append
        add(lit.pieces.polygons()[1])
        mixed = np.flatnonzero(cut_lit.mixed)
        at, _ = cut_lit.blockers.rows(mixed, mesh=True)
        records[depth, "occluders"].append(np.bincount(at, minlength=len(mixed)))
        records[depth, "boundary"].append(np.bincount(clipped.owner, minlength=len(clipped)))
        piece = np.asarray(lane_set.piece, np.int64)
        records[depth, "lanes"].append(np.bincount(piece)[np.unique(piece)] if len(piece) else piece)
        sub = np.take(chains.sub, lit.pieces.region)
        records[depth, "pieces_per_sub"].append(np.bincount(sub, minlength=int(chains.sub.max(initial=-1)) + 1))
        records[depth, "chains_per_sub"].append(np.bincount(chains.sub, minlength=int(chains.sub.max(initial=-1)) + 1))
        return out

    def shadow(*args, **kwargs):
        found = real_shadow(*args, **kwargs)
        lines = found[0]
        real = ~np.all(lines == np.asarray(EVERYTHING), axis=2)
        records[state["order"], "shadow_planes"].append(real.sum(axis=1))
        return found

    def clip(poly, count, lines):
        cut, cut_count = real_clip(poly, count, lines)
        records[state["order"], "cutout_corners"].append(cut_count[cut_count >= 3])
        return cut, cut_count

    mesh_trace.MeshTracer._lanes = lanes
    occlusion.clip, occlusion.shared_shadow_lines = clip, shadow
    try:
        simulate(scene, sensor_overrides=overrides, integrator_overrides={"max_depth": MAX_DEPTH})
    finally:
        mesh_trace.MeshTracer._lanes = real_lanes
        occlusion.clip, occlusion.shared_shadow_lines = real_clip, real_shadow
    return records


def summarise(scene: str, records: dict) -> list[dict]:
    """One row per (bounce order, quantity) of ``records`` (see the module docstring)."""
    rows = []
    for order in sorted({o for o, _ in records}):
        for quantity in QUANTITIES:
            parts = records.get((order, quantity), [])
            values = np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, np.int64)
            row = {"scene": scene, "order": order + 1, "quantity": quantity, "rows": len(values)}
            if len(values):
                row["mean"] = round(float(values.mean()), 2)
                for q in (50, 99, 99.9, 99.99):
                    row[f"p{q:g}"] = int(np.percentile(values, q, method="higher"))
                row["max"] = int(values.max())
                for c in CAPACITIES:
                    row[f"over_{c}"] = float(f"{np.mean(values > c):.3g}")
            rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pulses", type=int, default=128, help="Munich's pulses (default 128)")
    parser.add_argument("--city-triangles", type=float, default=1e6)
    parser.add_argument("--city-pulses", type=int, default=64, help="the city's pulses (0: no city)")
    args = parser.parse_args()
    print(machine(), flush=True)
    rows = []
    scenes = [("urban", "urban", {}), ("munich", "sionna:munich", {"n_pulses": args.pulses})]
    with tempfile.TemporaryDirectory() as folder:
        if args.city_pulses:
            from city_generator import generate
            xml = generate(folder, args.city_triangles)[0]
            scenes.append(("city", str(xml), {"n_pulses": args.city_pulses}))
        for name, scene, overrides in scenes:
            start = time.perf_counter()
            found = summarise(name, record(scene, overrides))
            print(f"{name}: {time.perf_counter() - start:.0f} s", flush=True)
            for row in found:
                print("  ".join(f"{k}={v}" for k, v in row.items()), flush=True)
            rows += found
    write_csv(NAME + ".csv", rows)


if __name__ == "__main__":
    main()
