"""Focusing benchmark: omega-K and range-Doppler against their FFT floor, backprojection throughput.

Run ``python benchmarks/focus_bench.py`` (``--size`` to change the FFT-focuser size). It
prints a table and writes ``focus.csv`` into the benchmarks' output folder (``--out`` of run.py, default ``./out/bench``). Ratios are measured in the same
run (the machine is shared and noisy, docs/design.md section 10):

* **omega-K** and **RDA** on an ``N x N`` (default 4096 x 4096) complex64 range-compressed
  array (white noise on a straight track: the cost does not depend on the scene), each
  against the time of *the same scipy FFT passes* on arrays of the same shapes (the
  padded range axis included; omega-K's range IFFT on its ``n_out`` Stolt output bins),
  i.e. the cost of the algorithm if its interpolation and phase multiplies were free.
  Also the ratio to four plain N x N FFT passes.
* **Backprojection** (:func:`sarmitsuba.focus.backproject`) on a 1024 x 1024 slant grid
  from 1024 pulses, in pixel-pulses (backprojections) per second.

Each timing is the best of ``--repeat`` runs (default 2) with all CPUs as workers.
"""
from __future__ import annotations

import argparse
import csv
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import scipy.fft

from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import backproject
from sarmitsuba.focus.omegak import omega_k
from sarmitsuba.focus.rda import _GUARD, range_doppler
from sarmitsuba.focus.stripmap import slant_output_grid, stripmap_geometry
from sarmitsuba.core.raw import RawData

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _table import output_dir  # noqa: E402



