"""Time-domain backprojection of range-compressed data onto an :class:`ImageGrid`.

Backprojection is the exact focuser: for every pixel and every pulse it looks up the
range-compressed echo at the pixel's two-way delay and removes the carrier phase,

.. math::

    I(\\mathbf{x}) = \\frac{1}{N_p} \\sum_{p=0}^{N_p - 1}
        d_p\\!\\left(\\frac{L_p(\\mathbf{x})}{c}\\right)
        \\exp\\!\\left(+j 2 \\pi f_c \\frac{L_p(\\mathbf{x})}{c}\\right),
    \\qquad L_p(\\mathbf{x}) = |\\mathbf{t}_p - \\mathbf{x}| + |\\mathbf{x} - \\mathbf{r}_p|,

where ``d_p`` is row ``p`` of :attr:`RawData.data`, interpolated in fast time (docs/design.md
sections 5 and 8; ``docs/physics.md`` eq. (S3), with eq. (S2) for the echo model
``a p_r(tau - L/c) exp(-j 2 pi fc L/c)``). A point target of amplitude ``a`` whose echo
lies inside the fast-time window of every pulse therefore focuses to a peak of ``a``.

Two implementations live here:

* :func:`backproject` -- the fast path: float32/complex64 arithmetic in the hot loop with
  hybrid precision, vectorised over pixel tiles and blocked over pulses, threaded.
* :func:`backproject_reference` -- a small, readable float64 loop over pulses with
  :func:`numpy.interp`; the oracle the fast path is tested against.

References
----------
.. [1] L. M. H. Ulander, H. Hellsten and G. Stenstrom, "Synthetic-aperture radar processing
   using fast factorized back-projection", IEEE Trans. Aerosp. Electron. Syst. 39(3),
   760-776, 2003 (section II: direct backprojection).
.. [2] ISCE3, ``cxx/isce3/focus/Backproject.cpp`` (double-precision delay and phase,
   complex64 data). The hybrid float64/float32 precision (Notes of :func:`backproject`) is
   this package's own: docs/design.md sections 5 and 8.
"""
from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData
from .beam import BeamWeighting, beam_axes, beam_weighting, illumination_count, normalise_columns, pixel_weights
from ..core.trajectory import echo_length
from .bp_contract import check_inputs, focus_metadata, make_image, progress_bar, receiver_motion
from .grid import ImageGrid
from .range_lines import PAD, carrier_table, fft_upsample, premodulated_pairs, residual_carrier_table

__all__ = ["backproject", "backproject_reference", "illumination_count"]

#: The upsampler under the name tests/test_backprojection.py imports (now :func:`.range_lines.fft_upsample`).
_fft_upsample = fft_upsample

#: Pixel tile (rows, columns). Each tile has its own float64 reference point, so float32
#: residuals stay small; with ``_STEP`` it sets the working set.
_TILE = (16, 128)
#: Pixel-pulses per vectorised step (per-thread working set: 48 bytes each, ~3 MiB).
_STEP = 1 << 16


