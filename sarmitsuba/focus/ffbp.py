"""Fast factorised backprojection (FFBP) of range-compressed data onto an :class:`ImageGrid`.

The direct sum (S3) of :func:`~sarmitsuba.focus.backproject` is factorised over sub-apertures
(Ulander, Hellsten and Stenstrom 2003, two levels): the pulses are split into sub-apertures of
``subaperture`` consecutive pulses; each is backprojected onto a polar grid of the image plane
around its own phase centre (:mod:`.polar`), which only has to sample the sub-aperture's own,
coarse, angular resolution; every polar image is then interpolated onto the pixels it reaches
and the results are summed. The interpolation is two 1-D passes (cubic B-splines): along the
sines onto each grid row at the image's own range samples, then along range onto the row's
pixels, with the carrier restored from tables in float64 phase. Nothing assumes a straight
track: each polar image is exact in its own frame (mean position and velocity of its pulses),
and each pulse keeps its own beam gate and window weight. Bistatic data (a receiver on its own
platform) get polar images on the half range sum about the two phase centres
(:mod:`.polar_bistatic`, docs/physics.md (F10)).

Cost, for pixels integrating ``N_a`` pulses each: ``subaperture x (polar samples)`` pixel-pulses
in the first stage (the polar samples of all sub-apertures together are about the swath's range
samples x the pulses x the beam's sines x ``4 |p - c| / lambda`` per sub-aperture pulse x the
angular oversampling: independent of ``subaperture``), then ``(pixels) x (N_a / subaperture + 1)``
interpolations, instead of ``(pixels) x N_a`` for the direct sum. docs/physics.md (F1)-(F9) derives the
factorisation, the error knobs and the defaults.

References
----------
.. [1] L. M. H. Ulander, H. Hellsten and G. Stenstrom, "Synthetic-aperture radar processing
   using fast factorized back-projection", IEEE Trans. Aerosp. Electron. Syst. 39(3),
   760-776, 2003.
"""
from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData
from .beam import BeamWeighting, beam_axes, beam_weighting
from .bp_contract import check_inputs, focus_metadata, make_image, progress_bar, receiver_motion
from .ffbp_plan import (BLOCK_COLUMNS, SUBAPERTURE, check_knobs, grid_edge_points, is_bistatic, n_blocks,
                        normalisation, plan_polar, residual_spread, row_geometry, rows_reached, subaperture_spans)
from .grid import ImageGrid
from .polar import (CHUNK, GeometryNotSupported, PolarAxes, PolarImage, beam_table, carrier_bits, premodulated_rows,
                    prepare, pulses_to_polar, r_pass, s_pass, spline_tables, workspace)
from .polar_bistatic import PREFILTER_REACH, BistaticFrame, prepare_samples, row_coefficients
from .range_lines import PAD, carrier_table, fft_upsample, premodulated_pairs, residual_carrier_table

__all__ = ["ffbp", "GeometryNotSupported"]

#: Range samples kept beyond the delays a first-stage polar image needs, and of them tapered.
LINE_GUARD, LINE_TAPER = 48, 16
#: Sub-apertures whose polar images are held at once (each is added to the grid, then dropped).
CHUNK_SUBAPERTURES = 24


