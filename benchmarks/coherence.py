"""Study: how much of the mesh tracer's per-sub-aperture work repeats what the last sub-aperture did.

The mesh tracer classifies every piece in a sub-aperture's reach (lit, transmit-lit, mixed, dark:
docs/physics.md (M4)) and builds its term lanes again for every sub-aperture. This records each
classification of a Munich render (its central pulses) by a key that names the same piece in
every sub-aperture (the chain's parts, the patch cell, whole or not) and reports, per bounce
order:

* the pieces per sub-aperture by class;
* for two consecutive sub-apertures, how the class of a piece in both changes (``from -> to``,
  as fractions of the pieces in both) and how many pieces are in one only (the beam's reach
  moving on);
* the *runs*: maximal stretches of consecutive sub-apertures in which a whole piece keeps one
  class that is not mixed; their mean length is how many sub-apertures one classification and
  one set of lanes could serve (visibility that follows the antenna, docs/design.md section 10).

Usage: ``python benchmarks/coherence.py [PULSES]`` (default 256; writes ``coherence.csv``).
"""
from __future__ import annotations

import collections
import sys

import numpy as np
from _table import machine, write_csv

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.driver import mesh_trace
from sarmitsuba.tracing.visibility import lit_pieces as lp

NAME = "coherence"
#: The classes as recorded: 0 dark, 1 transmit-lit only, 2 lit, 3 mixed.
CLASSES = ("dark", "transmit", "lit", "mixed")
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


def record(scene: str, pulses: int) -> dict:
    """{(order, sub-aperture): {piece key: class}} of one render (the classifier wrapped)."""
    records: dict = collections.defaultdict(dict)
    first_sub = [0]
    real_classify, real_call = lp.classify, mesh_trace.MeshTracer.__call__

    def classify(surfaces, chains, pieces, antenna, *args, **kwargs):
        out = real_classify(surfaces, chains, pieces, antenna, *args, **kwargs)
        order = int(chains.order.max(initial=0))
        cls = np.where(out.mixed, 3, np.where(out.lit, 2, np.where(out.transmit, 1, 0)))
        keys = np.concatenate([chains.parts[pieces.region], pieces.cell, pieces.whole[:, None]], axis=1)
        subs = chains.sub[pieces.region] + first_sub[0]
        for key, sub, c in zip(map(tuple, keys.tolist()), subs.tolist(), cls.tolist()):
            records[(order, sub)][key] = c
        return out

    def call(self, ctx, launch):
        out = real_call(self, ctx, launch)
        first_sub[0] += launch.n_subapertures
        return out

    lp.classify = mesh_trace.classify = classify
    mesh_trace.MeshTracer.__call__ = call
    try:
        simulate(scene, sensor_overrides={"n_pulses": pulses}, integrator_overrides={"max_depth": MAX_DEPTH})
    finally:
        lp.classify = mesh_trace.classify = real_classify
        mesh_trace.MeshTracer.__call__ = real_call
    return records


def summarise(records: dict) -> list[dict]:
    """One row per bounce order (see the module docstring)."""
    rows = []
    for order in sorted({o for o, _ in records}):
        per = [records[key] for key in sorted(k for k in records if k[0] == order)]
        counts = np.array([[sum(1 for v in r.values() if v == c) for c in range(4)] for r in per])
        both = only = 0
        moves = collections.Counter()
        for a, b in zip(per[:-1], per[1:]):
            common = a.keys() & b.keys()
            only += len(a.keys() ^ b.keys())
            both += len(common)
            moves.update((a[k], b[k]) for k in common)
        seen = collections.defaultdict(list)
        for i, r in enumerate(per):
            for key, c in r.items():
                seen[key].append((i, c))
        runs = steady = 0
        for key, visits in seen.items():
            last = None
            for i, c in visits:
                if c == 3 or not key[-1]:
                    last = None
                    continue
                runs += last is None or last != (i - 1, c)
                steady += 1
                last = (i, c)
        row = {"order": order + 1, "sub_apertures": len(per)}
        row.update({f"{name}_per_sub": int(round(v)) for name, v in zip(CLASSES, counts.mean(axis=0))})
        row["kept_class"] = round(sum(v for (a, b), v in moves.items() if a == b) / max(both, 1), 4)
        row["in_one_only_per_pair"] = round(only / max(len(per) - 1, 1))
        row["in_both_per_pair"] = round(both / max(len(per) - 1, 1))
        row["steady_share"] = round(steady / max(sum(len(v) for v in seen.values()), 1), 3)
        row["mean_run_subs"] = round(steady / max(runs, 1), 2)
        rows.append(row)
    return rows


def main() -> None:
    pulses = int(sys.argv[1]) if len(sys.argv) > 1 else 256
    print(machine(), flush=True)
    rows = summarise(record("sionna:munich", pulses))
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    write_csv(NAME + ".csv", rows)


if __name__ == "__main__":
    main()
