"""Planning of fast factorised backprojection (:mod:`.ffbp`) and of its float64 linear operator
(:mod:`.ffbp_linear`): the knobs, the sub-apertures, each sub-aperture's polar grid, the grid rows a
polar image reaches, and the normalisation. docs/physics.md (F1)-(F9).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.raw import RawData
from .beam import BeamWeighting, beam_axes, column_gain, unit_rows
from .grid import ImageGrid
from .polar import GeometryNotSupported, RSTEP, PolarAxes, PolarFrame, PolarImage
from .stripmap import check_monostatic

__all__ = ["check_knobs", "subaperture_spans", "n_blocks", "grid_edge_points", "phase_centres", "plan_polar",
           "row_geometry", "rows_reached", "normalisation", "SUBAPERTURE", "GAIN_STEP", "BLOCK_COLUMNS"]

#: Default pulses per sub-aperture (docs/physics.md (F1); measured in benchmarks/ffbp.py).
SUBAPERTURE = 16
#: Extra polar samples beyond the needed sines (cubic spline support and prefilter start-up).
S_MARGIN = 6
#: Extra range samples beyond the needed ranges (more than polar.TAPER + the spline support).
R_MARGIN = 16
#: Cycles per beam width of the beam weighting ``w(u)`` (and of the pattern in the data) that the
#: polar images resolve on top of the sub-aperture's own angular band (Taylor nbar 4: 3).
WEIGHT_CYCLES = 4.0
#: Largest number of sines of one polar image.
MAX_SINES = 1 << 16
#: Rows and columns between the exact evaluations of the expected gain (the normalisation).
GAIN_STEP = 32
#: Grid columns per range block of the last step (the unit of work of one thread).
BLOCK_COLUMNS = 512

def check_knobs(raw: RawData, subaperture: Any, angle_oversample: Any, range_oversample: Any) -> dict[str, Any]:
    """The ffbp knobs checked and normalised: ``{"subaperture": int, "range_oversample": int,
    "angle_oversample": float}``. Raises GeometryNotSupported for bistatic data without
    ``rx_time`` (:func:`~.stripmap.check_monostatic`: each polar sub-image is centred on one phase
    centre ``c`` and demodulated by the monostatic carrier ``exp(-j 4 pi fc |x - c| / c)``; for a
    receiver on another platform the range sum ``|x - T| + |x - R|`` grows along ``|x - c|`` at about
    ``cos(beta / 2)`` times that rate, a residual carrier far beyond the polar images' range
    Nyquist: measured, a 48 deg bistatic point target focused 3.6 m off and 14 dB low even with
    one pulse per sub-aperture), ValueError naming a knob outside its range (``subaperture``
    1 .. n_pulses, ``range_oversample`` 1 .. 8, ``angle_oversample`` [1.25, 8])."""
    check_monostatic(raw, "ffbp (its polar sub-images assume one phase centre per sub-aperture)")
    out: dict[str, Any] = {}
    for name, value, low, high in (("subaperture", subaperture, 1, raw.n_pulses),
                                   ("range_oversample", range_oversample, 1, 8)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise ValueError(f"{name} must be an integer in {low} .. {high}, got {value!r}")
        out[name] = int(value)
    try:
        angle = float(angle_oversample)
    except (TypeError, ValueError):
        angle = float("nan")
    if not 1.25 <= angle <= 8.0:
        raise ValueError(f"angle_oversample must be a number in [1.25, 8], got {angle_oversample!r}")
    out["angle_oversample"] = angle
    return out


def subaperture_spans(n_pulses: int, length: int) -> list[tuple[int, int]]:
    """``[(start, stop), ...]``: consecutive pulse ranges of ``length`` pulses covering
    ``n_pulses`` (the last one shorter when ``length`` does not divide it)."""
    return [(p0, min(p0 + length, n_pulses)) for p0 in range(0, n_pulses, length)]


def n_blocks(grid: ImageGrid) -> int:
    """Column blocks of :data:`BLOCK_COLUMNS` ground-range columns that cover ``grid`` (the
    last one partial)."""
    return -(-grid.shape[1] // BLOCK_COLUMNS)


# ============================================================================ planning
def grid_edge_points(grid: ImageGrid) -> np.ndarray:
    """World points of every pixel on the four edges of the grid, float64 [n, 3]."""
    a, r = grid.azimuth, grid.range
    aa = np.r_[a, a, np.full(r.size, a[0]), np.full(r.size, a[-1])]
    rr = np.r_[np.full(a.size, r[0]), np.full(a.size, r[-1]), r, r]
    return grid.origin + aa[:, None] * grid.azimuth_direction + rr[:, None] * grid.range_direction


def phase_centres(raw: RawData, pulses: slice) -> np.ndarray:
    """The antenna positions that bound a sub-aperture's delays, float64 [P or 2P, 3]: the
    transmitters, and with continuous motion the receivers too (their mean is the midpoint track,
    the sub-aperture's effective monostatic phase centre)."""
    if raw.rx_time is None:
        return raw.tx_position[pulses]
    return np.concatenate([raw.tx_position[pulses], raw.rx_position[pulses]])


def plan_polar(raw: RawData, grid: ImageGrid, beam: BeamWeighting, pulses: slice, angle_oversample: float,
          edges: np.ndarray) -> tuple[PolarFrame, PolarAxes, tuple[float, float], tuple[float, float]] | None:
    """Frame, axes and nonzero sines of the polar image of the pulses ``pulses``; None when it
    sees no pixel.

    Sines: the grid's, cut to the beam widened by the sub-aperture's extent (``|A_p - c| / r``
    and the turn of the velocity). Ranges: those of the grid's edge pixels within these sines
    (the extremes of the distance over a region of the plane lie on its boundary), cut to the
    fast-time window. The sine step resolves ``2 (fc + B/2) / c x max |A_p - c| x |du/ds|``
    cycles per unit sine plus :data:`WEIGHT_CYCLES` per beam width, ``angle_oversample`` times;
    the range step is ``c / (2 fs)``. Both axes get margins (:data:`S_MARGIN`, :data:`R_MARGIN`).
    """
    antennas = phase_centres(raw, pulses)
    centre = antennas.mean(axis=0)
    velocity = unit_rows(raw.velocity[pulses])
    direction = velocity.mean(axis=0)
    direction /= np.linalg.norm(direction)
    frame = PolarFrame(centre, direction, grid)
    s_edge, r_edge = frame.coordinates(edges)
    spread = float(np.max(np.linalg.norm(antennas - centre, axis=1)))
    s_lo, s_hi = float(s_edge.min()), float(s_edge.max())
    if beam.sines is not None:
        turn = float(np.max(np.linalg.norm(beam_axes(raw)[pulses] - direction, axis=1)))   # beam sines vs frame
        margin = 1.05 * spread / max(float(r_edge.min()), 1e-9) + turn + 1e-9
        s_lo, s_hi = max(s_lo, beam.sines[0] - margin), min(s_hi, beam.sines[1] + margin)
    inside = (s_edge >= s_lo) & (s_edge <= s_hi)
    if s_lo > s_hi or not inside.any():
        return None
    window = SPEED_OF_LIGHT * raw.fast_time[[0, -1]] / 2.0
    step = max([float(np.max(np.diff(axis))) for axis in (grid.azimuth, grid.range) if axis.size > 1] + [0.0])
    r_lo = max(float(r_edge[inside].min()) - step, window[0] - spread)
    r_hi = min(float(r_edge[inside].max()) + step, window[1] + spread)
    if r_lo > r_hi:
        return None
    rate = frame.s_rate(np.array([s_lo, s_lo, s_hi, s_hi]), np.array([r_lo, r_hi, r_lo, r_hi]))
    f_max = 2.0 * (raw.fc + raw.bandwidth / 2.0) / SPEED_OF_LIGHT * spread * float(np.max(rate))
    if not np.isfinite(f_max):
        raise GeometryNotSupported("ffbp: the grid reaches the track's vertical plane (a point of it lies under "
                         "the antenna path); use backproject")
    if beam.sines is not None:       # the beam weight varies across the beam: resolve a few cycles of it
        f_max += WEIGHT_CYCLES / (beam.sines[1] - beam.sines[0])
    ds = 1.0 / (2.0 * max(f_max, 1e-12) * angle_oversample)
    n_s = min(int(np.ceil((s_hi - s_lo) / ds)) + 1, MAX_SINES)
    ds = max(ds, (s_hi - s_lo) / max(n_s - 1, 1))
    dr = SPEED_OF_LIGHT / (2.0 * raw.fs)
    n_r = int(np.ceil((r_hi - r_lo) / dr)) + 1 + 2 * R_MARGIN
    axes = PolarAxes(s_lo - S_MARGIN * ds, ds, n_s + 2 * S_MARGIN, r_lo - R_MARGIN * dr, dr,
                     -(-n_r // RSTEP) * RSTEP)
    return frame, axes, (s_lo, s_hi), (float(window[0]), float(window[1]))


def row_geometry(grid: ImageGrid, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(p, q)`` float64 [n_az]: on row ``i``, ``|x - c|^2 = rho^2 + 2 rho p_i + q_i`` for the pixel at
    range coordinate ``rho``."""
    rel = grid.origin - centre
    e_a, e_r = grid.azimuth_direction, grid.range_direction
    p = rel @ e_r + grid.azimuth * (e_a @ e_r)
    q = rel @ rel + 2.0 * grid.azimuth * (rel @ e_a) + grid.azimuth ** 2
    return p, q


def rows_reached(grid: ImageGrid, image: PolarImage, blocks: list[slice]) -> list[slice | None]:
    """Per range block, the rows with a pixel whose sine lies in the image's nonzero sines (probed at
    the block's first, middle and last columns), or None."""
    frame = image.frame
    p, q = row_geometry(grid, frame.centre)
    v = frame.direction
    rel = grid.origin - frame.centre
    probe = np.array([[grid.range[b.start], grid.range[(b.start + b.stop - 1) // 2], grid.range[b.stop - 1]]
                      for b in blocks])                                                       # [n_b, 3]
    r = np.sqrt(q[:, None, None] + probe[None] * (2.0 * p[:, None, None] + probe[None]))
    s = (rel @ v + grid.azimuth[:, None, None] * (grid.azimuth_direction @ v)
         + probe[None] * (grid.range_direction @ v)) / r
    hit = (s.max(axis=2) >= image.s_span[0]) & (s.min(axis=2) <= image.s_span[1])          # [n_az, n_b]
    out: list[slice | None] = []
    for b in range(len(blocks)):
        rows = np.flatnonzero(hit[:, b])
        out.append(slice(int(rows[0]), int(rows[-1]) + 1) if rows.size else None)
    return out


# ============================================================================ normalisation
def normalisation(raw: RawData, grid: ImageGrid, beam: BeamWeighting) -> tuple[np.ndarray, float]:
    """What the summed image is multiplied by, as ``backproject`` normalises: float64 [n_rg], one
    factor per range column (``1 /`` the summed pulse weights, or ``1 /`` the column's largest
    expected gain from :func:`~.beam.column_gain` on every :data:`GAIN_STEP`-th row and column, 0
    below 1e-6 of the largest), and the largest sum or gain."""
    if beam.sines is None:
        norm = float(beam.pulse_weights(raw.n_pulses).sum())
        return np.full(grid.shape[1], 1.0 / norm if norm > 0 else 0.0), norm
    full = column_gain(raw, grid, beam, step=GAIN_STEP)
    norm = float(full.max()) if full.size else 0.0
    floor = 1e-6 * norm if norm > 0 else 1.0
    return np.where(full > floor, 1.0 / np.maximum(full, floor), 0.0), norm