# ============================================================================ public API
def ffbp(raw: RawData, grid: ImageGrid, *, subaperture: int | None = None, angle_oversample: float = 2.0,
         range_oversample: int = 2, oversample: int = 8, workers: int | None = None,
         azimuth_beamwidth: float | None = None, squint: float = 0.0, azimuth_pattern: float | None = None,
         window_azimuth: Any = "rect", progress: bool = False, desc: str = "ffbp") -> SarImage:
    """Focus range-compressed data by fast factorised backprojection.

    Same data, grid, beam options, normalisation and result as
    :func:`~sarmitsuba.focus.backproject` (read its Parameters for ``azimuth_beamwidth``,
    ``squint``, ``azimuth_pattern``, ``window_azimuth``, ``oversample``, ``workers`` and
    ``progress``), computed with fewer operations and an interpolation error set by the knobs
    below (docs/physics.md (F3), (F7); measured against ``backproject`` in benchmarks/ffbp.py).

    Parameters
    ----------
    raw : RawData
        Range-compressed echoes with uniform fast time: monostatic (``tx_position ==
        rx_position``), continuous motion (``rx_time`` given: each echo received where the
        antenna is at its arrival, eq. (J3) of docs/physics.md, exact as in ``backproject``), or
        bistatic stop-and-hop (a receiver on its own platform: polar images on the half range sum
        about the two phase centres, eq. (F10), :mod:`.polar_bistatic`).
    grid : ImageGrid
        Pixels to focus, all on one side of the track (no pixel under the antenna's path).
    subaperture : int, optional
        Pulses per sub-aperture (1 .. n_pulses; default 16, or every pulse when there are
        fewer): the factorisation. Each sub-aperture is
        backprojected directly onto its polar grid (cost ``subaperture x`` polar samples), then
        every pixel interpolates the ``(pulses in its beam) / subaperture + 1`` polar images that
        reach it.
    angle_oversample : float, default 2.0
        Sampling of the polar images in sine over their Nyquist rate (1.25 .. 8): sets the
        angular interpolation error (cubic B-spline, about -45 dB at 2 for a flat angular
        spectrum, lower with a tapered beam).
    range_oversample : int, default 2
        FFT upsampling of the polar images in range before the cubic B-spline (1 .. 8; -53 dB at
        2 for ``fs = 1.2 B``).
    oversample : int, default 8
        Upsampling of the range lines for the first stage, as in ``backproject`` (1 .. 64).
    workers : int, optional
        Threads (default: the CPUs available).
    azimuth_beamwidth, squint, azimuth_pattern, window_azimuth, progress
        As in :func:`~sarmitsuba.focus.backproject`.
    desc : str, default "ffbp"
        The progress bar's label.

    Returns
    -------
    SarImage
        complex64 ``[n_az, n_rg]`` on ``grid``, normalised as ``backproject`` (a point target of
        amplitude ``a`` peaks at ``a``; per range column by the largest expected gain
        ``sum_p w g^2`` with a beam). ``metadata["focus"]`` as ``backproject``'s (``algorithm``
        ``"backprojection"``) plus ``implementation = "ffbp"``, the knobs, ``subapertures`` (polar
        images), ``polar_samples`` (their samples), ``stage_seconds`` and
        ``pixel_pulses_per_second`` (pixels x pulses of the equivalent direct backprojection per
        second).

    Raises
    ------
    ValueError
        As ``backproject``; or a knob outside its range.
    GeometryNotSupported
        (a ValueError) A velocity normal to the image plane, a grid that straddles the track (a
        pixel under the antenna path) or, bistatic, a grid line that crosses its least range sum:
        use ``backproject``.

    Notes
    -----
    Accuracy (docs/physics.md (F7), (F8)): against ``backproject`` on analytic point targets the image NRMSE
    is -43 to -48 dB at the defaults (-33 dB with an ideal, all-or-nothing beam gate: a polar
    image interpolates the gate's single-pulse steps); on Sionna's Munich -33.5 dB, while
    ``backproject`` itself moves by -31.4 dB when its pixel tiles shift (its gate is placed per
    tile row). Precision: float64 geometry, float32 residuals as ``backproject``, and float64
    polar coordinates, so nothing depends on the range to the sensor.
    """
    t_start = time.perf_counter()
    t0, oversample, _, workers = check_inputs(raw, grid, oversample, 1, workers)
    knobs = check_knobs(raw, min(SUBAPERTURE, raw.n_pulses) if subaperture is None else subaperture,
                         angle_oversample, range_oversample)
    beam = beam_weighting(raw, azimuth_beamwidth, squint, azimuth_pattern, window_azimuth)
    pool = ThreadPoolExecutor(workers) if workers > 1 else None
    run = (lambda f, jobs: list(pool.map(f, jobs))) if pool else (lambda f, jobs: [f(j) for j in jobs])
    spans = subaperture_spans(raw.n_pulses, knobs["subaperture"])
    bar = progress_bar(progress, len(spans) + n_blocks(grid), desc=desc, unit="step")
    clock = {"start": time.perf_counter()}
    summed = np.zeros(grid.shape, np.complex64)
    counts = {"subapertures": 0, "polar_samples": 0, "first": 0.0, "last": 0.0}
    try:
        # the polar images of CHUNK_SUBAPERTURES sub-apertures at a time (memory: their prepared
        # tables, about 32 bytes per polar sample), added to the grid and dropped
        for c0 in range(0, len(spans), CHUNK_SUBAPERTURES):
            start = time.perf_counter()
            images = _first_stage(raw, grid, beam, spans[c0:c0 + CHUNK_SUBAPERTURES], t0, oversample, knobs, run, bar)
            middle = time.perf_counter()
            _last_step(grid, images, raw.fc, run, summed)
            counts["first"] += middle - start
            counts["last"] += time.perf_counter() - middle
            counts["subapertures"] += len(images)
            counts["polar_samples"] += sum(i.axes.n_s * i.axes.n_r for i in images)
            del images
        bar.update(n_blocks(grid))
        clock["subaperture_images"] = clock["start"] + counts["first"]
        clock["grid"] = clock["subaperture_images"] + counts["last"]
    finally:
        if pool is not None:
            pool.shutdown()
        bar.close()
    scale, norm = normalisation(raw, grid, beam)
    summed *= scale.astype(np.float32)[None, :]
    data = summed
    clock["normalisation"] = time.perf_counter()
    seconds = clock["normalisation"] - t_start
    steps = list(clock)
    stage_seconds = {name: round(clock[name] - clock[prev], 4) for prev, name in zip(steps, steps[1:])}
    focus = focus_metadata(raw, grid, seconds, beam, oversample=oversample, workers=workers,
                           implementation="ffbp", **knobs, subapertures=counts["subapertures"],
                           polar_samples=counts["polar_samples"], stage_seconds=stage_seconds,
                           azimuth_beamwidth=azimuth_beamwidth, squint=squint, max_pulses_per_pixel=norm,
                           monostatic=raw.rx_time is None and not is_bistatic(raw),
                           motion="stop-and-hop" if raw.rx_time is None else "continuous")
    focus["interpolation"] = "first stage: fft-upsample + linear; polar images: cubic B-spline (s, then r)"
    return make_image(raw, grid, data, focus)



