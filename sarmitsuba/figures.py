"""Figures that explain a simulation, drawn from the saved containers only (no tracing).

Every function reads :class:`~sarmitsuba.raw.RawData` / :class:`~sarmitsuba.image.SarImage`
objects (as loaded from ``raw.npz`` / ``image*.npz``) and, where it needs geometry, a
:class:`~sarmitsuba.scene.LoadedScene` for the geometric ground truth of
:mod:`sarmitsuba.groundtruth` (ray casts against the scene, no SAR tracing). Each writes
one PNG with matplotlib's Agg canvas (no pyplot state), atomically (temporary name, then
rename).

==============================  ================================================================
:func:`raw_figure`              Raw data: magnitude (dB) and phase, pulses x slant range; zoom on
                                the brightest point-like target (or a note that none is):
                                range migration, phase history against a point's.
:func:`image_figure`            Focused image in dB, axes in metres.
:func:`bounce_orders_figure`    Single, double, triple bounce side by side, on one dB scale.
:func:`overlay_figure`          Image with building footprints, layover, shadow and double-bounce
                                lines from the scene; returns how well they match the image.
:func:`comparison_figure`       Any labelled images side by side, resolutions annotated.
:func:`point_target_figure`     Point-target chip and cuts with IRW, PSLR and ISLR marked.
:func:`write_figures`           All figures that apply, into a directory (plus ``figures.json``).
:func:`redraw`                  :func:`write_figures` from the files of a ``render`` output.
==============================  ================================================================

Display conventions (as :func:`sarmitsuba.products.write_quicklook`): intensity ``|I|^2``
multilooked by whole factors so no axis exceeds ``max_pixels``; ``10 log10(I / I_ref)``
with ``I_ref`` the 99.5th percentile of the non-zero intensities (bright corners saturate),
clipped to ``dynamic_range_db``; range on x (near range, the sensor side, on the left),
azimuth on y (the flight direction, upward), metres from the scene centre (ground images) or
closest-approach slant range and azimuth from the scene centre (slant images), marked on every
image panel; colour bars as tall as the images. A figure that cannot be written raises
:class:`sarmitsuba.products.WriteError` naming the target file (no temporary file is left).
"""
from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .constants import SPEED_OF_LIGHT
from .image import SarImage
from .bandlimited import dft_rows
from .outputs import atomic_write, json_default
from .products import REFERENCE_PERCENTILE, _colorbar, _edges, _label_image_axes, _multilook
from .raw import RawData

__all__ = ["raw_figure", "image_figure", "bounce_orders_figure", "overlay_figure", "comparison_figure",
           "point_target_figure", "write_figures", "redraw", "image_resolution", "FIGURE_FILES"]

#: Files written by :func:`write_figures`, by role.
FIGURE_FILES = {"raw": "fig_raw.png", "image": "fig_image.png", "bounce_orders": "fig_bounce_orders.png",
                "overlay": "fig_overlay.png", "stats": "figures.json"}
_ORDER_NAMES = {1: "single bounce", 2: "double bounce", 3: "triple bounce"}


