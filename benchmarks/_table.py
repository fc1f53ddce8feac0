"""Shared output of the benchmark scripts: a CSV table under benchmarks/out/."""
from __future__ import annotations

import csv
from pathlib import Path


def write_csv(name: str, rows: list[dict]) -> Path:
    """Write ``rows`` (dicts with the same keys) to ``benchmarks/out/NAME``; returns the path."""
    out = Path(__file__).parent / "out"
    out.mkdir(exist_ok=True)
    path = out / name
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path}")
    return path