# ============================================================================ stages
def _first_stage(raw: RawData, grid: ImageGrid, beam: BeamWeighting, spans: list[tuple[int, int]], t0: float,
                 oversample: int, knobs: dict[str, Any], run, bar) -> list[PolarImage]:
    """Polar images of the first-stage sub-apertures, prepared for interpolation."""
    fine_rate = raw.fs * oversample
    carrier = residual_carrier_table(2.0 * np.pi * raw.fc / fine_rate)
    weights = None if beam.sines is not None or beam.is_rect else beam.pulse_weights(raw.n_pulses)
    table = None if beam.sines is None else (beam_table(beam.u, beam.table), *beam.sines)
    edges = grid_edge_points(grid)
    velocity = beam_axes(raw)                  # the beam table's sines (docs/physics.md (J4))
    receive = receiver_motion(raw)
    factor = math.gcd(oversample, knobs["range_oversample"])     # a bistatic image's range step c / (2 fs factor)

    def one(span: tuple[int, int]) -> PolarImage | None:
        pulses = slice(*span)
        planned = plan_polar(raw, grid, beam, pulses, knobs["angle_oversample"], edges, factor)
        if planned is not None:
            frame, axes, s_span, window = planned
            start, data = _cropped_lines(raw, pulses, axes)
            if weights is not None:
                data *= weights[pulses, None].astype(np.float32)
            t_start = t0 + start / raw.fs
            n_tab = (data.shape[1] - 1) * oversample + 1 + 2 * PAD
            lines = premodulated_pairs(fft_upsample(data, oversample, workers=1),
                                       carrier_table(raw.fc, t_start, raw.fc / fine_rate, n_tab))
            receivers = None if receive is None else (raw.rx_position[pulses], receive[0][pulses], receive[1][pulses])
            polar, (d_lo, d_hi) = pulses_to_polar(frame, axes, raw.tx_position[pulses], velocity[pulses], lines,
                                                  carrier, t_start, raw.fs, oversample, raw.fc, table, receivers)
            # ranges where every pulse's delay lies beyond the window (plus a fine sample): zero there
            guard = SPEED_OF_LIGHT / (2.0 * raw.fs * oversample)
            r_span = (window[0] - d_hi - guard, window[1] - d_lo + guard)
            image = PolarImage(frame, axes, polar, s_span, r_span)
            planned = prepare_samples(image) if isinstance(frame, BistaticFrame) else \
                prepare(image, knobs["range_oversample"])
        bar.update(1)
        return planned

    return [image for image in run(one, spans) if image is not None]


