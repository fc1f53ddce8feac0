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
from .polar_bistatic import BistaticFrame

__all__ = ["check_knobs", "subaperture_spans", "n_blocks", "grid_edge_points", "phase_centres", "plan_polar",
           "row_geometry", "rows_reached", "normalisation", "is_bistatic", "residual_spread", "bistatic_frame",
           "SUBAPERTURE", "GAIN_STEP", "BLOCK_COLUMNS", "BAND_MARGIN"]

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
#: Factor on the measured angular band of a bistatic polar image (F10): its largest residual rate is
#: probed at grid points, and the band carries the rates' spread besides (1.1: a 100 m/s receiver's
#: point target -41.2 dB -> -47.3 dB against ``backproject``, 1.25: -48.9 dB).
BAND_MARGIN = 1.1
#: Rows and columns between the exact evaluations of the expected gain (the normalisation).
GAIN_STEP = 32
#: Grid columns per range block of the last step (the unit of work of one thread).
BLOCK_COLUMNS = 512

def check_knobs(raw: RawData, subaperture: Any, angle_oversample: Any, range_oversample: Any) -> dict[str, Any]:
    """The ffbp knobs checked and normalised: ``{"subaperture": int, "range_oversample": int,
    "angle_oversample": float}``. Raises ValueError naming a knob outside its range (``subaperture``
    1 .. n_pulses, ``range_oversample`` 1 .. 8, ``angle_oversample`` [1.25, 8]). Any geometry passes
    here: bistatic data get polar images on the half range sum (:func:`plan_polar`, (F10))."""
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


def is_bistatic(raw: RawData, pulses: slice = slice(None)) -> bool:
    """True for stop-and-hop data (no ``rx_time``) whose receiver is not at the transmitter at some
    pulse of ``pulses``: their polar images are :class:`~.polar_bistatic.BistaticFrame`'s (F10)."""
    return raw.rx_time is None and not np.array_equal(raw.tx_position[pulses], raw.rx_position[pulses])


def residual_spread(raw: RawData, pulses: slice) -> float:
    """The largest one-way residual ``|L_p / 2 - r|`` [m] a sub-aperture's pulses can have about its
    polar coordinates: ``max |A_p - c|`` over :func:`phase_centres` (monostatic, continuous motion);
    ``max (|T_p - T_c| + |R_p - R_c|) / 2`` for bistatic data (F10)."""
    if is_bistatic(raw, pulses):
        tx, rx = raw.tx_position[pulses], raw.rx_position[pulses]
        return float(np.max(0.5 * (np.linalg.norm(tx - tx.mean(axis=0), axis=1)
                                    + np.linalg.norm(rx - rx.mean(axis=0), axis=1))))
    antennas = phase_centres(raw, pulses)
    return float(np.max(np.linalg.norm(antennas - antennas.mean(axis=0), axis=1)))


def plan_polar(raw: RawData, grid: ImageGrid, beam: BeamWeighting, pulses: slice, angle_oversample: float,
          edges: np.ndarray, range_factor: int = 1
          ) -> tuple[PolarFrame, PolarAxes, tuple[float, float], tuple[float, float]] | None:
    """Frame, axes and nonzero sines of the polar image of the pulses ``pulses``; None when it
    sees no pixel.

    Sines: the grid's, cut to the beam widened by the sub-aperture's extent (``|A_p - c| / r``
    and the turn of the velocity). Ranges: those of the grid's edge pixels within these sines
    (the extremes of the distance over a region of the plane lie on its boundary), cut to the
    fast-time window. The sine step resolves ``2 (fc + B/2) / c x max |A_p - c| x |du/ds|``
    cycles per unit sine plus :data:`WEIGHT_CYCLES` per beam width, ``angle_oversample`` times;
    the range step is ``c / (2 fs)``. Both axes get margins (:data:`S_MARGIN`, :data:`R_MARGIN`).
    Bistatic data (:func:`is_bistatic`): :func:`_plan_bistatic` (F10), its range step ``c / (2 fs
    range_factor)``.
    """
    if is_bistatic(raw, pulses):
        return _plan_bistatic(raw, grid, beam, pulses, angle_oversample, edges, range_factor)
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
    return frame, _axes(raw, f_max, angle_oversample, s_lo, s_hi, r_lo, r_hi, 1), (s_lo, s_hi), \
        (float(window[0]), float(window[1]))