# ============================================================================ public API
def backproject(raw: RawData, grid: ImageGrid, *, oversample: int = 8, pulse_block: int = 128,
                workers: int | None = None, azimuth_beamwidth: float | None = None,
                squint: float = 0.0, azimuth_pattern: float | None = None, window_azimuth: Any = "rect",
                progress: bool = False, desc: str = "backprojection") -> SarImage:
    """Focus range-compressed data by time-domain backprojection (fast path).

    Parameters
    ----------
    raw : RawData
        Range-compressed echoes (``raw.range_compressed`` must be true) with uniform
        fast time ``t0 + i / fs``. Monostatic and bistatic geometries are both exact. With
        ``raw.rx_time`` (continuous motion, no stop-and-hop) each echo is received where the
        antenna is at its own arrival, eq. (J3) of docs/physics.md (:func:`_leg_antennas`).
    grid : ImageGrid
        Pixels to focus (any plane; the geometry is evaluated in 3-D).
    oversample : int, default 8
        Range upsampling factor (1 .. 64) applied by FFT zero-padding before linear
        interpolation. 8 keeps the interpolation loss below 0.05 dB at ``fs = 1.2 B``.
    pulse_block : int, default 128
        Pulses whose upsampled range lines are held in memory at once
        (``pulse_block * n_samples * oversample * 16`` bytes); also the progress step.
    workers : int, optional
        Threads (NumPy releases the GIL in its loops). Default: the CPUs available.
    azimuth_beamwidth : float, optional
        Full width [deg] of the ideal azimuth beam, in (0, 90). When given, a pulse
        contributes to a pixel tile only if the tile lies within the beam, i.e. its
        angle from the zero-Doppler plane (normal to the platform velocity) is at most
        half the beamwidth plus the tile's own angular half-size (beam-limited
        backprojection): pixels do not integrate pulses that never illuminated them,
        which removes the azimuth-ambiguity ghosts at ``lambda R PRF / (2 v)`` and skips
        most of the work in stripmap. Each range column is then normalised by the number
        of pulses a fully illuminated pixel of it integrates, so a point target of
        amplitude ``a`` has peak ``a`` anywhere in the fully illuminated swath (``|a|^2`` =
        its RCS in normalised radiometry); pixels whose aperture the track's ends cut keep
        a proportionally lower gain.
    squint : float, deg, default 0
        Squint of that beam (positive forward, in (-60, 60)): a pixel is in the beam of
        pulse ``p`` when its along-track sine ``(x - A_p) . v_p / |x - A_p|`` lies in
        ``[sin(squint - beta / 2), sin(squint + beta / 2)]``, the tracer's criterion.
        Used only with ``azimuth_beamwidth``.
    azimuth_pattern : float, optional
        ``L / lambda`` (> 0) of the uniform aperture whose two-way azimuth field pattern
        ``g(phi)^2 = sinc^2(L / lambda * sin(phi - squint))`` (NumPy's sinc) weights the echoes in
        the data (the tracer's tapered beam, :attr:`RadarParameters.pattern_length` over the
        wavelength). It does not change what is summed, only the normalisation: the expected
        gain of a point target includes it, so the target still peaks at its amplitude.
        Needs ``azimuth_beamwidth`` (the traced beam, to the pattern's first nulls). None: no
        pattern in the data.
    window_azimuth : str or (str, dict), default "rect"
        Azimuth (Doppler) window, a :mod:`sarmitsuba.focus.windows` name or
        ``(name, {params})``: every pulse's contribution to a pixel is multiplied by ``w(u)``,
        ``u = (sin(phi) - sin_lo) / (sin_hi - sin_lo)`` in [0, 1] across the beam (``w`` of the
        windows module at ``x = u - 1/2``), ``sin(phi) = (x - A_p) . v_p / |x - A_p|``. Without
        ``azimuth_beamwidth`` (spotlight: every pixel integrates every pulse) ``u = p / (n_pulses - 1)``,
        the pulse's place in the aperture.
    progress : bool, default False
        Show a :mod:`tqdm` bar over pulse blocks.
    desc : str, default "backprojection"
        The bar's label (e.g. ``"focus order 2"`` when several images are focused in turn).

    Returns
    -------
    SarImage
        complex64 ``[n_az, n_rg]`` on ``grid`` (``algorithm="backprojection"``; ``window``
        ``"rect"`` or a label ``"range=..., azimuth=..."`` naming the range window recorded in
        ``raw.metadata["range_window"]`` and the azimuth window). Normalised so that a point
        target of amplitude ``a`` peaks at ``a``: by ``1 / n_pulses`` (``1 / sum_p w(u_p)`` with
        a window), or, with ``azimuth_beamwidth``, per range column by the largest
        ``sum_p w(u_p) g(phi_p)^2`` of its pixels (the gain of a fully illuminated point
        target). ``metadata`` is a deep copy of ``raw.metadata`` plus ``"focus"``: the
        parameters (``window_range`` and ``window_azimuth`` as ``{"name": ..., params}``,
        ``azimuth_pattern``, ``beam_sines``, ``squint``), the straight-track reference
        ``track`` (``{"position": mid-aperture transmitter [m], "direction": unit velocity,
        "length": first to last transmitter [m]}``,
        used by :mod:`sarmitsuba.analysis.point_target` for layover and energy widths), ``seconds`` and
        ``pixel_pulses_per_second``.

    Raises
    ------
    ValueError
        When the data are not range compressed, the fast-time axis is not ``t0 + i / fs``,
        there are no pulses or fewer than 2 samples, an option is out of range, the window
        is unknown, or ``azimuth_pattern`` is given without ``azimuth_beamwidth``.

    Notes
    -----
    *Hybrid precision* (docs/design.md sections 5 and 8; a float32 absolute range has a
    6.25 cm ulp at 800 km, up to 12.6 rad of two-way phase at X band). The grid is cut into
    tiles of ``_TILE`` pixels. For each pulse and tile the reference length
    ``L_ref = |t - c_T| + |c_T - r|`` to the tile centre ``c_T`` is computed in float64.
    Each pixel's residual per leg, with ``x`` relative to ``c_T`` and
    ``d = antenna - c_T``,

    .. math:: \\Delta R = \\frac{|\\mathbf{x}|^2 - 2 \\mathbf{d} \\cdot \\mathbf{x}}
                             {|\\mathbf{d}| + |\\mathbf{d} - \\mathbf{x}|}

    is formed in float32 (no cancellation, so the error is relative to the tile size,
    not to the 800 km slant range; tiles of coarse grids are shrunk so the residual's
    two-way carrier phase stays below ``2**15`` rad, i.e. its rounding below ~0.01 rad).
    Lengths are scaled to the upsampled sample ``c / (fs * oversample)``, so
    ``tau(x)`` becomes a fine-sample index
    ``iota = off + Delta``, where ``off = (L_ref / c - t0) fs * oversample`` is split in
    float64 into an integer and a fraction ``phi`` in [0, 1); only ``phi + Delta`` enters
    float32.

    *Carrier phase.* ``2 pi fc L / c = 2 pi fc t0 + kh iota`` with
    ``kh = 2 pi fc / (fs * oversample)``. The part at the integer sample
    ``floor(iota)`` is premultiplied into the upsampled line in float64 (reduced mod 2 pi,
    then cast), so a pixel only needs ``exp(j kh w)`` of the interpolation weight
    ``w = iota - floor(iota)`` in [0, 1). The absolute phase never exists in float32 and
    ``exp(+j 2 pi fc L_ref / c)`` is carried exactly. ``exp(j kh w)`` and
    ``w exp(j kh w)`` come from a table over ``w`` with ``2**b`` bins (``b <= 16``, 14 at
    X band with fs = 180 MHz and oversample 8), sized so the quantisation error stays
    below 2e-3 rad (0.11 deg); ``w`` itself is then quantised to ``2**-b`` fine sample.
    This replaces a float32 ``sin``/``cos`` per pixel and pulse and is 20 % faster.

    *Interpolation.* Each line is FFT-upsampled (zero-padded spectrum, the Nyquist bin of
    an even transform split between both halves), then interpolated linearly. Outside the
    window the line is zero: delays more than one fine sample outside contribute nothing
    (masked, never clamped onto edge samples).

    *Beam weight.* With ``azimuth_beamwidth`` the weight ``w(u)`` of every pulse and tile row
    is formed in float64 from the row's along-track offset and the tile centre's distance
    (as the beam test), then applied as float32 to the row's products; the same per (pulse,
    row) array carries ``w g^2`` into the normalisation. A rect window without a pattern
    is the 0/1 beam mask.

    *Accumulation.* Sums over at most ``pulse_block`` pulses are complex64; blocks are
    accumulated in complex128.

    *Cost.* About 5 ns per pixel and pulse on one core of the 2-core development VM
    (NumPy 2.4, AVX-512), i.e. ~2e8 pixel-pulses/s: two gathers, one sqrt, one division
    and ~12 other float32 passes per pixel and pulse, each over ~64k elements so that
    Python overhead stays below ~10 %. Threads split the tiles of each pulse block; two
    threads give only ~1.3-1.45x (measured ~3e8/s), because each of the ~17 NumPy calls
    of a step hands the GIL over; two processes on halves of the grid reach ~1.95x.

    Examples
    --------
    >>> grid = ImageGrid.ground(centre, (1, 0, 0), (0, -1, -1), 200.0, 200.0, 0.25)  # doctest: +SKIP
    >>> image = backproject(raw, grid, progress=True)  # doctest: +SKIP
    """
    t_start = time.perf_counter()
    t0, oversample, pulse_block, workers = check_inputs(raw, grid, oversample, pulse_block, workers)
    beam = beam_weighting(raw, azimuth_beamwidth, squint, azimuth_pattern, window_azimuth)
    pulse_weights = None if beam.sines is not None else beam.pulse_weights(raw.n_pulses)
    n_pulses, n_samples = raw.data.shape
    n_up = (n_samples - 1) * oversample + 1
    n_tab = n_up + 2 * PAD
    fine_rate = raw.fs * oversample  # upsampled samples per second
    kh = 2.0 * np.pi * raw.fc / fine_rate  # carrier phase per fine sample [rad]
    receive = receiver_motion(raw)
    monostatic = receive is None and bool(np.array_equal(raw.tx_position, raw.rx_position))
    legs = (raw.tx_position,) if monostatic else (raw.tx_position, raw.rx_position)
    half_sample = SPEED_OF_LIGHT / fine_rate / 2.0  # one-way length of one fine sample [m]
    # residual unit: the per-leg residuals, summed over the legs (doubled when monostatic),
    # count fine samples of two-way delay
    unit = half_sample * len(legs)
    modulation = carrier_table(raw.fc, t0, raw.fc / fine_rate, n_tab)
    weights = residual_carrier_table(kh)
    tiles = _make_tiles(grid, unit, half_sample, raw.fc)
    image = np.zeros(grid.shape, np.complex128)
    counts = np.zeros(grid.shape) if beam.sines is not None else None
    workspaces = threading.local()

    def run_tile(args: tuple[_Tile, _Block]) -> None:
        tile, block = args
        ws = getattr(workspaces, "ws", None)
        if ws is None:
            ws = workspaces.ws = _Workspace(max(_STEP, _TILE[0] * _TILE[1]))
        _backproject_tile(tile, block, ws, image, counts)

    bar = progress_bar(progress, n_pulses, desc=desc)
    pool = ThreadPoolExecutor(workers) if workers > 1 else None
    axes = beam_axes(raw) if beam.sines is not None else None      # the beam's, not the sway's (J4)
    try:
        for p0 in range(0, n_pulses, pulse_block):
            p1 = min(p0 + pulse_block, n_pulses)
            data = raw.data[p0:p1]
            if pulse_weights is not None and not beam.is_rect:
                data = data * pulse_weights[p0:p1, None].astype(np.float32)
            lines = fft_upsample(data, oversample, workers=workers)
            block = _Block(lines, modulation, [leg[p0:p1] for leg in legs], monostatic, unit,
                           t0, fine_rate, grid, weights)
            if beam.sines is not None:
                block.beam = (beam, axes[p0:p1])
            if receive is not None:
                block.receive = (receive[0][p0:p1], receive[1][p0:p1])
            jobs = [(tile, block) for tile in tiles]
            if pool is None:
                for job in jobs:
                    run_tile(job)
            else:
                list(pool.map(run_tile, jobs))
            bar.update(p1 - p0)
    finally:
        if pool is not None:
            pool.shutdown()
        bar.close()
    if counts is None:
        norm = float(pulse_weights.sum())
        data = (image / norm if norm > 0 else np.zeros_like(image)).astype(np.complex64)
    else:
        data, norm = normalise_columns(image, counts)
    seconds = time.perf_counter() - t_start
    focus = focus_metadata(raw, grid, seconds, beam, oversample=oversample, pulse_block=pulse_block,
                            workers=workers, implementation="numpy-hybrid-float32",
                            azimuth_beamwidth=azimuth_beamwidth, squint=squint, max_pulses_per_pixel=norm,
                            tile=list(_TILE), weight_table_bins=weights[1], monostatic=monostatic,
                            motion="stop-and-hop" if receive is None else "continuous")
    return make_image(raw, grid, data, focus)


