"""The raw-data figure: magnitude, phase and a zoom on the brightest point-like echo.

Part of the explanatory figures of :mod:`sarmitsuba.products.figures` (which re-exports
:func:`raw_figure`); drawn from a saved :class:`~sarmitsuba.core.raw.RawData` only, with the display
conventions of :mod:`sarmitsuba.products.plotting`.

==============================  ================================================================
:func:`raw_figure`              Raw data: magnitude (dB) and phase, pulses x slant range; zoom on
                                the brightest point-like target (or a note that none is):
                                range migration, phase history against a point's.
:func:`pick_echo`               The brightest echo whose phase history is a point target's.
:class:`Echo`                   That echo and how well it follows a point target.
==============================  ================================================================
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from .plotting import agg_figure, check_dynamic_range, decibels, display_looks, edges, multilook, \
    reference_intensity, save_png
from ..core.raw import RawData

__all__ = ["raw_figure", "pick_echo", "Echo", "POINT_PHASE_RMS", "MIN_LIT_FRACTION"]


def raw_figure(raw: RawData, path: str | os.PathLike, *, dynamic_range_db: float = 50.0,
               figsize: tuple[float, float] = (12.0, 9.0), dpi: int = 100, max_pixels: int = 800) -> Path:
    """Raw data: magnitude and phase (pulses x slant range), and a zoom on a point target's echo.

    Panels: (a) ``|s|`` in dB of the data as stored (range compressed or chirped);
    (b) their phase (cyclic colour map), blank where the magnitude is more than 30 dB below
    ``I_ref``; (c) the range-compressed magnitude around the brightest point-like echo, with
    the range-migration curve ``R(p) = sqrt(R0^2 + |A_p - A_0|^2)`` of a point at closest
    range ``R0`` seen broadside at pulse ``p_0``; (d) the unwrapped phase along that echo
    against the azimuth phase history of a point, ``-4 pi (R(p) - R0) / lambda`` (with a
    fitted phase and broadside pulse), the chirp that azimuth focusing compresses. An echo
    counts as point-like only when its phase history matches a point's within
    :data:`POINT_PHASE_RMS` rad RMS over its beam and it is compact in range (``pick_echo``):
    the brightest echoes of walls (urban, dihedral) are not. When no echo is, (c) and (d)
    show the brightest echo and its measured phase, say "no point-like target found" and
    draw no point-target curves.

    Parameters
    ----------
    raw : RawData
        Chirped data are range compressed for (c) and (d) with
        :func:`sarmitsuba.focus.range_compression.range_compress`.
    path : str or os.PathLike
        Target PNG.
    dynamic_range_db : float, default 50
        Shown range below ``I_ref`` in dB.
    figsize, dpi : figure size in inches and dots per inch (PNG = ``figsize * dpi`` pixels).
    max_pixels : int, default 800
        Display decimation: no axis of (a)/(b) exceeds this many pixels.

    Returns
    -------
    Path
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    compressed = raw.data
    if not raw.range_compressed:
        from ..focus.range_compression import range_compress
        compressed = range_compress(raw).data
    slant = SPEED_OF_LIGHT * raw.fast_time / 2.0
    fig = agg_figure(figsize, dpi)
    axes = fig.subplots(2, 2)
    looks = display_looks(raw.data.shape, max_pixels)
    power = multilook(raw.data, looks)
    reference = reference_intensity(power)
    extent = (*edges(slant[:power.shape[1] * looks[1]]), -0.5, power.shape[0] * looks[0] - 0.5)
    shown = axes[0, 0].imshow(decibels(power, reference, dynamic_range_db), cmap="gray", vmin=-dynamic_range_db,
                              vmax=0, origin="lower", aspect="auto", extent=extent, interpolation="nearest")
    fig.colorbar(shown, ax=axes[0, 0], label="dB")
    kind = "range compressed" if raw.range_compressed else "chirped (not range compressed)"
    axes[0, 0].set_title(f"(a) |raw|, {kind}: {raw.n_pulses} pulses x {raw.n_samples} samples", fontsize="small")
    sub = raw.data[::looks[0], ::looks[1]]
    phase = np.where(np.abs(sub) ** 2 >= reference * 1e-3, np.angle(sub), np.nan)
    shown = axes[0, 1].imshow(phase, cmap="twilight", vmin=-np.pi, vmax=np.pi, origin="lower", aspect="auto",
                              extent=extent, interpolation="nearest")
    fig.colorbar(shown, ax=axes[0, 1], label="phase [rad]")
    axes[0, 1].set_title("(b) phase (blank: more than 30 dB below the reference)", fontsize="small")
    for ax in axes[0]:
        ax.set_xlabel("slant range c tau / 2 [m]")
        ax.set_ylabel("pulse")
    _raw_zoom(fig, axes[1], raw, compressed, slant, dynamic_range_db)
    fig.suptitle(f"{raw.metadata.get('scene', 'raw data')}: fc {raw.fc / 1e9:.3g} GHz, B {raw.bandwidth / 1e6:.4g} "
                 f"MHz, PRF {raw.prf:g} Hz, fs {raw.fs / 1e6:.4g} MHz", fontsize="medium")
    return save_png(fig, path, dpi)


