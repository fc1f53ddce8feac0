"""How far each interpolant of synthetic_s1_poeorb.EOF lies from the orbit it was written from
(docs/physics.md (J6)): the two-body + J2 orbit of make_orbit.py, propagated again by DOP853 to the
middle of every 10 s interval, against sarmitsuba's 4-point Hermite window, scipy's piecewise cubic
Hermite and a not-a-knot spline through the positions alone. Run from the repository root:
``python tests/data/orbit/interpolation_error.py``. Prints the largest error of each, in mm.
"""
from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from pyproj import Transformer
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).parent))
import make_orbit as M  # noqa: E402

from sarmitsuba.core.trajectory import from_state_vectors, read_state_vectors  # noqa: E402


def main() -> None:
    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=False)
    r0 = np.array(to_ecef.transform(M.LAT0, M.LON0, 693e3))
    up = r0 / np.linalg.norm(r0)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    north = np.cross(up, east)
    az = math.pi - math.asin(math.cos(math.radians(98.18)) / math.cos(math.asin(up[2])))
    v0 = math.sqrt(M.GM / np.linalg.norm(r0)) * (math.sin(az) * east + math.cos(az) * north)
    half = M.STEP * M.HALF
    t = np.arange(-half + M.STEP / 2, half, M.STEP)               # the middle of every interval
    y0 = np.concatenate([r0, v0])
    kw = dict(method="DOP853", rtol=1e-13, atol=1e-6)
    fwd = solve_ivp(M.gravity, (0, half), y0, t_eval=t[t > 0], **kw)
    back = solve_ivp(M.gravity, (0, -half), y0, t_eval=t[t < 0][::-1], **kw)
    y = np.concatenate([back.y[:, ::-1], fwd.y], axis=1).T
    c, s = np.cos(-M.OMEGA * t), np.sin(-M.OMEGA * t)
    truth = np.stack([c * y[:, 0] - s * y[:, 1], s * y[:, 0] + c * y[:, 1], y[:, 2]], axis=1)
    states = read_state_vectors(Path(__file__).with_name("synthetic_s1_poeorb.EOF"))
    for name, sv in (("4-point Hermite window", states), ("piecewise cubic Hermite", replace(states, window=0)),
                     ("spline through positions", replace(states, window=0, velocity=None))):
        error = np.linalg.norm(from_state_vectors(sv).position(t + half) - truth, axis=1)
        print(f"{name:26s} max error {error.max() * 1e3:.4f} mm")


if __name__ == "__main__":
    main()