def _cropped_lines(raw: RawData, pulses: slice, axes: PolarAxes) -> tuple[int, np.ndarray]:
    """First sample and a copy of the pulses' range lines over the delays of a polar image
    (``2 (r -+ |A_p - c|) / c``) plus :data:`LINE_GUARD` samples, whose outer :data:`LINE_TAPER`
    samples are tapered to zero where the crop cuts the line (so that the FFT upsampling does not
    ring into the needed delays)."""
    spread = residual_spread(raw, pulses)
    r_first, r_last = axes.r0 - spread, axes.r0 + (axes.n_r - 1) * axes.dr + spread
    t0 = float(raw.fast_time[0])
    lo = int(np.floor((2.0 * r_first / SPEED_OF_LIGHT - t0) * raw.fs)) - LINE_GUARD
    hi = int(np.ceil((2.0 * r_last / SPEED_OF_LIGHT - t0) * raw.fs)) + LINE_GUARD + 1
    lo, hi = max(lo, 0), min(hi, raw.n_samples)
    data = np.array(raw.data[pulses, lo:hi], dtype=np.complex64)
    ramp = (0.5 - 0.5 * np.cos(np.pi * (np.arange(LINE_TAPER) + 0.5) / LINE_TAPER)).astype(np.float32)
    if lo > 0:
        data[:, :LINE_TAPER] *= ramp[:min(LINE_TAPER, data.shape[1])]
    if hi < raw.n_samples:
        data[:, -LINE_TAPER:] *= ramp[::-1][-min(LINE_TAPER, data.shape[1]):]
    return lo, data


def _last_step(grid: ImageGrid, images: list[PolarImage], fc: float, run, out: np.ndarray) -> None:
    """Add the polar images, interpolated onto the grid, to ``out`` (complex64 [n_az, n_rg], in
    place; one range block of :data:`BLOCK_COLUMNS` columns per job, so that jobs write disjoint
    pixels)."""
    if not images:
        return
    kappa = 4.0 * np.pi * fc / SPEED_OF_LIGHT
    s_tables = spline_tables(12)
    fine_dr = images[0].fine.dr
    r_tables = spline_tables(carrier_bits(kappa * fine_dr), kappa * fine_dr)
    blocks = [slice(b * BLOCK_COLUMNS, min((b + 1) * BLOCK_COLUMNS, grid.shape[1])) for b in range(n_blocks(grid))]
    reach = run(lambda image: rows_reached(grid, image, blocks), images)

    def block(b: int) -> None:
        for image, rows in zip(images, reach):
            if rows[b] is not None:
                _image_to_block(grid, image, rows[b], blocks[b], kappa, s_tables, r_tables, out)

    run(block, range(len(blocks)))