# ============================================================================ helpers
def _figure(figsize: tuple[float, float], dpi: int, layout: str = "constrained") -> Any:
    """An Agg figure; ``layout="compressed"`` for rows of equal-aspect images sharing a colour bar
    (the bar then spans the images' height, not the grid cell's; not with a suptitle, which
    upsets it)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    if not (len(figsize) == 2 and min(figsize) > 0 and dpi > 0):
        raise ValueError(f"figsize must be two positive inches and dpi > 0, got {figsize!r}, {dpi!r}")
    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Any, path: str | os.PathLike, dpi: int) -> Path:
    return atomic_write(Path(path), lambda tmp: fig.savefig(tmp, format="png", dpi=dpi), "figure")


def _check_range(dynamic_range_db: float) -> float:
    value = float(dynamic_range_db)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"dynamic_range_db must be a finite number > 0 (dB), got {dynamic_range_db!r}")
    return value


def _looks(shape: tuple[int, ...], max_pixels: int) -> tuple[int, int]:
    if int(max_pixels) != max_pixels or max_pixels < 1:
        raise ValueError(f"max_pixels must be a whole number >= 1, got {max_pixels!r}")
    return tuple(max(1, -(-n // int(max_pixels))) for n in shape[:2])  # type: ignore[return-value]


def _reference(*powers: np.ndarray) -> float:
    """``I_ref``: the 99.5th percentile of all non-zero finite intensities (1.0 when none)."""
    values = np.concatenate([p[np.isfinite(p) & (p > 0)].ravel() for p in powers])
    return float(np.percentile(values, REFERENCE_PERCENTILE)) if values.size else 1.0


def _db(power: np.ndarray, reference: float, dynamic_range_db: float) -> np.ndarray:
    floor = reference * 10.0 ** (-dynamic_range_db / 10.0)
    power = np.where(np.isfinite(power), np.maximum(power, floor), floor)
    return np.minimum(10.0 * np.log10(power / reference), 0.0)


def _image_extent(image: SarImage, shown: tuple[int, int], looks: tuple[int, int]) -> tuple[float, ...]:
    return (*_edges(image.range[:shown[1] * looks[1]]), *_edges(image.azimuth[:shown[0] * looks[0]]))


def _show_image(ax: Any, image: SarImage, power: np.ndarray, looks: tuple[int, int], reference: float,
                dynamic_range_db: float) -> Any:
    """Draw multilooked ``power`` of ``image`` in dB on ``ax``; returns the AxesImage."""
    db = _db(power, reference, dynamic_range_db)
    shown = ax.imshow(db, cmap="gray", vmin=-dynamic_range_db, vmax=0.0, origin="lower",
                      extent=_image_extent(image, db.shape, looks), aspect="equal", interpolation="nearest")
    _label_image_axes(ax, image)
    return shown


def _percent(fraction: float | None) -> str:
    return "n/a" if fraction is None else f"{100 * fraction:.0f} %"


def _block(mask: np.ndarray, looks: tuple[int, int], how: str) -> np.ndarray:
    """Downsample a bool mask by ``looks``: ``"any"`` pixel or ``"half"`` of the block set."""
    n0, n1 = (max(1, mask.shape[0] // looks[0]) * looks[0], max(1, mask.shape[1] // looks[1]) * looks[1])
    blocks = mask[:n0, :n1].reshape(n0 // looks[0], looks[0], n1 // looks[1], looks[1])
    return blocks.any(axis=(1, 3)) if how == "any" else blocks.mean(axis=(1, 3)) >= 0.5


def image_resolution(image: SarImage) -> tuple[float, float] | None:
    """Nominal (unweighted) ``(rho_azimuth, rho_range)`` [m] of an image, from its metadata, or None.

    ``metadata["focus"]["azimuth_resolution"]`` / ``["range_resolution"]`` when the focuser
    recorded them (e.g. spotlight), else from ``metadata["radar"]``
    (:class:`~sarmitsuba.radar.RadarParameters`): ground- or slant-range resolution per
    ``image.plane`` and the stripmap azimuth resolution.
    """
    focus = image.metadata.get("focus") if isinstance(image.metadata.get("focus"), dict) else {}
    if "azimuth_resolution" in focus and "range_resolution" in focus:
        return float(focus["azimuth_resolution"]), float(focus["range_resolution"])
    radar = image.metadata.get("radar")
    if not isinstance(radar, dict):
        return None
    from .radar import RadarParameters
    try:
        names = set(RadarParameters.names())
        values = {k: v for k, v in radar.items() if k in names}
        if values.get("scene_center") is not None:
            values["scene_center"] = tuple(values["scene_center"])
        p = RadarParameters(**values)
    except (TypeError, ValueError):
        return None
    rho_rg = p.ground_range_resolution if image.plane == "ground" else p.slant_range_resolution
    return float(p.azimuth_resolution), float(rho_rg)


def _order_label(image: SarImage, k: int) -> str:
    order = int(image.metadata.get("bounce_order", k))
    return f"order {order} ({_ORDER_NAMES.get(order, f'{order} bounces')})"


# ============================================================================ raw data
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
    :data:`POINT_PHASE_RMS` rad RMS over its beam and it is compact in range (``_pick_echo``):
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
    dynamic_range_db = _check_range(dynamic_range_db)
    compressed = raw.data
    if not raw.range_compressed:
        from .focus.range_compression import range_compress
        compressed = range_compress(raw).data
    slant = SPEED_OF_LIGHT * raw.fast_time / 2.0
    fig = _figure(figsize, dpi)
    axes = fig.subplots(2, 2)
    looks = _looks(raw.data.shape, max_pixels)
    power = _multilook(raw.data, looks)
    reference = _reference(power)
    extent = (*_edges(slant[:power.shape[1] * looks[1]]), -0.5, power.shape[0] * looks[0] - 0.5)
    shown = axes[0, 0].imshow(_db(power, reference, dynamic_range_db), cmap="gray", vmin=-dynamic_range_db,
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
    return _save(fig, path, dpi)


#: A candidate is a point target when its measured azimuth phase history differs from a point's
#: by at most this RMS [rad] (after a fitted constant and slope, i.e. phase and broadside pulse).
POINT_PHASE_RMS = 1.0
#: ... and lights at least this fraction of the pulses of its beam (within 20 dB of its brightest).
MIN_LIT_FRACTION = 0.8
_COHERENCE = 0.5             # normalised correlation with a point's history to be tested
_CANDIDATES = 8              # echoes tested, brightest first (coarse azimuth compression)


@dataclass(frozen=True)
class _Echo:
    """An echo of the raw data and how well it follows a point target (see :func:`_pick_echo`).

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