def backproject_reference(raw: RawData, grid: ImageGrid, *, oversample: int = 8,
                          azimuth_beamwidth: float | None = None, squint: float = 0.0,
                          azimuth_pattern: float | None = None, window_azimuth: Any = "rect") -> SarImage:
    """Readable float64 backprojection: the oracle for :func:`backproject`.

    A plain loop over pulses: FFT-upsample the range line (complex128), pad one zero
    fine sample at each end, :func:`numpy.interp` at the pixel delays ``L / c`` (zero
    outside), multiply by ``exp(+j 2 pi fc L / c)`` with ``L`` and the phase in float64,
    and sum. With a beam, every pixel's own along-track sine ``s = (x - A_p) . v_p / |x - A_p|``
    (no tiles) gives its weight ``w(u)``, ``u = (s - sin_lo) / (sin_hi - sin_lo)``, and its
    expected gain ``w(u) sinc^2(L / lambda * sin(asin(s) - squint))``; each range column is
    divided by its pixels' largest summed gain. Without a beam the weight is ``w(p / (n - 1))``
    and the image is divided by its sum (``n_pulses`` for rect). Same parameters, result and
    errors as :func:`backproject`; tens of times slower, so use it on small grids only.
    """
    t_start = time.perf_counter()
    t0, oversample, _, _ = check_inputs(raw, grid, oversample, 1, 1)
    beam = beam_weighting(raw, azimuth_beamwidth, squint, azimuth_pattern, window_azimuth)
    n_pulses, n_samples = raw.data.shape
    dt = 1.0 / (raw.fs * oversample)
    n_up = (n_samples - 1) * oversample + 1
    tau_line = t0 + np.arange(-1, n_up + 1) * dt  # fine samples plus one zero at each end
    x = grid.positions().reshape(-1, 3)
    image = np.zeros(x.shape[0], np.complex128)
    gain = np.zeros(x.shape[0])
    receive = receiver_motion(raw)
    axes = beam_axes(raw)
    for p in range(n_pulses):
        line = np.zeros(n_up + 2, np.complex128)
        line[1:-1] = fft_upsample(raw.data[p].astype(np.complex128), oversample)
        length = echo_length(raw.tx_position[p], raw.rx_position[p], raw.velocity[p],
                             None if receive is None else receive[1][p], x)
        echo = np.interp(length / SPEED_OF_LIGHT, tau_line, line, left=0.0, right=0.0)
        cycles = np.mod(raw.fc * length / SPEED_OF_LIGHT, 1.0)
        weight, expected = pixel_weights(raw, beam, axes, p, x)
        image += weight * echo * np.exp(2j * np.pi * cycles)
        gain += expected
    if beam.sines is None:
        total = gain[0] if gain.size else 0.0
        data = (image / total if total > 0 else 0.0 * image).reshape(grid.shape).astype(np.complex64)
    else:
        data, _ = normalise_columns(image.reshape(grid.shape), gain.reshape(grid.shape))
    focus = focus_metadata(raw, grid, time.perf_counter() - t_start, beam, oversample=oversample,
                            azimuth_beamwidth=azimuth_beamwidth, squint=squint,
                            implementation="numpy-reference-float64",
                            motion="stop-and-hop" if receive is None else "continuous")
    return make_image(raw, grid, data, focus)