def _image_to_block(grid: ImageGrid, image: PolarImage, rows: slice, cols: slice, kappa: float, s_tables,
                    r_tables, out: np.ndarray) -> None:
    """Add one prepared polar image to the pixels ``rows x cols`` of ``out`` (in place): the s-pass
    onto the rows at the image's fine range samples, then the r-pass onto the pixels."""
    frame, fine = image.frame, image.fine
    if isinstance(frame, BistaticFrame):
        _bistatic_to_block(grid, image, rows, cols, kappa, s_tables, r_tables, out)
        return
    rho = grid.range[cols]
    p, q = row_geometry(grid, frame.centre)
    p, h2 = p[rows], q[rows] - p[rows] ** 2                # |x - c|^2 = (rho + p)^2 + h2 on each row
    ends = rho[[0, -1]][None, :] + p[:, None]
    side = 1.0 if ends[0, 0] > 0 else -1.0
    if np.any(ends * side <= 0):
        raise GeometryNotSupported("ffbp: an image row crosses the closest point to a sub-aperture centre inside the "
                         "grid (the grid straddles the track); use backproject")
    r_ends = np.sqrt(ends * ends + h2[:, None])
    k0 = max(0, int(np.floor((r_ends.min() - fine.r0) / fine.dr)) - 3)
    k1 = min(fine.n_r, int(np.ceil((r_ends.max() - fine.r0) / fine.dr)) + 4)
    if k1 - k0 < 4:
        return
    # pixels beyond the image's ranges, or where all its pulses' delays leave the window, read zeros
    clip = k0 == 0 or k1 == fine.n_r or r_ends.min() < image.r_span[0] or r_ends.max() > image.r_span[1]
    outside = ((image.r_span[0] - fine.r0) / fine.dr - k0, (image.r_span[1] - fine.r0) / fine.dr - k0)
    r_k = fine.r0 + fine.dr * np.arange(k0, k1)
    carrier = np.exp(1j * np.mod(kappa * r_k, 2.0 * np.pi)).astype(np.complex64)
    v = frame.direction
    along = (grid.origin - frame.centre) @ v + grid.azimuth[rows] * (grid.azimuth_direction @ v)
    step = max(1, CHUNK // (max(rho.size, r_k.size) + 2 * 4))
    ws = workspace(step * (max(rho.size, r_k.size) + 8))
    r_k2 = r_k * r_k
    for i0 in range(0, p.size, step):
        part = slice(i0, min(i0 + step, p.size))
        n_rows = part.stop - part.start
        # s-pass: the point of each row at each fine range sample, its sine, the image there
        rho_k = np.subtract(r_k2[None, :], h2[part, None], out=ws.f64[0, :n_rows * r_k.size].reshape(n_rows, -1))
        np.maximum(rho_k, 0.0, out=rho_k)
        np.sqrt(rho_k, out=rho_k)
        rho_k *= side
        rho_k -= p[part, None]
        rho_k *= grid.range_direction @ v
        rho_k += along[part, None]
        rho_k /= r_k[None, :]
        coeffs = s_pass(image, rho_k, k0, s_tables, ws.c64[1, :rho_k.size].reshape(rho_k.shape))
        # r-pass: each pixel's range in fine samples from r_k[0], the coefficients there with the carrier
        position = np.add(rho[None, :], p[part, None], out=ws.f64[1, :n_rows * rho.size].reshape(n_rows, -1))
        position *= position
        position += h2[part, None]
        np.sqrt(position, out=position)
        position -= r_k[0]
        position *= 1.0 / fine.dr
        if clip:
            position[(position < outside[0]) | (position > outside[1])] = -1e9
            np.clip(position, -2.0, r_k.size + 1.0, out=position)
        target = out[rows.start + i0:rows.start + part.stop, cols]
        target += r_pass(premodulated_rows(coeffs, carrier, ws), r_k.size, position, r_tables,
                         ws.c64[0, :position.size].reshape(position.shape))


def _bistatic_to_block(grid: ImageGrid, image: PolarImage, rows: slice, cols: slice, kappa: float, s_tables,
                       r_tables, out: np.ndarray) -> None:
    """:func:`_image_to_block` for a bistatic polar image (F10), along the grid axis that crosses the
    half range sum's contours more steeply over the block
    (:meth:`~.polar_bistatic.BistaticFrame.along_azimuth`: along the grid's columns, the grid and the
    block transposed; a receiver off to the side can turn the contours along the rows)."""
    if image.frame.along_azimuth(grid, rows, cols):
        swapped = ImageGrid(grid.origin, grid.range_direction, grid.azimuth_direction, grid.range, grid.azimuth,
                            grid.plane)
        _bistatic_lines(swapped, image, cols, rows, kappa, s_tables, r_tables, out.T)
    else:
        _bistatic_lines(grid, image, rows, cols, kappa, s_tables, r_tables, out)


def _bistatic_lines(grid: ImageGrid, image: PolarImage, rows: slice, cols: slice, kappa: float, s_tables,
                    r_tables, out: np.ndarray) -> None:
    """The lines ``rows`` of ``grid`` at its pixels ``cols`` of ``out``, in chunks of lines: the s-pass
    reads the image's values (:func:`~.polar_bistatic.prepare_samples`) at the lines' points at its
    range samples ``rho_k`` around the chunk's pixels (:meth:`~.polar_bistatic.BistaticFrame.row_sines`,
    closed form), the line prefilter (:func:`~.polar_bistatic.row_coefficients`) makes them range
    coefficients along each line, and the r-pass reads them at the pixels' half range sums
    (:meth:`~.polar_bistatic.BistaticFrame.pixel_ranges`)."""
    frame, fine = image.frame, image.fine
    rho, side = frame.pixel_ranges(grid, rows, cols)                        # [n_rows, n_cols]
    reach = 3 + PREFILTER_REACH
    first = max(0, int(np.floor((rho.min() - fine.r0) / fine.dr)) - reach)  # the block's range samples
    last = min(fine.n_r, int(np.ceil((rho.max() - fine.r0) / fine.dr)) + 1 + reach)
    if last - first < 4 + 2 * PREFILTER_REACH:
        return
    block_k = fine.r0 + fine.dr * np.arange(first, last)
    table = frame.row_sine_table(grid, rows, block_k, side)                 # exact sines, every ROW_STEP-th
    step = max(1, CHUNK // (max(rho.shape[1], last - first) + 2 * 4))
    ws = workspace(step * (max(rho.shape[1], last - first) + 8))
    spline = np.empty(step * (last - first), np.complex128)                # the lines' coefficients
    for i0 in range(0, rho.shape[0], step):
        part = slice(i0, min(i0 + step, rho.shape[0]))
        lo, hi = float(rho[part].min()), float(rho[part].max())
        k0 = max(first, int(np.floor((lo - fine.r0) / fine.dr)) - reach)
        k1 = min(last, int(np.ceil((hi - fine.r0) / fine.dr)) + 1 + reach)
        if k1 - k0 < 4 + 2 * PREFILTER_REACH:
            continue
        clip = k0 == 0 or k1 == fine.n_r or lo < image.r_span[0] or hi > image.r_span[1]
        outside = ((image.r_span[0] - fine.r0) / fine.dr - k0, (image.r_span[1] - fine.r0) / fine.dr - k0)
        r_k = fine.r0 + fine.dr * np.arange(k0, k1)
        carrier = np.exp(1j * np.mod(kappa * r_k, 2.0 * np.pi)).astype(np.complex64)
        sines = frame.row_sines(grid, rows, block_k, side, (part, slice(k0 - first, k1 - first)), table,
                                (ws.f64[0], ws.f64[1]))
        values = s_pass(image, sines, k0, s_tables, ws.c64[1, :sines.size].reshape(sines.shape))
        coeffs = row_coefficients(values, spline)
        position = np.subtract(rho[part], r_k[0], out=ws.f64[1, :rho[part].size].reshape(rho[part].shape))
        position *= 1.0 / fine.dr
        if clip:
            position[(position < outside[0]) | (position > outside[1])] = -1e9
            np.clip(position, -2.0, r_k.size + 1.0, out=position)
        target = out[rows.start + part.start:rows.start + part.stop, cols]
        target += r_pass(premodulated_rows(coeffs, carrier, ws), r_k.size, position, r_tables,
                         ws.c64[0, :position.size].reshape(position.shape))