#: A candidate is a point target when its measured azimuth phase history differs from a point's
#: by at most this RMS [rad] (after a fitted constant and slope, i.e. phase and broadside pulse).
POINT_PHASE_RMS = 1.0
#: ... and lights at least this fraction of the pulses of its beam (within 20 dB of its brightest).
MIN_LIT_FRACTION = 0.8
_COHERENCE = 0.5             # normalised correlation with a point's history to be tested
_CANDIDATES = 8              # echoes tested, brightest first (coarse azimuth compression)


@dataclass(frozen=True)
class Echo:
    """An echo of the raw data and how well it follows a point target (see :func:`pick_echo`).

    ``sample``: range sample of the peak at the broadside pulse ``pulse``; ``first``/``last``:
    the pulses of its beam; ``r0`` [m]: closest-approach slant range; ``pulses`` [n] int,
    ``curve`` [n] m: the point's range history ``R(p)`` over them; ``measured`` [n] rad: the
    unwrapped phase sampled along ``R(p)``; ``model`` [n] rad: the point's
    ``-4 pi (R(p) - R0) / lambda`` plus the constant and slope (phase, broadside pulse) fitted
    to ``measured``; both NaN where the echo is more than 20 dB below its brightest, and
    shifted together so that ``model`` is 0 at ``pulse``; ``rms`` [rad] of ``measured -
    model`` (weighted by magnitude); ``width`` [m]: half-power width in slant range at the
    broadside pulse; ``lit``: fraction of those pulses within 20 dB of the brightest;
    ``point_like``: ``rms <= POINT_PHASE_RMS``, ``width`` within two range resolutions
    (``c / B``) plus a sample, and ``lit >= MIN_LIT_FRACTION``.
    """

    sample: int
    pulse: int
    first: int
    last: int
    r0: float
    pulses: np.ndarray
    curve: np.ndarray
    measured: np.ndarray
    model: np.ndarray
    rms: float
    width: float
    lit: float
    point_like: bool


def pick_echo(raw: RawData, compressed: np.ndarray, slant: np.ndarray) -> Echo:
    """The brightest point-like echo, or (``point_like`` False) the brightest echo when none is.

    Candidates: the peaks of a coarse azimuth compression (every range line correlated with
    the phase history of a point at that range, ``exp(-j 4 pi sqrt(R^2 + s^2) / lambda)``
    over the azimuth beam ``metadata["radar"]["azimuth_beamwidth"]`` (default 1 degree),
    no range-cell migration correction), brightest first. Each is tested as a point target
    (:func:`_point_test`): its phase history sampled along the point's range history
    ``R(p)`` must follow ``-4 pi (R(p) - R0) / lambda`` within :data:`POINT_PHASE_RMS` and
    its echo must be compact in range. Extended targets fail: a wall parallel to the track
    has a flat phase history (its stationary point moves with the antenna).

    Parameters
    ----------
    raw : RawData
    compressed : complex [n_pulses, n_samples]
        The range-compressed data.
    slant : float64 [n_samples], m
        ``c tau / 2`` of each sample.

    Returns
    -------
    Echo
        The first candidate that is point-like, else the brightest echo of all.
    """
    half_beam, step = _beam(raw)
    for _, k, p in _candidates(raw, compressed, slant, half_beam, step):
        half = int(round(slant[k] * half_beam / step))
        echo = _point_test(raw, compressed, slant, k, p, max(0, p - half), min(raw.n_pulses - 1, p + half))
        if echo.point_like:
            return echo
    return echo                                          # the brightest echo, not point-like