def _pick_echo(raw: RawData, compressed: np.ndarray, slant: np.ndarray) -> _Echo:
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
                p_b: int) -> _Echo:
    """Compare the echo at sample ``k``, broadside pulse ``p0`` with a point target (:class:`_Echo`)."""
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
    return _Echo(k0, p0, p_a, p_b, r0, pulses, curve, measured, fitted, rms, width, covered, point_like)


def _raw_zoom(fig: Any, axes: Any, raw: RawData, compressed: np.ndarray, slant: np.ndarray,
              dynamic_range_db: float) -> None:
    """Panels (c) and (d) of :func:`raw_figure`."""
    magnitude = np.abs(compressed)
    if not np.any(magnitude > 0):
        for ax in axes:
            ax.text(0.5, 0.5, "no echo", ha="center", va="center", transform=ax.transAxes)
        return
    echo = _pick_echo(raw, compressed, slant)
    p_a, p_b, k_peak = echo.first, echo.last, echo.sample
    peak = float(magnitude[p_a:p_b + 1, max(0, k_peak - 3):k_peak + 4].max())
    migration = float(echo.curve.max() - echo.r0)
    dr = float(slant[1] - slant[0]) if raw.n_samples > 1 else 1.0
    half_cols = max(16, int(math.ceil(2 * migration / dr)) + 8)
    span = p_b - p_a + 1
    rows = slice(max(0, p_a - span // 4), min(raw.n_pulses, p_b + span // 4 + 1))
    cols = slice(max(0, k_peak - half_cols), min(raw.n_samples, k_peak + half_cols + 1))
    extent = (*_edges(slant[cols]), rows.start - 0.5, rows.stop - 0.5)
    db = _db(magnitude[rows, cols].astype(np.float64) ** 2, peak ** 2, dynamic_range_db)
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


def _draw_point_echo(axes: Any, echo: _Echo, migration: float, dr: float) -> None:
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


def _draw_extended_echo(axes: Any, echo: _Echo) -> None:
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


# ============================================================================ images
def image_figure(image: SarImage, path: str | os.PathLike, *, dynamic_range_db: float = 40.0,
                 title: str | None = None, figsize: tuple[float, float] = (9.0, 7.5), dpi: int = 100,
                 max_pixels: int = 800) -> Path:
    """The focused image in dB with axes in metres, resolution and grid annotated.

    Parameters
    ----------
    image : SarImage
    path : str or os.PathLike
        Target PNG.
    dynamic_range_db : float, default 40
        Shown range below ``I_ref`` (99.5th percentile) in dB.
    title : str, optional
        First title line (default: the scene name).
    figsize, dpi, max_pixels
        As :func:`raw_figure`.

    Returns
    -------
    Path
    """
    dynamic_range_db = _check_range(dynamic_range_db)
    looks = _looks(image.data.shape, max_pixels)
    power = _multilook(image.data, looks)
    fig = _figure(figsize, dpi)
    ax = fig.add_subplot()
    shown = _show_image(ax, image, power, looks, _reference(power), dynamic_range_db)
    _colorbar(fig, ax, shown, f"dB re the {REFERENCE_PERCENTILE:g}th percentile")
    ax.set_title(f"{title or image.metadata.get('scene', 'SAR image')}\n{_describe(image, looks)}", fontsize="small")
    return _save(fig, path, dpi)


def _window_label(image: SarImage) -> str:
    """``image.window``, or the range window of ``metadata["range_window"]`` when that was
    applied before a focuser that itself records ``"rect"`` (backprojection)."""
    applied = image.metadata.get("range_window")
    name = applied.get("name") if isinstance(applied, dict) else None
    if image.window == "rect" and name and name != "rect":
        return f"{name} range"
    return image.window


def _describe(image: SarImage, looks: tuple[int, int] = (1, 1)) -> str:
    spacing = (abs(float(image.azimuth[1] - image.azimuth[0])) if image.azimuth.size > 1 else float("nan"),
               abs(float(image.range[1] - image.range[0])) if image.range.size > 1 else float("nan"))
    # the window on a line of its own: weighted windows have long names (taylor(nbar=4, sll=-35) twice)
    first = f"{image.algorithm}, {_window_label(image)} window"
    second = [f"{image.plane} plane, {image.data.shape[0]}x{image.data.shape[1]} px of "
              f"{spacing[0]:.2f} x {spacing[1]:.2f} m"]
    res = image_resolution(image)
    if res is not None:
        second.append(f"nominal resolution {res[0]:.2f} m (az) x {res[1]:.2f} m ({image.plane} rg)")
    if looks != (1, 1):
        second.append(f"shown with {looks[0]}x{looks[1]} looks")
    return "\n".join([first, second[0]] + ([", ".join(second[1:])] if second[1:] else []))


def bounce_orders_figure(images_per_order: Sequence[SarImage] | Mapping[str, SarImage], path: str | os.PathLike, *,
                         dynamic_range_db: float = 40.0, dpi: int = 100, max_pixels: int = 600,
                         panel_size: tuple[float, float] = (5.0, 5.2)) -> Path:
    """Images of each bounce order side by side, on one dB scale.

    Parameters
    ----------
    images_per_order : sequence of SarImage (order 1, 2, ...) or mapping label -> SarImage
        As :attr:`sarmitsuba.pipeline.Simulation.images_per_order` or the saved
        ``image_order*.npz``; all on the same grid.
    path : str or os.PathLike
        Target PNG.
    dynamic_range_db : float, default 40
        Shown range in dB below the common reference: the 99.5th percentile of the pooled
        intensities of all panels, so a dark panel is dark because its order is weak.
    dpi, max_pixels
        As :func:`raw_figure`.
    panel_size : (float, float), default (5, 5.2)
        Inches per panel; the PNG is ``(n * width, height) * dpi`` pixels.

    Returns
    -------
    Path

    Notes
    -----
    Each title gives the order's share of the total image energy ``sum |I|^2``.
    """
    dynamic_range_db = _check_range(dynamic_range_db)
    if isinstance(images_per_order, Mapping):
        labelled = list(images_per_order.items())
    else:
        labelled = [(_order_label(im, k), im) for k, im in enumerate(images_per_order, start=1)]
    if not labelled:
        raise ValueError("bounce_orders_figure needs at least one image")
    looks = _looks(labelled[0][1].data.shape, max_pixels)
    powers = [_multilook(im.data, looks) for _, im in labelled]
    reference = _reference(*powers)
    energy = np.array([float(np.sum(np.abs(im.data.astype(np.complex128)) ** 2)) for _, im in labelled])
    share = energy / energy.sum() if energy.sum() > 0 else np.zeros_like(energy)
    fig = _figure((panel_size[0] * len(labelled), panel_size[1]), dpi)
    axes = np.atleast_1d(fig.subplots(1, len(labelled), sharex=True, sharey=True))
    for ax, (label, im), power, s in zip(axes, labelled, powers, share):
        shown = _show_image(ax, im, power, looks, reference, dynamic_range_db)
        ax.set_title(f"{label}\n{100 * s:.1f} % of the image energy", fontsize="small")
    _colorbar(fig, axes[-1], shown, "dB re common reference")      # all panels share the grid and scale
    fig.suptitle(f"{labelled[0][1].metadata.get('scene', '')}: bounce orders on one scale "
                 f"({dynamic_range_db:g} dB shown)", fontsize="medium")
    return _save(fig, path, dpi)


def comparison_figure(images: Mapping[str, SarImage], path: str | os.PathLike, *, dynamic_range_db: float = 40.0,
                      common_scale: bool = True, dpi: int = 100, max_pixels: int = 600,
                      panel_size: tuple[float, float] = (5.5, 5.5)) -> Path:
    """Labelled images side by side (e.g. stripmap vs spotlight), resolutions annotated.

    Parameters
    ----------
    images : mapping label -> SarImage
        Any images (grids may differ); one panel each, in order.
    path : str or os.PathLike
        Target PNG.
    dynamic_range_db : float, default 40
    common_scale : bool, default True
        One dB reference for all panels (calibrated images compare directly); False = each
        panel relative to its own 99.5th percentile.
    dpi, max_pixels, panel_size
        As :func:`bounce_orders_figure`.

    Returns
    -------
    Path

    Notes
    -----
    Each panel title gives the algorithm, window, grid and pixel spacing, and the nominal
    resolution of :func:`image_resolution` when the metadata allow it.
    """
    dynamic_range_db = _check_range(dynamic_range_db)
    if not images:
        raise ValueError("comparison_figure needs at least one image")
    labelled = list(images.items())
    looks = [_looks(im.data.shape, max_pixels) for _, im in labelled]
    powers = [_multilook(im.data, lk) for (_, im), lk in zip(labelled, looks)]
    common = _reference(*powers)
    fig = _figure((panel_size[0] * len(labelled), panel_size[1]), dpi, layout="compressed")
    axes = np.atleast_1d(fig.subplots(1, len(labelled)))
    for ax, (label, im), power, lk in zip(axes, labelled, powers, looks):
        shown = _show_image(ax, im, power, lk, common if common_scale else _reference(power), dynamic_range_db)
        ax.set_title(f"{label}\n" + _describe(im, lk), fontsize="x-small")
    fig.colorbar(shown, ax=list(axes), label="dB" + (" re common reference" if common_scale else ""))
    return _save(fig, path, dpi)


# ============================================================================ ground truth
def overlay_figure(image: SarImage, loaded: Any, path: str | os.PathLike, *, truth: Any = None,
                   threshold_db: float = 6.0, dynamic_range_db: float = 40.0, dpi: int = 100,
                   max_pixels: int = 700, figsize: tuple[float, float] = (13.0, 5.4)) -> dict[str, Any]:
    """The image with the scene's geometric ground truth drawn in, and how well they agree.

    Left: the image in dB with layover (orange) and shadow (blue) as transparent fills,
    building footprints as yellow outlines and the double-bounce lines (wall feet facing
    the sensor) in red. Right: the same masks as a label map.

    Parameters
    ----------
    image : SarImage
        Ground-plane image.
    loaded : LoadedScene
        The scene the image was made from (see :func:`sarmitsuba.groundtruth.ground_truth`).
    path : str or os.PathLike
        Target PNG.
    truth : GroundTruth, optional
        Precomputed masks; default computed here (ray casts, about 1 s for ``urban``).
    threshold_db : float, default 6
        "Bright" means an intensity ``threshold_db`` above the image median; "dark" means
        ``threshold_db`` below it.
    dynamic_range_db, dpi, max_pixels, figsize
        Display, as :func:`image_figure`.

    Returns
    -------
    dict
        ``path`` (Path) plus the numbers of :func:`sarmitsuba.groundtruth.agreement`:
        ``layover_overlap`` (fraction of layover-mask pixels whose intensity exceeds the
        image median by ``threshold_db``), ``double_bounce_bright``, ``shadow_dark``, mean
        levels and pixel counts.
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from .groundtruth import agreement, ground_truth
    dynamic_range_db = _check_range(dynamic_range_db)
    truth = ground_truth(loaded, image) if truth is None else truth
    stats = agreement(image, truth, threshold_db)
    looks = _looks(image.data.shape, max_pixels)
    power = _multilook(image.data, looks)
    fig = _figure(figsize, dpi)
    ax, ax_labels = fig.subplots(1, 2, sharex=True, sharey=True)
    shown = _show_image(ax, image, power, looks, _reference(power), dynamic_range_db)
    _colorbar(fig, ax, shown, "dB")
    extent = _image_extent(image, power.shape, looks)
    layers = (("layover", "half", (1.0, 0.55, 0.0, 0.40)), ("shadow", "half", (0.1, 0.55, 1.0, 0.45)),
              ("double_bounce", "any", (1.0, 0.0, 0.0, 0.95)))
    footprint = _block(truth.footprint, looks, "half").astype(float)
    if footprint.any() and footprint.shape[0] > 1 and footprint.shape[1] > 1:
        x = np.linspace(extent[0], extent[1], footprint.shape[1] + 1)
        y = np.linspace(extent[2], extent[3], footprint.shape[0] + 1)
        ax.contour(0.5 * (x[1:] + x[:-1]), 0.5 * (y[1:] + y[:-1]), footprint, levels=[0.5], colors="yellow",
                   linewidths=1.0, zorder=2)
    for name, how, colour in layers:
        mask = _block(getattr(truth, name), looks, how)
        rgba = np.zeros((*mask.shape, 4))
        rgba[mask] = colour
        ax.imshow(rgba, origin="lower", extent=extent, aspect="equal", interpolation="nearest",
                  zorder=3 if name == "double_bounce" else 1)
    ax.set_title(f"{image.metadata.get('scene', 'SAR image')} with the scene's ground truth\n"
                 f"layover: {_percent(stats['layover_overlap'])} of its pixels > median + {threshold_db:g} dB; "
                 f"shadow: {_percent(stats['shadow_dark'])} < median - {threshold_db:g} dB", fontsize="small")
    labels = np.zeros(power.shape, np.uint8)          # later labels win: double bounce on top
    for value, name in ((1, "footprint"), (2, "shadow"), (3, "layover"), (4, "double_bounce")):
        labels[_block(getattr(truth, name), looks, "any" if name == "double_bounce" else "half")] = value
    colours = ["0.92", "0.45", "deepskyblue", "darkorange", "red"]
    ax_labels.imshow(labels, cmap=ListedColormap(colours), vmin=-0.5, vmax=4.5,
                     origin="lower", extent=extent, aspect="equal", interpolation="nearest")
    ax_labels.set_xlabel(ax.get_xlabel())
    ax_labels.set_title(f"ground truth from the scene geometry (height threshold {truth.height_threshold:g} m)",
                        fontsize="small")
    names = ["open ground", "building footprint", "shadow", "layover", "double bounce (wall foot)"]
    ax_labels.legend(handles=[Patch(color=c, label=n) for c, n in zip(colours, names)], loc="center left",
                     bbox_to_anchor=(1.02, 0.5), fontsize="x-small", frameon=False)   # beside: clear of the labels
    stats["path"] = _save(fig, path, dpi)
    return stats


# ============================================================================ point target
def _report_value(report: Any, name: str, default: Any = None) -> Any:
    if isinstance(report, Mapping):
        value = report.get(name, default)
    else:
        value = getattr(report, name, default)
    return default if value is None else value


def point_target_figure(image: SarImage, report: Any, path: str | os.PathLike, *, oversample: int = 16,
                        dynamic_range_db: float = 40.0, figsize: tuple[float, float] = (13.0, 4.6),
                        dpi: int = 100) -> Path:
    """The standard point-target figure: chip, range and azimuth cuts, with IRW and sidelobes.

    Parameters
    ----------
    image : SarImage
        The analysed image.
    report : PointTargetReport or mapping
        From :func:`sarmitsuba.analysis.analyze_point_target`, or a dict with the same keys.
        Required: ``row``, ``column`` (fractional pixel of the peak), ``irw_azimuth``,
        ``irw_range`` [m], ``pslr_azimuth_db``, ``pslr_range_db`` [dB]. Optional:
        ``first_null_azimuth``, ``first_null_range`` [m], ``islr_azimuth_nullbounded_db``,
        ``islr_range_nullbounded_db`` [dB], ``phase_ramp_azimuth``, ``phase_ramp_range``
        [rad / pixel] (default: estimated from the chip, as the analysis does), ``chip``
        [pixels] (default 64), ``rcs_db``, ``azimuth_error``, ``range_error`` [m].
    path : str or os.PathLike
        Target PNG.
    oversample : int, default 16
        Samples per pixel of the drawn cuts (exact band-limited DFT interpolation of the
        de-ramped chip); the chip image is drawn at ``oversample / 4``.
    dynamic_range_db : float, default 40
        Shown range below the peak.
    figsize, dpi
        As :func:`raw_figure`.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        A required key is missing or the chip does not fit in the image.
    """
    dynamic_range_db = _check_range(dynamic_range_db)
    missing = [k for k in ("row", "column", "irw_azimuth", "irw_range", "pslr_azimuth_db", "pslr_range_db")
               if _report_value(report, k) is None]
    if missing:
        raise ValueError(f"point-target report lacks {missing}")
    ov = int(oversample)
    if ov < 1:
        raise ValueError(f"oversample must be >= 1, got {oversample!r}")
    n_az, n_rg = image.data.shape
    row, col = float(_report_value(report, "row")), float(_report_value(report, "column"))
    r, c = int(round(row)), int(round(col))
    chip = min(int(_report_value(report, "chip", 64)), 2 * min(r, n_az - r, c, n_rg - c)) // 2 * 2
    if chip < 8:
        raise ValueError(f"the peak at pixel ({row:.1f}, {col:.1f}) is too close to the image edge for a chip")
    i0, j0 = r - chip // 2, c - chip // 2
    z = image.data[i0:i0 + chip, j0:j0 + chip].astype(np.complex128)
    w_az = _report_value(report, "phase_ramp_azimuth", float(np.angle(np.sum(z[1:] * np.conj(z[:-1])))))
    w_rg = _report_value(report, "phase_ramp_range", float(np.angle(np.sum(z[:, 1:] * np.conj(z[:, :-1])))))
    n = np.arange(chip)
    spectrum = np.fft.fft2(z * np.exp(-1j * (w_az * n[:, None] + w_rg * n[None, :])))
    u_pk, v_pk = row - i0, col - j0
    steps = (abs(float(image.azimuth[1] - image.azimuth[0])), abs(float(image.range[1] - image.range[0])))
    t = np.arange(-(chip // 2) * ov, (chip // 2) * ov) / ov                       # pixels from the peak
    cut_az = np.abs(dft_rows(chip, u_pk + t) @ spectrum @ dft_rows(chip, [v_pk]).T)[:, 0]
    cut_rg = np.abs(dft_rows(chip, [u_pk]) @ spectrum @ dft_rows(chip, v_pk + t).T)[0]
    peak = max(cut_az.max(), cut_rg.max())
    fine = np.arange(0, chip, 4 / ov) if ov >= 4 else np.arange(chip, dtype=float)
    chip_img = np.abs(dft_rows(chip, fine) @ spectrum @ dft_rows(chip, fine).T) ** 2
    fig = _figure(figsize, dpi)
    ax_chip, ax_rg, ax_az = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.0, 1.3, 1.3]})
    extent = ((fine[0] - v_pk) * steps[1], (fine[-1] - v_pk) * steps[1],
              (fine[0] - u_pk) * steps[0], (fine[-1] - u_pk) * steps[0])
    db = _db(chip_img, peak ** 2, dynamic_range_db)
    shown = ax_chip.imshow(db, cmap="viridis", vmin=-dynamic_range_db, vmax=0, origin="lower", extent=extent,
                           aspect="equal", interpolation="bilinear")
    ax_chip.contour(db, levels=[-3.0], colors="white", linewidths=0.8, origin="lower", extent=extent)
    ax_chip.axhline(0, color="w", lw=0.5, ls=":")
    ax_chip.axvline(0, color="w", lw=0.5, ls=":")
    fig.colorbar(shown, ax=ax_chip, label="dB (peak = 0)", shrink=0.8)
    ax_chip.set_xlabel("range from peak [m]")
    ax_chip.set_ylabel("azimuth from peak [m]")
    ax_chip.set_title(f"chip {chip}x{chip} px (white: -3 dB)", fontsize="small")
    for ax, cut, axis, step in ((ax_rg, cut_rg, "range", steps[1]), (ax_az, cut_az, "azimuth", steps[0])):
        _draw_cut(ax, t * step, cut / peak, report, axis, dynamic_range_db)
    extra = [f"{k.replace('_', ' ').replace(' db', '')} {float(_report_value(report, k)):.3g} {unit}"
             for k, unit in (("azimuth_error", "m"), ("range_error", "m"), ("rcs_db", "dBsm"))
             if _report_value(report, k) is not None]
    fig.suptitle(f"point target at azimuth {float(image.azimuth[0]) + row * steps[0]:.2f} m, range "
                 f"{float(image.range[0]) + col * steps[1]:.2f} m ({_window_label(image)} window)"
                 + (f"; {', '.join(extra)}" if extra else ""), fontsize="medium")
    return _save(fig, path, dpi)


def _draw_cut(ax: Any, x: np.ndarray, amplitude: np.ndarray, report: Any, axis: str,
              dynamic_range_db: float) -> None:
    """One cut in dB with -3 dB, IRW, first nulls and PSLR marked."""
    db = 20 * np.log10(np.maximum(amplitude, 10 ** (-dynamic_range_db / 20 - 1)))
    irw = float(_report_value(report, f"irw_{axis}"))
    pslr = float(_report_value(report, f"pslr_{axis}_db"))
    islr = _report_value(report, f"islr_{axis}_nullbounded_db")
    null = _report_value(report, f"first_null_{axis}")
    ax.plot(x, db, color="k", lw=1.0)
    ax.axhline(-3.0, color="tab:blue", lw=0.8, ls="--", label="-3 dB")
    for s in (-0.5, 0.5):
        ax.axvline(s * irw, color="tab:blue", lw=0.8)
    ax.axhline(pslr, color="tab:red", lw=0.8, ls="--", label=f"PSLR {pslr:.2f} dB")
    if null is not None:
        for s in (-1.0, 1.0):
            ax.axvline(s * float(null), color="0.5", lw=0.6, ls=":")
    ax.set_xlim(x[0], x[-1])
    ax.set_ylim(-dynamic_range_db, 3.0)
    ax.set_xlabel(f"{axis} from peak [m]")
    ax.set_ylabel("dB (peak = 0)")
    text = f"IRW {irw:.3f} m" + (f", ISLR {float(islr):.2f} dB" if islr is not None else "")
    ax.set_title(f"{axis} cut: {text}", fontsize="small")
    ax.legend(loc="upper right", fontsize="x-small")


# ============================================================================ batch
def write_figures(out_dir: str | os.PathLike, raw: RawData | None, image: SarImage,
                  images_per_order: Sequence[SarImage] = (), loaded: Any = None) -> dict[str, Path]:
    """Write every figure that applies into ``out_dir`` (names: :data:`FIGURE_FILES`).

    Parameters
    ----------
    out_dir : path
        Existing or new directory.
    raw : RawData or None
        Gives ``fig_raw.png``.
    image : SarImage
        Gives ``fig_image.png``.
    images_per_order : sequence of SarImage
        Per-bounce-order images (``fig_bounce_orders.png`` when there are any).
    loaded : LoadedScene, optional
        The scene (``fig_overlay.png``, ground-plane images only).

    Returns
    -------
    dict
        Role -> path written. ``"stats"`` is ``figures.json``: the overlay numbers of
        :func:`overlay_figure` (when drawn) and the list of figures.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    stats: dict[str, Any] = {}
    if raw is not None:
        paths["raw"] = raw_figure(raw, out / FIGURE_FILES["raw"])
    paths["image"] = image_figure(image, out / FIGURE_FILES["image"])
    if len(images_per_order):
        paths["bounce_orders"] = bounce_orders_figure(list(images_per_order), out / FIGURE_FILES["bounce_orders"])
    if loaded is not None and image.plane == "ground":
        overlay = overlay_figure(image, loaded, out / FIGURE_FILES["overlay"])
        paths["overlay"] = overlay.pop("path")
        stats["overlay"] = overlay
    stats["figures"] = {role: str(p) for role, p in paths.items()}
    target = out / FIGURE_FILES["stats"]
    paths["stats"] = atomic_write(target, lambda tmp: tmp.write_text(
        json.dumps(stats, indent=2, default=json_default)), "figure statistics")
    return paths


def redraw(out_dir: str | os.PathLike, *, scene: bool = True) -> dict[str, Path]:
    """Redraw every figure from the files of a ``render`` output directory, without tracing.

    Reads ``raw.npz`` (if present), ``image.npz`` and ``image_order<k>.npz`` (sorted by
    ``k``); with ``scene`` (default), also loads the scene named in
    ``image.metadata["scene_path"]`` with the radar parameters the image was made with
    (``image.metadata["radar"]``) for the overlay, when that file exists.

    Returns
    -------
    dict
        As :func:`write_figures`.

    Raises
    ------
    sarmitsuba.image.SarImageError
        No readable ``image.npz``.
    """
    out = Path(out_dir)
    image = SarImage.load(out / "image.npz")
    raw = RawData.load(out / "raw.npz") if (out / "raw.npz").is_file() else None
    orders = sorted(out.glob("image_order*.npz"), key=lambda p: int(re.sub(r"\D", "", p.stem) or 0))
    per_order = [SarImage.load(p) for p in orders]
    loaded = _scene_of(image) if scene else None
    return write_figures(out, raw, image, per_order, loaded)


def _scene_of(image: SarImage) -> Any:
    """The scene an image was made from, with its radar parameters; None when unavailable."""
    path = image.metadata.get("scene_path")
    if not path or not Path(path).is_file():
        return None
    from .scene import load_scene
    radar = image.metadata.get("radar") or {}
    overrides = {k: v for k, v in radar.items() if v is not None}
    return load_scene(path, sensor_overrides=overrides)
