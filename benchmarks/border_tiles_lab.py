"""Owned regions against whole tiles on a plate, in NumPy (issue 26; a lab, not in the suite).

The kernel's lit regions are unions of whole tube tiles: a tube whose central ray meets a facet
counts its whole tile, so a facet's border returns as the tubes' staircase, which moves with the
lattice and, for an elevated facet, jumps between sub-apertures (docs/physics.md (T3)). The owned
partition (:mod:`sarmitsuba.owned_regions`, docs/physics.md (T6)) gives each member tube a convex
region clipped to the facet; the regions tile the facet for every pulse.

The case: a square PEC plate 4 m wide at height ``h`` above the aim plane (``z = 0``), turned by
``psi`` about the vertical, seen by the default sensor (1000 m altitude, 45 deg incidence, 0.667 m
between pulses), ``--tubes`` tubes across. Its first-bounce PO per pulse and frequency (5 across
100 MHz at 9.6 GHz), with the plane-wave phase about the plate's centre, is compared:

* ``exact``: with the closed form over the whole plate (Gordon 1975);
* ``moved``: with the lattice moved by (0.37, 0.41) cells;
* ``subap``: 19 pulses per trace (the default's size here) with one pulse per trace.

Both methods use exact polygon integrals, so the lab measures the lit regions alone, not the
kernel's per-tile PO terms.

Usage: ``python benchmarks/border_tiles_lab.py [--tubes 20] [--height 0,35] [--psi 30,60] [--pulses 96]``
"""
from __future__ import annotations

import argparse
import math

import numpy as np

from sarmitsuba.owned_regions import owned_regions, region_polygons
from sarmitsuba.physical_optics import polygon_integral

C = 299_792_458.0
TRACK = np.array([1.0, 0.0, 0.0])
LOOK = np.array([0.0, 1.0, 0.0])
UP = np.array([0.0, 0.0, 1.0])      # TRACK x LOOK: cells are counter-clockwise about +z


def project(points: np.ndarray, antenna: np.ndarray, z: float) -> np.ndarray:
    """Rays from ``antenna`` through ``points`` meet the plane ``z``."""
    t = (antenna[2] - z) / (antenna[2] - points[..., 2])
    return antenna + (points - antenna) * t[..., None]


def _integral(poly2d: np.ndarray, q: np.ndarray) -> complex:
    """Gordon's closed form over a horizontal polygon given in (x, y), without the ``q_z h`` phase."""
    return polygon_integral(np.c_[poly2d, np.zeros(len(poly2d))], UP, np.r_[q[:2], 0.0])