# ============================================================================ fast path internals
#: Largest two-way carrier phase [rad] of a residual inside a tile. float32 rounds the
#: residual and its terms to a few 2**-24 of their size, so the phase error stays at a few
#: 2**15 * 2**-24 = 0.002 rad (X band: tiles up to ~115 m a side; only grids with pixels
#: coarser than ~1 m get tiles smaller than ``_TILE``).
_MAX_TILE_PHASE = 2.0**15


class _Tile:
    """One pixel tile: its float64 reference point and local coordinates.

    ``alpha``/``rho`` are the tile-local azimuth/range coordinates (float64, residual
    units); ``cross`` is ``2 cos(e_a, e_r) alpha rho`` (float32 ``[n_a * n_r]``, ``None``
    for an orthogonal grid) so that ``|x|^2 = alpha^2 + rho^2 + cross``; ``rmax`` bounds
    ``|residual|`` in fine samples.
    """

    def __init__(self, grid: ImageGrid, rows: slice, cols: slice, unit: float, half_sample: float):
        a = grid.azimuth[rows]
        r = grid.range[cols]
        a_c, r_c = 0.5 * (a[0] + a[-1]), 0.5 * (r[0] + r[-1])
        self.rows, self.cols = rows, cols
        self.shape = (a.size, r.size)
        self.centre = grid.origin + a_c * grid.azimuth_direction + r_c * grid.range_direction
        alpha, rho = a - a_c, r - r_c
        cos_ar = float(grid.azimuth_direction @ grid.range_direction)
        cross = 2.0 * cos_ar * alpha[:, None] * rho[None, :]
        q = alpha[:, None] ** 2 + rho[None, :] ** 2 + cross
        self.rmax = float(np.sqrt(q.max())) / half_sample
        #: Largest distance [m] of a tile pixel from the tile centre.
        self.half_size = float(np.sqrt(q.max()))
        #: Row offsets from the tile centre along the azimuth axis, float64 [n_a] m.
        self.row_offsets = alpha.copy()
        self.alpha, self.rho = alpha / unit, rho / unit
        self.cross = (cross / unit**2).astype(np.float32).reshape(-1) if abs(cos_ar) > 1e-12 else None