def _beam(raw: RawData) -> tuple[float, float]:
    """``tan(beamwidth / 2)`` of the azimuth beam and the along-track pulse spacing [m]."""
    radar = raw.metadata.get("radar") if isinstance(raw.metadata.get("radar"), dict) else {}
    half_beam = math.tan(math.radians(float(radar.get("azimuth_beamwidth") or 1.0)) / 2.0)
    direction = raw.velocity[0] / max(float(np.linalg.norm(raw.velocity[0])), 1e-12)
    along = (raw.tx_position - raw.tx_position[0]) @ direction
    step = float(np.median(np.abs(np.diff(along)))) if raw.n_pulses > 1 else 1.0
    return half_beam, max(step, 1e-12)


def _candidates(raw: RawData, compressed: np.ndarray, slant: np.ndarray, half_beam: float,
                step: float) -> list[tuple[float, int, int]]:
    """Peaks ``(value, sample, pulse)`` of the coarse azimuth compression to test as point targets.

    First up to ``_CANDIDATES`` peaks whose normalised correlation with a point's phase
    history, ``|sum s h*| / sqrt(sum |s|^2 sum |h|^2)`` over the overlap, is at least
    :data:`_COHERENCE` (brightest first, at least a beam apart in pulses or 4 samples in
    range: a bright wall's range sidelobes do not crowd out a weaker point); last the
    brightest peak of all, the echo shown when none of them is point-like.
    """
    n_fft = int(2 ** math.ceil(math.log2(2 * raw.n_pulses)))
    offsets = np.fft.fftfreq(n_fft, 1.0 / n_fft) * step                 # m, circular lag order
    support = np.fft.fft(np.arange(n_fft) < raw.n_pulses)
    found, brightest = [], (0.0, 0, raw.n_pulses // 2)
    for cols in np.array_split(np.arange(raw.n_samples), max(1, raw.n_samples // 256)):
        r0 = slant[cols][None, :]
        history = np.exp(-4j * np.pi * raw.fc / SPEED_OF_LIGHT * (np.sqrt(r0 ** 2 + offsets[:, None] ** 2) - r0))
        history[np.abs(offsets)[:, None] > r0 * half_beam] = 0.0
        window = np.conj(np.fft.fft(np.abs(history) ** 2, axis=0))
        data = compressed[:, cols].astype(np.complex128)
        correlate = lambda spectrum, kernel: np.fft.ifft(spectrum * kernel, axis=0)[:raw.n_pulses]  # noqa: E731
        focused = np.abs(correlate(np.fft.fft(data, n_fft, axis=0), np.conj(np.fft.fft(history, axis=0))))
        energy = correlate(np.fft.fft(np.abs(data) ** 2, n_fft, axis=0), window).real
        taps = correlate(support[:, None], window).real
        coherence = focused / np.sqrt(np.maximum(energy * taps, 1e-300))
        p, c = np.unravel_index(int(np.argmax(focused)), focused.shape)
        if focused[p, c] > brightest[0]:
            brightest = (float(focused[p, c]), int(cols[c]), int(p))
        focused[coherence < _COHERENCE] = 0.0
        for _ in range(_CANDIDATES):
            p, c = np.unravel_index(int(np.argmax(focused)), focused.shape)
            if not focused[p, c] > 0:
                break
            found.append((float(focused[p, c]), int(cols[c]), int(p)))
            half = max(1, int(round(slant[cols[c]] * half_beam / step)))
            focused[max(0, p - half):p + half + 1, max(0, c - 4):c + 5] = 0.0
    kept: list[tuple[float, int, int]] = []
    for value, k, p in sorted(found, reverse=True):
        half = max(1, int(round(slant[k] * half_beam / step)))
        if all(abs(k - k2) > 4 or abs(p - p2) > half for _, k2, p2 in kept):
            kept.append((value, k, p))
    return kept[:_CANDIDATES] + [brightest]


def _point_test(raw: RawData, compressed: np.ndarray, slant: np.ndarray, k: int, p0: int, p_a: int,
                p_b: int) -> Echo:
    """Compare the echo at sample ``k``, broadside pulse ``p0`` with a point target (:class:`Echo`)."""
    magnitude = np.abs(compressed[p0]).astype(np.float64)
    dr = float(slant[1] - slant[0]) if raw.n_samples > 1 else 1.0
    k0 = int(np.argmax(magnitude[max(0, k - 3):k + 4])) + max(0, k - 3)
    r0 = float(slant[k0])
    if 0 < k0 < raw.n_samples - 1:                                  # parabolic peak refinement
        y = magnitude[k0 - 1:k0 + 2]
        denom = y[0] - 2 * y[1] + y[2]
        if denom < 0:
            r0 += 0.5 * (y[0] - y[2]) / denom * dr
    above = magnitude >= magnitude[k0] / math.sqrt(2.0)
    lo, hi = k0, k0
    while lo > 0 and above[lo - 1]:
        lo -= 1
    while hi < raw.n_samples - 1 and above[hi + 1]:
        hi += 1
    width = (hi - lo + 1) * dr
    antenna = 0.5 * (raw.tx_position + raw.rx_position)
    pulses = np.arange(p_a, p_b + 1)
    curve = np.sqrt(r0 ** 2 + np.sum((antenna[pulses] - antenna[p0]) ** 2, axis=1))
    samples = np.clip(np.rint((curve - slant[0]) / dr).astype(int), 0, raw.n_samples - 1)
    echo = compressed[pulses, samples].astype(np.complex128)
    model = -4.0 * np.pi * raw.fc / SPEED_OF_LIGHT * (curve - r0)
    weight = np.abs(echo)
    lit = weight >= 0.1 * weight.max() if weight.max() > 0 else np.zeros(pulses.size, bool)
    measured, fitted = np.full(pulses.size, np.nan), np.full(pulses.size, np.nan)
    rms = math.inf
    if lit.sum() >= 3:            # unwrap the difference from the model: slow for a point, so unwrapping is safe
        residual = np.unwrap(np.angle(echo[lit] * np.exp(-1j * model[lit])))
        basis = np.stack([np.ones(int(lit.sum())), (pulses[lit] - p0) / max(1, p_b - p_a)], axis=1)
        w = weight[lit]
        coef = np.linalg.lstsq(basis * w[:, None], residual * w, rcond=None)[0]
        rms = float(np.sqrt(np.sum(w * (residual - basis @ coef) ** 2) / np.sum(w)))
        measured[lit], fitted[lit] = model[lit] + residual, model[lit] + basis @ coef
        shift = fitted[lit][np.argmin(np.abs(pulses[lit] - p0))]
        measured, fitted = measured - shift, fitted - shift
    resolution = SPEED_OF_LIGHT / (2.0 * raw.bandwidth)
    covered = float(lit.mean())                 # a point is lit over its whole beam, a wall's end over half
    point_like = rms <= POINT_PHASE_RMS and width <= 2.0 * resolution + dr and covered >= MIN_LIT_FRACTION
    return Echo(k0, p0, p_a, p_b, r0, pulses, curve, measured, fitted, rms, width, covered, point_like)


def _raw_zoom(fig: Any, axes: Any, raw: RawData, compressed: np.ndarray, slant: np.ndarray,
              dynamic_range_db: float) -> None:
    """Panels (c) and (d) of :func:`raw_figure`."""
    magnitude = np.abs(compressed)
    if not np.any(magnitude > 0):
        for ax in axes:
            ax.text(0.5, 0.5, "no echo", ha="center", va="center", transform=ax.transAxes)
        return
    echo = pick_echo(raw, compressed, slant)
    p_a, p_b, k_peak = echo.first, echo.last, echo.sample
    peak = float(magnitude[p_a:p_b + 1, max(0, k_peak - 3):k_peak + 4].max())
    migration = float(echo.curve.max() - echo.r0)
    dr = float(slant[1] - slant[0]) if raw.n_samples > 1 else 1.0
    half_cols = max(16, int(math.ceil(2 * migration / dr)) + 8)
    span = p_b - p_a + 1
    rows = slice(max(0, p_a - span // 4), min(raw.n_pulses, p_b + span // 4 + 1))
    cols = slice(max(0, k_peak - half_cols), min(raw.n_samples, k_peak + half_cols + 1))
    extent = (*edges(slant[cols]), rows.start - 0.5, rows.stop - 0.5)
    db = decibels(magnitude[rows, cols].astype(np.float64) ** 2, peak ** 2, dynamic_range_db)
    shown = axes[0].imshow(db, cmap="gray", vmin=-dynamic_range_db, vmax=0, origin="lower", aspect="auto",
                           extent=extent, interpolation="nearest")
    fig.colorbar(shown, ax=axes[0], label="dB (peak = 0)")
    axes[0].set_xlabel("slant range c tau / 2 [m]")
    axes[0].set_ylabel("pulse")
    axes[1].set_xlabel("pulse")
    axes[1].set_ylabel("phase [rad]")
    if echo.point_like:
        _draw_point_echo(axes, echo, migration, dr)
    else:
        _draw_extended_echo(axes, echo)


def _draw_point_echo(axes: Any, echo: Echo, migration: float, dr: float) -> None:
    """Panels (c), (d) for a point-like echo: its range migration and phase history against a point's."""
    axes[0].plot(echo.curve, echo.pulses, "--", color="orangered", lw=1.2,
                 label=f"R(p): migration {migration:.3g} m = {migration / dr:.2g} samples")
    axes[0].legend(loc="upper right", fontsize="x-small")
    axes[0].set_title(f"(c) range compressed, brightest point target (R0 = {echo.r0:.2f} m, "
                      f"pulses {echo.first}-{echo.last})", fontsize="small")
    axes[1].plot(echo.pulses, echo.measured, color="k", lw=1.2, label="measured (unwrapped, along R(p))")
    axes[1].plot(echo.pulses, echo.model, "--", color="orangered", lw=1.2,
                 label=f"point target -4 pi (R(p) - R0) / lambda, fitted (RMS difference {echo.rms:.2f} rad)")
    axes[1].legend(loc="lower center", fontsize="x-small")
    axes[1].set_title("(d) its azimuth phase history: the chirp that azimuth focusing compresses",
                      fontsize="small")


def _draw_extended_echo(axes: Any, echo: Echo) -> None:
    """Panels (c), (d) when no echo is point-like: the brightest echo, no point-target model."""
    if echo.rms > POINT_PHASE_RMS:
        reason = f"phase history {echo.rms:.3g} rad RMS from a point's"
    elif echo.lit < MIN_LIT_FRACTION:
        reason = f"lit over {100 * echo.lit:.0f} % of its beam only"
    else:
        reason = f"echo {echo.width:.2f} m wide in range"

    axes[0].set_title(f"(c) range compressed, brightest echo: no point-like target found\n({reason}; "
                      "an extended target such as a wall)", fontsize="small")
    axes[1].plot(echo.pulses, echo.measured, color="k", lw=1.2, label="measured (unwrapped, along the echo)")
    axes[1].legend(loc="lower center", fontsize="x-small")
    axes[1].set_title("(d) its azimuth phase history: not a point target's, no parabola drawn", fontsize="small")