def inside(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Points (horizontal) inside a convex counter-clockwise polygon."""
    ok = np.ones(points.shape[:-1], bool)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        e, r = b - a, points - a
        ok &= e[0] * r[..., 1] - e[1] * r[..., 0] > 0
    return ok


class Lab:
    def __init__(self, tubes: int, height: float, psi_deg: float, side: float = 4.0, n_pulses: int = 96,
                 n_freq: int = 5):
        self.h = height
        fc, bandwidth = 9.6e9, 100e6
        self.k = 2 * math.pi * np.linspace(fc - bandwidth / 2, fc + bandwidth / 2, n_freq) / C
        altitude, incidence = 1000.0, math.radians(45.0)
        g = altitude * math.tan(incidence)
        x = (np.arange(n_pulses) - (n_pulses - 1) / 2) * 100.0 / 150.0
        self.antenna = np.stack([x, np.full_like(x, -g), np.full_like(x, altitude)], axis=1)
        psi = math.radians(psi_deg)
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * side / 2
        rot = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])
        self.plate = np.concatenate([corners @ rot.T, np.full((4, 1), height)], axis=1)
        self.ds = side / tubes                              # tube width on the aim plane (along track)
        self.dg = self.ds / math.cos(incidence)             # and in ground range
        self.centre = np.array([0.0, 0.0, height])

    def q(self, antenna: np.ndarray, k: float) -> np.ndarray:
        d = self.centre - antenna
        return -2.0 * k * d / np.linalg.norm(d)             # two-way plane-wave phase about the centre

    def exact(self, antenna: np.ndarray) -> np.ndarray:
        """The closed form over the whole plate (Gordon 1975, ``physical_optics.polygon_integral``)."""
        return np.array([polygon_integral(self.plate, UP, self.q(antenna, k)) for k in self.k])

    # ------------------------------------------------------------------ the lattice at A_ref
    def members(self, reference: np.ndarray, shift: tuple[float, float]):
        """Cell indices whose central ray from ``reference`` meets the plate, and the membership grid."""
        foot = project(self.plate, reference, 0.0)
        lo, hi = foot.min(axis=0) - 3 * np.array([self.ds, self.dg, 0]), foot.max(axis=0) + 3 * np.array([self.ds, self.dg, 0])
        i = np.arange(math.floor(lo[0] / self.ds - shift[0]), math.ceil(hi[0] / self.ds - shift[0]))
        j = np.arange(math.floor(lo[1] / self.dg - shift[1]), math.ceil(hi[1] / self.dg - shift[1]))
        ii, jj = np.meshgrid(i, j, indexing="ij")
        centres = self.cell_point(ii, jj, 0.5, 0.5, shift)
        hit = project(centres, reference, self.h)
        grid = inside(hit[..., :2], self.plate[:, :2])
        return i, j, grid

    def cell_point(self, i, j, fa, fg, shift):
        a = (np.asarray(i) + shift[0] + fa) * self.ds
        g = (np.asarray(j) + shift[1] + fg) * self.dg
        return np.stack([a, g, np.zeros_like(a)], axis=-1)

    # ------------------------------------------------------------------ one pulse's sum
    def staircase(self, antenna, reference, shift) -> np.ndarray:
        """Today's kernel: every member tube's whole tile as the pulse sees it (docs/physics.md (T3))."""
        i, j, grid = self.members(reference, shift)
        out = np.zeros(self.k.size, complex)
        for a, b in zip(*np.nonzero(grid)):
            tile = np.array([project(self.cell_point(i[a], j[b], fa, fg, shift), antenna, self.h)[:2]
                             for fa, fg in ((0, 0), (1, 0), (1, 1), (0, 1))])
            out += [_integral(tile, self.q(antenna, k)) for k in self.k]
        return out * self.phase(antenna)

    def owned(self, antenna, reference, shift) -> np.ndarray:
        """Every member tube integrates its owned region clipped to the plate (docs/physics.md (T6))."""
        i, j, grid = self.members(reference, shift)
        members = {(int(i[a]), int(j[b])) for a, b in zip(*np.nonzero(grid))}
        point = lambda a, g: project(self.cell_point(a, g, 0.0, 0.0, shift), antenna, self.h)[:2]  # noqa: E731
        column = lambda a: (point(a, 0), point(a, 1))            # noqa: E731  (left: column a - 1)
        row = lambda g: (point(0, g), point(-1, g))              # noqa: E731  (left: row g - 1)
        polys = [p for ps in region_polygons(self.plate[:, :2], owned_regions(members, column, row)).values()
                 for p in ps]
        out = np.array([sum(_integral(p, self.q(antenna, k)) for p in polys) for k in self.k])
        return out * self.phase(antenna)

    def phase(self, antenna) -> np.ndarray:
        """The plane-wave phase's constant part over the plate's plane (``q_z h``)."""
        return np.exp(1j * np.array([self.q(antenna, k)[2] * self.h for k in self.k]))

    def data(self, pulses_per_trace: int, shift, method: str) -> np.ndarray:
        rows = []
        n = len(self.antenna)
        for s0 in range(0, n, pulses_per_trace):
            block = self.antenna[s0:s0 + pulses_per_trace]
            reference = 0.5 * (block[0] + block[-1])
            rows += [getattr(self, method)(a, reference, shift) for a in block]
        return np.array(rows)


def nrmse_db(a, b):
    return 20 * math.log10(max(np.linalg.norm(a - b) / np.linalg.norm(b), 1e-15))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tubes", type=int, default=20, help="tubes across the plate")
    parser.add_argument("--height", default="0,35", help="plate heights above the aim plane, m")
    parser.add_argument("--psi", default="30,60", help="plate turns about the vertical, deg")
    parser.add_argument("--pulses", type=int, default=96)
    args = parser.parse_args()
    print(f"{'h m':>5} {'psi':>4} {'method':>9} {'exact dB':>9} {'moved dB':>9} {'subap dB':>9}")
    for h in (float(v) for v in args.height.split(",")):
        for psi in (float(v) for v in args.psi.split(",")):
            lab = Lab(args.tubes, h, psi, n_pulses=args.pulses)
            truth = np.array([lab.exact(a) for a in lab.antenna])
            for method in ("staircase", "owned"):
                base = lab.data(1, (0.0, 0.0), method)
                moved = lab.data(1, (0.37, 0.41), method)
                sub = lab.data(19, (0.0, 0.0), method)
                print(f"{h:5.0f} {psi:4.0f} {method:>9} {nrmse_db(base, truth):9.1f} "
                      f"{nrmse_db(moved, base):9.1f} {nrmse_db(sub, base):9.1f}", flush=True)


if __name__ == "__main__":
    main()
