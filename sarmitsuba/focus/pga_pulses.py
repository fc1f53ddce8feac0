"""Phase gradient autofocus on the pulses themselves (docs/physics.md (PGA7)).

When a sway's defocused response folds onto its azimuth ambiguities (its Doppler excursion and
the beam's band exceed the PRF, :func:`~sarmitsuba.focus.autofocus_pulses.pga_focus`), no image
spectrum holds the error as a function of the antenna's position: between two pulses it turns
by more than pi. The pulses still hold it. For a point at ``X``, every pulse's range-compressed
echo read at the delay ``L_p / c`` of the track the processor knows, times
``exp(+j 2 pi fc L_p / c)``, is ``a_p exp(j phi(s_p))`` (:func:`target_samples`): the error itself,
sampled at every pulse, however far it smears the image. The points are the point-like lines of
a deramped backprojection ((PGA4)), moved along the track to the centroid of their echo's power,
where the beam saw them (:func:`beam_centred`). The kernel of (PGA)
(:func:`~sarmitsuba.focus.pga_kernel.iterate`) then runs on these samples: their image domain is
one ambiguity period, periodic (a response wider than the period folds round it, and the
circular centring and window keep it in one piece), and the gradient it estimates is the phase
step from one pulse to the next, read at every pulse with no interpolation.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData
from .autofocus import RMS_DB, kernel_options, refusal_of
from .pga_deramp import FresnelFrame, fresnel_frame
from .pga_kernel import apply_phase, circular_distance, extend_phase, iterate, spectral_power, weighted_rms
from .range_lines import fft_upsample
from .pga_lines import (band_occupancy, dominance_db, doppler_band, point_lines, reference_azimuth, reference_shift, signal_pixels,
                        upsample)

__all__ = ["PulseEstimate", "pulse_positions", "recentred", "estimate_pulses", "reference_phase",
           "target_samples", "line_points", "beam_centred", "window_scr_db"]


@dataclasses.dataclass(frozen=True)
class PulseEstimate:
    """One round of PGA on the pulses.

    Attributes
    ----------
    phase : float64 [n_pulses], rad
        The phase error of every pulse, modulo 2 pi where it turns by more than pi from one pulse
        to the next, less a constant and the linear phase that keeps the corrected response where
        the samples were read (:func:`recentred`); held at the support's end values beyond it.
    support : bool [n_pulses]
        Pulses whose summed power over the used lines lies within ``SUPPORT_DB`` of the peak.
    lines : int
        Lines used.
    windows : list of int
        The window of every iteration [samples of the period: ``n_pulses`` per ambiguity period].
    converged : bool
    rms : float, rad
        Power-weighted rms of ``phase`` over the supported pulses within ``RMS_DB`` of the peak.
    dominance_db : float, dB
        The estimation image's brightest pixel over the median of its signal (eq. (PGA3)).
    line_index : int [lines]
        The range columns used.
    window_scr_db : float, dB
        The last window's energy over the clutter it holds (the lines' median intensity outside
        it, times its samples, ``2 (width // 2) + 1``), less one (eq. (PGA8)): ``inf`` without clutter.
    """

    phase: np.ndarray
    support: np.ndarray
    lines: int
    windows: list[int]
    converged: bool
    rms: float
    dominance_db: float
    line_index: np.ndarray
    window_scr_db: float = float("inf")


def pulse_positions(tx_position: np.ndarray, track: dict[str, Any]) -> np.ndarray:
    """float64 [n_pulses], m: every pulse's along-track position from the track's mid-aperture
    ``position`` along its ``direction`` (``image.metadata["focus"]["track"]``)."""
    return (np.asarray(tx_position, float) - np.asarray(track["position"], float)) @ np.asarray(track["direction"], float)


def target_samples(raw: RawData, points: np.ndarray, factor: int = 8) -> np.ndarray:
    """complex128 [n_pulses, m]: every pulse's range-compressed echo read at each of ``points``
    (float64 [m, 3], m) at its two-way delay ``L_p / c`` on the track ``raw`` records, times
    ``exp(+j 2 pi fc L_p / c)`` (eq. (PGA7)): the point's echo with the carrier of that track removed,
    ``a_p exp(j phi(s_p))`` for a point there, however the error smears its image. The fast time is
    FFT-upsampled ``factor`` times (:func:`~sarmitsuba.focus.range_lines.fft_upsample`) and read
    linearly. ``raw`` must be range compressed."""
    fine = fft_upsample(np.asarray(raw.data), factor)
    dt = (raw.fast_time[1] - raw.fast_time[0]) / factor if raw.fast_time.size > 1 else 1.0 / raw.fs
    rows = np.arange(raw.n_pulses)
    out = np.zeros((raw.n_pulses, len(points)), complex)
    for j, point in enumerate(np.asarray(points, float)):
        delay = (np.linalg.norm(raw.tx_position - point, axis=1) + np.linalg.norm(raw.rx_position - point, axis=1)) \
            / SPEED_OF_LIGHT
        index = np.clip((delay - raw.fast_time[0]) / dt, 0.0, fine.shape[1] - 1.000001)
        low = index.astype(int)
        frac = index - low
        out[:, j] = (fine[rows, low] * (1.0 - frac) + fine[rows, low + 1] * frac) * np.exp(2j * np.pi * raw.fc * delay)
    return out


def beam_centred(raw: RawData, points: np.ndarray, positions: np.ndarray, track: dict[str, Any]) -> np.ndarray:
    """``points`` [m, 3] moved along the track to where the beam saw them: the along-track position
    at the centroid of each point's echo power over the pulses, ``sum s_p |c_p|^2 / sum |c_p|^2``
    (:func:`target_samples`; the two-way antenna pattern is centred on the target whatever the phase
    error, for a beam without squint). A point read metres from its target walks out of its range
    cell across the aperture; the image of a response folded onto its ambiguities does not say
    where along the track the target is, the echo's power does."""
    direction = np.asarray(track["direction"], float)
    moved = np.array(points, float)
    for _ in range(2):
        power = np.abs(target_samples(raw, moved)) ** 2
        centre = positions @ power / np.maximum(power.sum(axis=0), 1e-300)
        moved += np.outer(centre - (moved - np.asarray(track["position"], float)) @ direction, direction)
    return moved


def line_points(image: SarImage, frame: FresnelFrame, data: np.ndarray, lines: np.ndarray,
                spacing: float) -> np.ndarray:
    """float64 [m, 3], m: for each of ``lines`` (range columns of the deramped ``data``), the world
    point at the circular centroid of its response over one ambiguity period (``lambda R0 / (2 d)``,
    ``d`` = ``spacing`` the pulse spacing), on the image's plane: where its target lies, up to the
    shift the error's linear part makes (which only tilts the samples' phase)."""
    points = np.zeros((lines.size, 3))
    for j, col in enumerate(lines):
        period = frame.wavelength * float(frame.r0[col]) / (2.0 * spacing)
        x = frame.rows
        turn = np.sum(np.abs(data[:, col]) ** 2 * np.exp(2j * np.pi * x / period))
        along = float(np.angle(turn)) * period / (2.0 * np.pi)
        along += period * np.round((x[int(np.argmax(np.abs(data[:, col])))] - along) / period)
        azimuth = along * frame.sense                 # rows are along-track: azimuth times the sense
        points[j] = image.origin + image.range[col] * image.range_direction + azimuth * image.azimuth_direction
    return points


def estimate_pulses(image: SarImage, raw: RawData, positions: np.ndarray, *, max_window: int | None = None,
                    cells: int | None = None, lines: np.ndarray | None = None,
                    progress: bool = False) -> tuple[PulseEstimate | None, str]:
    """(PGA) on the pulses' echoes of ``image``'s point-like targets (eq. (PGA7)).

    Parameters
    ----------
    image : SarImage
        A backprojected image of ``raw`` on the (nominal) track (``metadata["focus"]["track"]``).
    raw : RawData
        The range-compressed data it was focused from.
    positions : float64 [n_pulses], m
        Along-track positions of the pulses it was focused from (:func:`pulse_positions`).
    max_window : int, optional
        The widest first window [samples of the period: ``n_pulses`` per ambiguity period].
    cells : int, optional
        The narrowest window, eq. (PGA6): ``n_pulses cells / support``.
    lines : int [k], optional
        The range columns to learn from (the image's dominance then is not asked for); default the
        point-like lines (eq. (PGA4)).
    progress : bool

    Returns
    -------
    (PulseEstimate or None, str)
        The estimate, or None and why none was made: no deramp, or the refusals of
        :func:`~sarmitsuba.focus.autofocus.refusal_of` ((PGA3), (PGA4)).
    """
    frame = fresnel_frame(image)
    if frame is None:
        return None, ("the estimation image cannot be deramped (it needs more than "
                      "pga_deramp.MAX_UPSAMPLE times its azimuth sampling)")
    data = upsample(np.asarray(image.data), frame.factor) * np.exp(-1j * frame.phase)
    intensity = np.abs(data) ** 2
    signal = signal_pixels(intensity)
    dominance = dominance_db(intensity, signal)
    chosen = lines is not None
    if not chosen:
        lines = point_lines(intensity, signal, band_occupancy(image.data, doppler_band(image)))
    reason = refusal_of(np.inf if chosen else dominance, lines.size)[0]
    if reason:
        return None, reason
    spacing = float(np.median(np.abs(np.diff(positions)))) if positions.size > 1 else 1.0
    samples = target_samples(raw, beam_centred(raw, line_points(image, frame, data, lines, spacing),
                                               positions, image.metadata["focus"]["track"]))
    options = kernel_options()
    options.pop("max_window_m")
    options.update(max_window=max_window, cells=cells)
    found = iterate(samples, options, progress)
    power = spectral_power(found.centred)
    phase = recentred(samples, extend_phase(found.total, found.support), 0.0)
    return PulseEstimate(phase, found.support, int(lines.size), found.widths, found.converged,
                         weighted_rms(phase, found.support, power, RMS_DB), dominance, lines,
                         window_scr_db(found.centred, found.widths[-1])), ""


def window_scr_db(centred: np.ndarray, width: int) -> float:
    """[dB] The energy of the centred lines (complex [n, m], their responses at index 0) within the
    window of ``width`` samples (circular), less the clutter it holds, over that clutter: the median
    intensity of the summed lines outside the window times the window's samples (eq. (PGA8)). An
    estimate from these lines fits the phase of the clutter inside the window as well as the
    target's: its phase noise is about ``1 / sqrt(2 r)`` rad at a ratio ``r``. ``inf`` where the
    lines hold nothing outside the window."""
    intensity = np.sum(np.abs(centred) ** 2, axis=1)
    keep = circular_distance(centred.shape[0]) <= width // 2
    if keep.all():
        return float("inf")
    clutter = float(np.median(intensity[~keep])) * int(keep.sum())
    energy = float(intensity[keep].sum()) - clutter
    if not clutter > 0:
        return float("inf")
    return float(10.0 * np.log10(max(energy, 1e-300) / clutter))


def recentred(samples: np.ndarray, phase: np.ndarray, to: float | None = None) -> np.ndarray:
    """``phase`` [n_pulses] plus the linear phase that puts the corrected response where the
    uncorrected one was: the circular centroid of the summed intensity of ``samples`` [n_pulses, m]
    in their image domain (one period), before and after ``exp(-j phase)``, made to coincide; or,
    where ``to`` is given, the corrected centroid put at that index (0 for samples read at the
    point itself, :func:`target_samples`: their image peaks there once the error is gone). The
    integrated gradient is the error modulo 2 pi at every pulse, and its linear part, a shift,
    is not the error's (eq. (PGA5)): a straight-line fit to a phase that wraps from pulse to pulse
    would move the response by up to half a period."""
    n = samples.shape[0]
    turn = np.exp(2j * np.pi * np.arange(n) / n)

    def centroid(phi: np.ndarray) -> float:
        intensity = np.sum(np.abs(apply_phase(samples, phi)) ** 2, axis=1)
        return float(np.angle(np.sum(intensity * turn)) * n / (2.0 * np.pi))
    shift = ((centroid(np.zeros(n)) if to is None else to) - centroid(phase) + n / 2.0) % n - n / 2.0
    f = (np.arange(n) - n // 2) / n
    return phase + 2.0 * np.pi * f * shift


def reference_phase(image: SarImage, reference: Any, positions: np.ndarray) -> tuple[np.ndarray, float]:
    """The linear pulse phase [rad, float64 [n_pulses]] that moves the known point ``reference``
    (3 floats, m) back to where it belongs in ``image`` (focused from the corrected pulses), and the
    shift it removes [m, along the image's azimuth axis] (docs/physics.md (PGA5)): the point appears
    ``D`` from its place, and ``exp(-j 2 k D' s_p / R0)`` on pulse ``p`` (``D'`` the shift along the
    track, ``R0`` the point's closest approach) moves it by ``-D``.

    Raises
    ------
    ParameterError
        ``reference`` is not 3 finite numbers or lies outside the image.
    """
    target = reference_azimuth(image, reference)
    step = float(np.median(np.diff(image.azimuth)))
    shift = reference_shift(np.asarray(image.data), image, step, target)
    track = image.metadata["focus"]["track"]
    direction = np.asarray(track["direction"], float)
    offset = np.asarray(target[1], float) - np.asarray(track["position"], float)
    r0 = float(np.linalg.norm(offset - (offset @ direction) * direction))
    k = 2.0 * np.pi * float(image.metadata["focus"]["fc"]) / SPEED_OF_LIGHT
    along = shift * float(image.azimuth_direction @ direction)
    return 2.0 * k * along / r0 * positions, shift