def noise_raw(n_pulses: int, n_samples: int, *, seed: int = 1) -> RawData:
    """Airborne X-band straight-track RawData holding complex white noise (10 km, 21.9 deg squint free)."""
    fc, bw, fs, prf, speed, h, r = 9.6e9, 150e6, 180e6, 400.0, 100.0, 6000.0, 10e3
    rng = np.random.default_rng(seed)
    data = np.empty((n_pulses, n_samples), np.complex64)
    data.real = rng.standard_normal((n_pulses, n_samples), np.float32)
    data.imag = rng.standard_normal((n_pulses, n_samples), np.float32)
    t = (np.arange(n_pulses) - (n_pulses - 1) / 2) / prf
    pos = np.zeros((n_pulses, 3))
    pos[:, 0] = speed * t
    pos[:, 1] = np.sqrt(r**2 - h**2)
    pos[:, 2] = h
    vel = np.tile([speed, 0.0, 0.0], (n_pulses, 1))
    fast = 2 * r / C + (np.arange(n_samples) - n_samples // 2) / fs
    return RawData(data=data, fast_time=fast, pulse_time=t, tx_position=pos, rx_position=pos.copy(),
                   velocity=vel, fc=fc, bandwidth=bw, chirp_rate=bw / 1e-6, pulse_length=1e-6, fs=fs, prf=prf,
                   range_compressed=True, metadata={"scene": "benchmark noise"})


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def fft_passes(shapes: list[tuple[tuple[int, int], int, bool]], workers: int, repeat: int) -> float:
    """Time of scipy FFT passes: each ``(shape, axis, inverse)`` on a complex64 array of that shape."""
    arrays = [np.ones(shape, np.complex64) for shape, _, _ in shapes]

    def run():
        for a, (_, axis, inverse) in zip(arrays, shapes):
            (scipy.fft.ifft if inverse else scipy.fft.fft)(a, axis=axis, workers=workers)
    return best(run, repeat)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=4096, help="N for the N x N FFT-focuser runs (default 4096)")
    parser.add_argument("--bp-size", type=int, default=1024, help="backprojection grid side and pulses (1024)")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args(argv)
    workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    n = args.size
    raw = noise_raw(n, n)
    geo = stripmap_geometry(raw, squint=0.0, scene_centre=(0.0, 0.0, 0.0))
    rows = []

    # ---- omega-K (default 12 taps, oversample 1.5): forward FFTs on the padded n_pad columns,
    # range IFFT on the Stolt output's n_out columns (metadata of the timed run)
    focus = {}
    t_wk = best(lambda: focus.update(omega_k(raw, geometry=geo, workers=workers).metadata["focus"]), args.repeat)
    n_pad, n_out = focus["n_pad"], focus["n_out"]
    floor_wk = fft_passes([((n, n_pad), 1, False), ((n, n_pad), 0, False), ((n, n_out), 1, True),
                           ((n, n), 0, True)], workers, args.repeat)
    # ---- RDA (8 taps, upsample 2)
    t_rd = best(lambda: range_doppler(raw, geometry=geo, workers=workers), args.repeat)
    n1 = scipy.fft.next_fast_len(n + _GUARD)
    floor_rd = fft_passes([((n, n1), 1, False), ((n, n1), 0, False), ((n, 2 * n1), 1, True),
                           ((n, n), 0, True)], workers, args.repeat)
    plain = fft_passes([((n, n), 1, False), ((n, n), 0, False), ((n, n), 1, True), ((n, n), 0, True)],
                       workers, args.repeat)
    for name, t, floor in (("omega-k", t_wk, floor_wk), ("rda", t_rd, floor_rd)):
        rows.append({"benchmark": name, "shape": f"{n}x{n}", "seconds": t, "fft_floor_seconds": floor,
                     "ratio_to_fft_floor": t / floor, "ratio_to_4_plain_fft_passes": t / plain,
                     "msamples_per_second": n * n / t / 1e6, "pixel_pulses_per_second": ""})
    rows.append({"benchmark": "4 plain fft passes", "shape": f"{n}x{n}", "seconds": plain, "fft_floor_seconds": plain,
                 "ratio_to_fft_floor": 1.0, "ratio_to_4_plain_fft_passes": 1.0,
                 "msamples_per_second": n * n / plain / 1e6, "pixel_pulses_per_second": ""})

    # ---- backprojection
    m = args.bp_size
    raw_bp = noise_raw(m, 2 * m)
    geo_bp = stripmap_geometry(raw_bp, squint=0.0, scene_centre=(0.0, 0.0, 0.0))
    full = slant_output_grid(geo_bp, raw_bp)
    grid = type(full)(origin=full.origin, azimuth_direction=full.azimuth_direction,
                      range_direction=full.range_direction, azimuth=full.azimuth[:m],
                      range=full.range[m // 2:m // 2 + m], plane="slant")
    t_bp = best(lambda: backproject(raw_bp, grid, workers=workers), 1)
    rows.append({"benchmark": "backprojection", "shape": f"{m}x{m} grid, {m} pulses", "seconds": t_bp,
                 "fft_floor_seconds": "", "ratio_to_fft_floor": "", "ratio_to_4_plain_fft_passes": "",
                 "msamples_per_second": "", "pixel_pulses_per_second": m * m * m / t_bp})

    # ---- report
    print(f"focusing benchmark: {platform.processor() or platform.machine()}, {workers} workers, "
          f"numpy {np.__version__}, scipy {scipy.__version__}")
    print(f"{'benchmark':<22}{'shape':<28}{'seconds':>9}{'FFT floor':>11}{'ratio':>8}{'/4 FFT':>8}{'rate':>14}")
    for r in rows:
        rate = (f"{r['pixel_pulses_per_second']:.3g} bp/s" if r["pixel_pulses_per_second"] != ""
                else f"{r['msamples_per_second']:.1f} MS/s")
        floor = f"{r['fft_floor_seconds']:.3f}" if r["fft_floor_seconds"] != "" else "-"
        ratio = f"{r['ratio_to_fft_floor']:.2f}" if r["ratio_to_fft_floor"] != "" else "-"
        plain_r = f"{r['ratio_to_4_plain_fft_passes']:.2f}" if r["ratio_to_4_plain_fft_passes"] != "" else "-"
        print(f"{r['benchmark']:<22}{r['shape']:<28}{r['seconds']:>9.3f}{floor:>11}{ratio:>8}{plain_r:>8}{rate:>14}")
    out = output_dir() / "focus.csv"
    with open(out, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