def _axes(raw: RawData, f_max: float, angle_oversample: float, s_lo: float, s_hi: float, r_lo: float,
          r_hi: float, factor: int) -> PolarAxes:
    """The polar axes over ``[s_lo, s_hi] x [r_lo, r_hi]``: sine step ``1 / (2 f_max angle_oversample)``
    (at most :data:`MAX_SINES` sines), range step ``c / (2 fs factor)``, with the margins."""
    ds = 1.0 / (2.0 * max(f_max, 1e-12) * angle_oversample)
    n_s = min(int(np.ceil((s_hi - s_lo) / ds)) + 1, MAX_SINES)
    ds = max(ds, (s_hi - s_lo) / max(n_s - 1, 1))
    dr = SPEED_OF_LIGHT / (2.0 * raw.fs) / factor if factor != 1 else SPEED_OF_LIGHT / (2.0 * raw.fs)
    n_r = int(np.ceil((r_hi - r_lo) / dr)) + 1 + 2 * R_MARGIN * factor
    return PolarAxes(s_lo - S_MARGIN * ds, ds, n_s + 2 * S_MARGIN, r_lo - R_MARGIN * factor * dr, dr,
                     -(-n_r // RSTEP) * RSTEP)


def _plan_bistatic(raw: RawData, grid: ImageGrid, beam: BeamWeighting, pulses: slice, angle_oversample: float,
                   edges: np.ndarray, factor: int
                   ) -> tuple[BistaticFrame, PolarAxes, tuple[float, float], tuple[float, float]] | None:
    """:func:`plan_polar` for bistatic data (F10): a :class:`~.polar_bistatic.BistaticFrame`, ``r`` the
    half range sum, sampled at ``c / (2 fs factor)`` (the image is formed at its final range step, not
    upsampled); the angular band from the pulses' largest residual rate (:func:`_bistatic_rate`);
    and the sheared lattice ``s' = s - a (rho - rho_mid)``, ``a`` the least-squares slope of ``s``
    along the beam's edges within the grid (:func:`_common_slope`; without a beam, along the grid's
    boundary): the beam is a band of the transmitter's sines, slanted in ``(s, rho)`` by the
    receiver's. The axes' sines are ``s'``; ``BAND_MARGIN`` widens the band."""
    frame = bistatic_frame(raw, grid, pulses)
    extent = _bistatic_extent(raw, grid, beam, pulses, frame, edges)
    if extent is None:
        return None
    s, rho, where = extent
    window = SPEED_OF_LIGHT * raw.fast_time[[0, -1]] / 2.0
    step = max([float(np.max(np.diff(axis))) for axis in (grid.azimuth, grid.range) if axis.size > 1] + [0.0])
    r_lo = max(float(rho.min()) - step, window[0] - frame.spread)
    r_hi = min(float(rho.max()) + step, window[1] + frame.spread)
    if r_lo > r_hi:
        return None
    rate = _bistatic_rate(frame, grid, edges)
    f_max = 2.0 * (raw.fc + raw.bandwidth / 2.0) / SPEED_OF_LIGHT * frame.spread * rate * BAND_MARGIN
    if not np.isfinite(f_max):
        raise GeometryNotSupported("ffbp: no grid point within the sub-aperture's beam is a regular point of its "
                                   "bistatic polar coordinates; use backproject")
    if beam.sines is not None:       # the beam weight varies across the beam (of the transmitter's sines)
        f_max += WEIGHT_CYCLES / (frame.w_t * (beam.sines[1] - beam.sines[0]))
    mid = 0.5 * (r_lo + r_hi)
    frame.shear = (np.array([_common_slope(s, rho, where), 0.0]), mid)
    lattice = s - frame.lattice_shift(rho)
    pad = 1e-9 + 0.5 * max([float(np.max(np.abs(np.diff(lattice[where == g])), initial=0.0)) for g in (1, 2)])
    s_lo, s_hi = float(lattice.min()) - pad, float(lattice.max()) + pad
    return frame, _axes(raw, f_max, angle_oversample, s_lo, s_hi, r_lo, r_hi, factor), (s_lo, s_hi), \
        (float(window[0]), float(window[1]))


def _common_slope(s: np.ndarray, rho: np.ndarray, where: np.ndarray) -> float:
    """The least-squares slope ``d s / d rho`` common to the beam's two edges (``where`` 1 and 2, each
    with its own intercept: the edges lie apart in ``rho`` as well as in ``s``), or of all the
    points when the beam's edges do not cross the grid; 0 when ``rho`` does not vary."""
    groups = [where == 1, where == 2] if np.count_nonzero(where) > 2 else [np.ones(where.size, bool)]
    num = den = 0.0
    for g in groups:
        if g.sum() > 1:
            dr, ds = rho[g] - rho[g].mean(), s[g] - s[g].mean()
            num, den = num + float(dr @ ds), den + float(dr @ dr)
    return num / den if den > 0 else 0.0


def bistatic_frame(raw: RawData, grid: ImageGrid, pulses: slice) -> BistaticFrame:
    """The :class:`~.polar_bistatic.BistaticFrame` of a sub-aperture of bistatic data: ``V_T`` the
    transmitters' mean velocity, ``V_R`` the receivers' (the data do not carry it: the mean of the
    receive positions' finite differences over ``pulse_time``; zero for a single pulse)."""
    lo, hi = max(pulses.start - 1, 0), min(pulses.stop + 1, raw.n_pulses)
    if hi - lo > 1:
        rates = np.gradient(raw.rx_position[lo:hi], raw.pulse_time[lo:hi], axis=0)
        rx_velocity = rates[pulses.start - lo:pulses.stop - lo].mean(axis=0)
    else:
        rx_velocity = np.zeros(3)
    return BistaticFrame(raw.tx_position[pulses], raw.rx_position[pulses], raw.velocity[pulses].mean(axis=0),
                         rx_velocity, grid)


def _bistatic_extent(raw: RawData, grid: ImageGrid, beam: BeamWeighting, pulses: slice, frame: BistaticFrame,
                     edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(s, rho)`` float64 [n] of the boundary points of the grid's part in the sub-aperture's beams
    (F10) and where each lies (int [n]: 0 a grid edge, 1 and 2 the beam's two edges), or None when
    the beams miss the grid.

    The beam holds the points whose transmitter sine (:meth:`~.polar_bistatic.BistaticFrame.tx_sine`)
    lies in the beam's sines widened by ``1.05 max |T_p - T_c| / |x - T_c|`` and the turn of the
    velocity; the extremes of ``s`` and ``rho`` over that part lie on its boundary: the grid's
    edge pixels inside and the two widened beam edges inside the grid (65 points each, along the
    closed-form cone of the transmitter's sine, (F2))."""
    points = [edges]
    keep = np.ones(edges.shape[0], bool)
    if beam.sines is not None:
        r_t = np.linalg.norm(edges - frame.centre, axis=1)
        turn = float(np.max(np.linalg.norm(beam_axes(raw)[pulses] - frame.direction, axis=1)))
        margin = 1.05 * frame.tx_spread / max(float(r_t.min()), 1e-9) + turn + 1e-9
        sine = frame.tx_sine(edges)
        keep = (sine >= beam.sines[0] - margin) & (sine <= beam.sines[1] + margin)
        frame.beam_span = (beam.sines[0] - margin, beam.sines[1] + margin)
        ranges = np.linspace(r_t.min(), r_t.max(), 65)
        for edge in (beam.sines[0] - margin, beam.sines[1] + margin):
            xi1, xi2, valid = frame.in_plane(np.full(ranges.size, edge), ranges)
            curve = frame.centre + frame.h * frame.normal + xi1[:, None] * frame.e1 + xi2[:, None] * frame.e2
            points.append(curve)
            keep = np.concatenate([keep, valid & _in_grid(grid, curve)])
    if not keep.any():
        return None
    s, rho = frame.coordinates(np.concatenate(points)[keep])
    return s, rho, (np.arange(keep.size) >= edges.shape[0])[keep] * (1 + (np.arange(keep.size) >= keep.size - 65))[keep]


def _in_grid(grid: ImageGrid, x: np.ndarray) -> np.ndarray:
    """bool [n]: the plane points ``x`` [n, 3] within the grid's azimuth and range spans."""
    e = np.stack([grid.azimuth_direction, grid.range_direction])                       # [2, 3]
    ab = np.linalg.solve(e @ e.T, e @ (x - grid.origin).T)                               # [2, n]
    return ((ab[0] >= grid.azimuth.min()) & (ab[0] <= grid.azimuth.max())
            & (ab[1] >= grid.range.min()) & (ab[1] <= grid.range.max()))


def _bistatic_rate(frame: BistaticFrame, grid: ImageGrid, edges: np.ndarray) -> float:
    """The largest :meth:`~.polar_bistatic.BistaticFrame.residual_rate` over plane points of the grid within the
    sub-aperture's beams (``frame.beam_span`` of transmitter sines; every 8th edge pixel and a 9 x 9
    lattice, all of them when none lies in the beams: the corners of the ``(s, rho)`` box need not be
    plane points); inf when none is a regular plane point."""
    rows = np.linspace(0, grid.shape[0] - 1, 9).round().astype(int)
    cols = np.linspace(0, grid.shape[1] - 1, 9).round().astype(int)
    lattice = (grid.origin + grid.azimuth[rows][:, None, None] * grid.azimuth_direction
               + grid.range[cols][None, :, None] * grid.range_direction).reshape(-1, 3)
    points = np.concatenate([edges[::8], edges[-1:], lattice])
    sine = frame.tx_sine(points)
    inside = (sine >= frame.beam_span[0]) & (sine <= frame.beam_span[1])
    rate = frame.residual_rate(points[inside] if inside.any() else points)       # a beam between the probes: all
    rate = rate[np.isfinite(rate)]
    return float(rate.max()) if rate.size else np.inf


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
    if isinstance(frame, BistaticFrame):              # its pulses' beams: the transmitter's sines
        s = frame.tx_sine(grid.origin + grid.azimuth[:, None, None, None] * grid.azimuth_direction
                          + probe[None, ..., None] * grid.range_direction)
        span = frame.beam_span
    else:
        r = np.sqrt(q[:, None, None] + probe[None] * (2.0 * p[:, None, None] + probe[None]))
        s = (rel @ v + grid.azimuth[:, None, None] * (grid.azimuth_direction @ v)
             + probe[None] * (grid.range_direction @ v)) / r
        span = image.s_span
    hit = (s.max(axis=2) >= span[0]) & (s.min(axis=2) <= span[1])                          # [n_az, n_b]
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