def _make_tiles(grid: ImageGrid, unit: float, half_sample: float, fc: float) -> list[_Tile]:
    """Cut the grid into tiles of at most ``_TILE`` pixels, smaller when the pixels are so
    coarse that a tile's residual phase could exceed ``_MAX_TILE_PHASE``."""
    n_az, n_rg = grid.shape
    half_diagonal = _MAX_TILE_PHASE / (4.0 * np.pi * fc / SPEED_OF_LIGHT)  # metres
    limit = half_diagonal * np.sqrt(2.0)  # metres per tile side
    sizes = []
    for axis, default in ((grid.azimuth, _TILE[0]), (grid.range, _TILE[1])):
        step = float(np.max(np.diff(axis))) if axis.size > 1 else 0.0
        sizes.append(default if step == 0.0 else int(np.clip(limit // step, 1, default)))
    return [_Tile(grid, slice(i, min(i + sizes[0], n_az)), slice(j, min(j + sizes[1], n_rg)), unit, half_sample)
            for i in range(0, n_az, sizes[0]) for j in range(0, n_rg, sizes[1])]


class _Block:
    """Upsampled, carrier-premodulated range lines of one pulse block, plus its geometry.

    ``table`` is complex128 ``[n_pulses * n_tab]``: each element packs the complex64 pair
    ``(T0[k], T1[k]) = (s[k] E[k], (s[k + 1] - s[k]) E[k])`` with ``s`` the zero-padded
    upsampled line and ``E`` the carrier table, so one gather yields both interpolation
    terms. The echo times ``exp(+j 2 pi fc tau)`` at fine position ``k + w`` is then
    ``(T0 + w T1) exp(j kh w) = T0 P0(w) + T1 P1(w)`` with ``(P0, P1)`` from
    :func:`~.range_lines.residual_carrier_table`: two gathers and one complex64 multiply per pixel and pulse.
    """

    def __init__(self, lines: np.ndarray, modulation: np.ndarray, legs: list[np.ndarray], monostatic: bool,
                 unit: float, t0: float, fine_rate: float, grid: ImageGrid, weights: tuple[np.ndarray, int]):
        n_pulses, n_up = lines.shape
        n_tab = modulation.size
        self.table = premodulated_pairs(lines, modulation)
        self.index_dtype = np.int32 if self.table.size < 2**31 else np.int64
        self.n_pulses, self.n_tab, self.n_up = n_pulses, n_tab, n_up
        self.legs, self.monostatic, self.unit = legs, monostatic, unit
        self.t0, self.fine_rate = t0, fine_rate
        self.e_az, self.e_rg = grid.azimuth_direction, grid.range_direction
        self.weights, self.n_weights = weights
        #: (beam weighting, unit velocity [P, 3]) for beam-limited backprojection, or None.
        self.beam: tuple[BeamWeighting, np.ndarray] | None = None
        #: (velocity [P, 3] m/s, rx_delay [P] s) of continuous-motion data, or None (stop-and-hop).
        self.receive: tuple[np.ndarray, np.ndarray] | None = None


class _Workspace:
    """Per-thread scratch arrays for one vectorised step of ``size`` pixel-pulses (48 B each)."""

    def __init__(self, size: int):
        self.size = size
        self.f32 = np.empty((3, size), np.float32)
        self.gather = np.empty((2, size), np.complex128)
        self.index = {np.int32: np.empty(size, np.int32), np.int64: np.empty(0, np.int64)}

    def index_buffer(self, dtype: type) -> np.ndarray:
        if self.index[dtype].size < self.size:
            self.index[dtype] = np.empty(self.size, dtype)
        return self.index[dtype]


def _tile_geometry(tile: _Tile, block: _Block) -> dict[str, Any]:
    """float64 reference quantities of one tile for every pulse of a block.

    Per leg: ``a_term [P, n_a]`` and ``r_term [P, n_r]`` (float32) with
    ``|x|^2 - 2 d.x = a_term[:, i] + r_term[:, j] (+ cross)``, and ``|d|``, ``|d|^2`` as
    float32 ``[P, 1]``. Then ``phi`` (fraction of the reference fine-sample index),
    ``base`` (flat table index of its integer part), the clip bounds and the skip/inside
    flags of each pulse.
    """
    length = np.zeros(block.n_pulses)
    legs = []
    for antenna in _leg_antennas(tile, block):
        d = antenna - tile.centre  # float64 [P, 3]
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        length += dist
        d_az, d_rg, r_s = d @ block.e_az / block.unit, d @ block.e_rg / block.unit, dist / block.unit
        legs.append(((tile.alpha**2 - 2.0 * np.multiply.outer(d_az, tile.alpha)).astype(np.float32),
                     (tile.rho**2 - 2.0 * np.multiply.outer(d_rg, tile.rho)).astype(np.float32),
                     r_s.astype(np.float32)[:, None], (r_s * r_s).astype(np.float32)[:, None]))
    if block.monostatic:
        length *= 2.0
    offset = (length / SPEED_OF_LIGHT - block.t0) * block.fine_rate  # fine-sample index of the centre
    skip = (offset + tile.rmax + 1.0 < -1.0) | (offset - tile.rmax - 1.0 > block.n_up)
    mask = gain = None
    if block.beam is not None:
        mask, gain = _beam_mask(tile, block)
        skip |= ~mask.any(axis=1)
    inside = (offset - tile.rmax - 1.0 >= -1.0) & (offset + tile.rmax + 1.0 <= block.n_up)
    whole = np.where(skip, 0.0, np.floor(offset))
    first = whole + PAD  # table index of fine sample `whole` within its row
    rows = np.arange(block.n_pulses) * block.n_tab
    return {
        "legs": legs,
        "phi": np.where(skip, 0.0, offset - whole).astype(np.float32)[:, None],
        "base": (first + rows).astype(block.index_dtype)[:, None],
        "low": np.where(skip, -PAD, -first).astype(np.float32)[:, None],
        "high": np.where(skip, -PAD, block.n_tab - 1 - first).astype(np.float32)[:, None],
        "skip": skip, "inside": inside, "mask": mask, "gain": gain,
    }


def _leg_antennas(tile: _Tile, block: _Block) -> list[np.ndarray]:
    """The antenna of each leg for one tile, float64 [P, 3]: with continuous motion the receiver at
    the arrival of the tile centre's echo, ``rx + v (L_c / c - rx_delay)`` (eq. (J3)), which every
    pixel of the tile shares. A pixel ``h`` from the centre receives ``2 h / c`` earlier or later;
    its receiver then lies ``2 h |v| / c`` from the one used, a length error below
    ``2 h |v| / c (h / R + |sin phi|)`` (``phi`` the squint of the pixel's line of sight; 0.01 mm
    for a 60 m tile at 7.6 km/s, 500 km and a 1 deg beam)."""
    if block.receive is None:
        return list(block.legs)
    tx, rx = block.legs
    velocity, delay = block.receive
    reach = (np.linalg.norm(tx - tile.centre, axis=1) + np.linalg.norm(rx - tile.centre, axis=1)) / SPEED_OF_LIGHT
    return [tx, rx + (reach - delay)[:, None] * velocity]


def _beam_mask(tile: _Tile, block: _Block) -> tuple[np.ndarray, np.ndarray]:
    """Beam weight of each tile row for each pulse: float32 [P, n_a] ``w(u)`` (0 outside pulse
    p's beam; the 0/1 mask for a rect window without pattern) and float64 [P, n_a] the expected
    gain ``w(u) g^2``.

    Row ``i`` is in the beam when ``(c_T - A_p) . v_p + alpha_i (e_az . v_p)`` lies between
    ``sin_lo |c_T - A_p|`` and ``sin_hi |c_T - A_p|``:
    the along-track offset is exact per row, the distance is the tile centre's (so the beam
    edge of a pixel is placed to within ``sin(beta / 2)`` times the tile's range half-extent).
    """
    beam, v = block.beam
    e = tile.centre - block.legs[0]
    dist = np.linalg.norm(e, axis=1)[:, None]
    along = np.einsum("ij,ij->i", e, v)[:, None] + np.outer(v @ block.e_az, tile.row_offsets)
    return beam.weights(along, dist)


def _backproject_tile(tile: _Tile, block: _Block, ws: _Workspace, image: np.ndarray,
                      counts: np.ndarray | None = None) -> None:
    """Add one pulse block's contribution to one tile of ``image`` (complex128, in place), and
    with a beam the expected point-target gain ``sum_p w g^2`` per pixel to ``counts``."""
    geo = _tile_geometry(tile, block)
    if counts is not None and geo["gain"] is not None:
        counts[tile.rows, tile.cols] += geo["gain"][~geo["skip"]].sum(axis=0)[:, None]
    n_pixels = tile.shape[0] * tile.shape[1]
    acc = np.zeros(2 * n_pixels, np.complex64)  # interleaved sums of T0 P0 and T1 P1
    step = max(1, ws.size // n_pixels)
    for s0 in range(0, block.n_pulses, step):
        pulses = slice(s0, min(s0 + step, block.n_pulses))
        if geo["skip"][pulses].all():
            continue
        _kernel(tile, geo, pulses, not geo["inside"][pulses].all(), block, ws, acc)
    image[tile.rows, tile.cols] += (acc[0::2] + acc[1::2]).reshape(tile.shape)


def _kernel(tile: _Tile, geo: dict[str, Any], pulses: slice, clip: bool, block: _Block,
            ws: _Workspace, acc: np.ndarray) -> None:
    """The hot loop: ``pulses`` x tile pixels in float32/complex64, into preallocated buffers."""
    n_p, (n_a, n_r) = pulses.stop - pulses.start, tile.shape
    size = n_p * n_a * n_r
    iota, den, tmp = (buf[:size].reshape(n_p, n_a * n_r) for buf in ws.f32)
    index = ws.index_buffer(block.index_dtype)[:size].reshape(n_p, -1)
    samples, weights = ws.gather[0, :size], ws.gather[1, :size]

    # ---- residual delay [fine samples] per leg: (|x|^2 - 2 d.x) / (|d| + |d - x|)
    for k, (a_term, r_term, dist, dist2) in enumerate(geo["legs"]):
        num = iota if k == 0 else tmp
        np.add(a_term[pulses, :, None], r_term[pulses, None, :], out=num.reshape(n_p, n_a, n_r))
        if tile.cross is not None:
            np.add(num, tile.cross, out=num)
        np.add(num, dist2[pulses], out=den)
        np.sqrt(den, out=den)
        np.add(den, dist[pulses], out=den)
        np.divide(num, den, out=num)
        if k:
            np.add(iota, tmp, out=iota)

    # ---- index relative to the integer reference sample; outside the window -> zero pads
    np.add(iota, geo["phi"][pulses], out=iota)
    if clip:
        np.clip(iota, geo["low"][pulses], geo["high"][pulses], out=iota)
    np.floor(iota, out=den)
    np.subtract(iota, den, out=iota)  # interpolation weight w in [0, 1)
    np.copyto(index, den, casting="unsafe")
    np.add(index, geo["base"][pulses], out=index)

    # ---- gather (T0, T1) and (P0(w), P1(w)); sum T0 P0 + T1 P1 over the pulses
    flat = index.reshape(-1)
    np.take(block.table, flat, out=samples, mode="clip")
    np.multiply(iota, float(block.n_weights), out=iota)
    np.copyto(flat, iota.reshape(-1), casting="unsafe")
    np.take(block.weights, flat, out=weights, mode="clip")
    product = samples.view(np.complex64)
    np.multiply(product, weights.view(np.complex64), out=product)
    if geo["mask"] is not None:                      # beam-limited: weight rows, zero outside the beam
        rows = product.reshape(n_p, n_a, 2 * n_r)
        np.multiply(rows, geo["mask"][pulses, :, None], out=rows)
    acc += np.add.reduce(product.reshape(n_p, -1), axis=0)
