"""Phase gradient autofocus (PGA) of a focused image: estimate and remove an azimuth phase error.

A processor that focuses on the nominal track of a platform that did not fly it leaves in every
echo the phase of the antenna's deviation along the line of sight (docs/physics.md (J4)). When
that phase error is the same for every target in the image, it multiplies the image's azimuth
spectrum, and PGA recovers it from the image alone (docs/physics.md (PGA)):

1. per range line, circularly shift the brightest azimuth sample to the centre (its position
   is a linear phase in the spectrum, not part of the error);
2. keep a window about the centre that holds the defocused response and rejects the other
   targets and clutter (its width from the summed intensity, shrinking every iteration);
3. take the azimuth spectrum ``G_n(u)`` of every line and estimate the error's gradient by the
   maximum-likelihood kernel ``dphi(u) = arg sum_n G_n(u) G_n*(u - 1)``;
4. integrate, remove mean and linear trend (a constant phase and a shift), and multiply the
   image's spectrum by ``exp(-j phi)``; repeat until the correction is small.

Backprojected images are first deramped (docs/physics.md (PGA2)): multiplied by
``exp(-j k (x - x_ref)^2 / R0)`` so that their azimuth spectrum is indexed by the antenna's position
along the track, where the error of a motion is one function for every target.

PGA runs only where the image holds a dominant scatterer (docs/physics.md (PGA3)): its brightest
pixel at least :data:`DOMINANCE_DB` above the median intensity of its signal. It learns only from
the point-like range lines (docs/physics.md (PGA4), :func:`~sarmitsuba.focus.pga_lines.point_lines`):
a peak well above the clutter holding most of the line's lit energy near it; clutter, rims and the
double bounce of walls spread along the line and are left out. With fewer than :data:`MIN_LINES`
such lines, or no dominant scatterer, it would fit a phase error to speckle and smear an image
that may have been focused; it warns instead and returns the image unchanged.

A linear phase error only shifts the image and PGA cannot see it. Given the world position of a
known point (``reference``), PGA measures where that point appears and removes the shift
(docs/physics.md (PGA5)); without one, ``metadata["autofocus"]["linear_part"]`` says that it was
not estimated and, where the metadata record the motion error, bounds the shift.

No Python SAR library ships a maintained PGA (sarpy, ISCE3 and sarkit do not), so it is written
here, following the paper step by step.

References
----------
.. [1] D. E. Wahl, P. H. Eichel, D. C. Ghiglia and C. V. Jakowatz, "Phase gradient autofocus: a
   robust tool for high resolution SAR phase correction", IEEE Trans. Aerosp. Electron. Syst.
   30(3), 827-835, 1994.
.. [2] C. V. Jakowatz and D. E. Wahl, "Eigenvector method for maximum-likelihood estimation of
   phase errors in synthetic-aperture-radar imagery", J. Opt. Soc. Am. A 10(12), 2539-2546, 1993.
"""
from __future__ import annotations

import copy
import dataclasses
import warnings
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.trajectory import MotionError
from .pga_lines import (POINT_DB, POINT_SHARE, linear_shift_bound, point_lines, reference_azimuth,
                        reference_shift, shift_phase, signal_pixels, upsample)

__all__ = ["signal_pixels", "point_lines", "pga", "AutofocusReport", "AutofocusWarning"]

#: Largest number of iterations.
MAX_ITERATIONS = 20
#: Iterations run at least (the window shrinks in each: a wide first window biases the estimate).
MIN_ITERATIONS = 4
#: Stop when the rms of an iteration's correction falls below this [rad].
TOLERANCE = 0.05
#: The window's first width: the azimuth samples where the summed, centred intensity lies within
#: this many dB of its peak, times :data:`WIDEN` (Wahl et al. section III-C: -10 dB).
WINDOW_DB = 10.0
WIDEN = 1.5
#: Each iteration's window is this fraction of the last, never narrower than :data:`MIN_WINDOW` nor
#: than the first over :data:`FLOOR` (a window narrower than the error's paired echoes cuts them off and
#: loses the error's fast part).
SHRINK = 0.8
MIN_WINDOW = 5
FLOOR = 4
#: Spectral samples whose summed power lies below this many dB of its peak carry no estimate (their
#: correction is held at the nearest estimate's); the rms that decides convergence and is reported
#: is taken over the samples within :data:`RMS_DB`. It is what keeps PGA short of the true track on a
#: clean Taylor-weighted point (-54.2 dB against -57.8); a wider support takes in samples where
#: clutter outweighs the point (docs/physics.md (PGA5)).
SUPPORT_DB = 40.0
RMS_DB = 20.0
#: Fewer point-like range lines than this (docs/physics.md (PGA4)): too few targets for an
#: estimate, PGA warns and returns the image unchanged.
MIN_LINES = 3
#: PGA needs dominant scatterers (Wahl et al. 1994, section II): it runs only when the image's
#: brightest pixel stands this many dB above the median intensity of the pixels that hold signal
#: (:func:`signal_pixels`: the clutter background, not the empty parts of the image), measured
#: on the image PGA works on (deramped, eq. (PGA2)). Speckle alone reaches about
#: ``10 log10((ln N + 0.58) / ln 2)``: 13.9 dB for ``N = 4096^2`` pixels; measured on rendered
#: clutter 12.2 to 13.3 dB, where PGA ran 17 to 20 iterations to 6 to 7 rad rms and smeared the
#: image. A trihedral in that clutter, on the nominal track of a 2 cm sway: PGA
#: restores it at 29.8 dB and above, fails at 21.0 dB (docs/physics.md (PGA3)).
DOMINANCE_DB = 25.0


class AutofocusWarning(UserWarning):
    """The image does not fit PGA's assumptions well: the estimate may be unreliable."""


@dataclasses.dataclass(frozen=True)
class AutofocusReport:
    """What PGA estimated.

    Attributes
    ----------
    phase_error : float64 [n_azimuth], rad
        The phase error removed from the azimuth spectrum, in centred frequency order
        (``numpy.fft.fftshift`` of ``numpy.fft.fftfreq(n_azimuth, d_azimuth)``), less its
        power-weighted mean and linear trend over the supported samples; held at its end values beyond them.
    support : bool [n_azimuth]
        Spectral samples with signal (within :data:`SUPPORT_DB` of the summed power's peak).
    iterations : int
    rms_phase_error : float, rad
        Rms of ``phase_error`` over the samples within :data:`RMS_DB` of the peak, weighted by the
        summed power.
    converged : bool
        Whether the last correction fell below :data:`TOLERANCE` within :data:`MAX_ITERATIONS`.
    lines : int
        Point-like range lines used (:func:`point_lines`, docs/physics.md (PGA4)).
    window : list of int
        The window width [azimuth samples] of every iteration (of the upsampled image with ``deramp``).
    deramp : bool
        Whether the image was deramped (docs/physics.md (PGA2)): then ``phase_error`` is a function
        of the antenna's along-track position, common to every target of a stripmap image.
    dominance_db : float, dB
        The brightest pixel over the median intensity of the pixels that hold signal
        (:func:`signal_pixels`, docs/physics.md (PGA3)).
    applied : bool
        False when ``dominance_db`` < :data:`DOMINANCE_DB` (no dominant scatterer) or fewer than
        :data:`MIN_LINES` range lines are point-like: the image was returned unchanged
        (``iterations`` 0, ``phase_error`` zero).
    linear_shift_m : float or None, m
        The along-track shift removed with the linear part of the phase error, measured at the
        ``reference`` point (docs/physics.md (PGA5)); None when no reference was given (the
        linear part is then not estimated and the image may be shifted along track).
    reference : tuple of 3 floats or None, m
        The world position of the known point the linear part was estimated from.
    linear_bound_m : float or None, m
        Without a reference: the largest shift the linear part can leave, ``ground range x
        max |de/ds|`` (eq. (PGA5)), where the image's metadata record a sinusoidal motion error;
        None otherwise.
    refusal : str
        Why the image was returned unchanged (``"no dominant scatterer"`` or ``"N point-like range
        line(s)"``, fewer than :data:`MIN_LINES`); ``""`` when PGA ran.
    correction : float64 [n_azimuth] or None, rad
        The whole phase removed from the azimuth spectrum (``phase_error`` plus the linear part
        taken out at ``reference``), centred order; None when PGA was not applied.
    aperture_position : float64 [n_azimuth] or None, m
        With ``deramp``: the antenna's along-track position, from the track's mid-aperture position
        along its direction, that each spectral sample stands for on the lines used,
        ``-f lambda R0 / 2`` (eq. (PGA2); ``R0`` their power-weighted closest-approach range);
        None otherwise. :func:`~sarmitsuba.focus.autofocus_pulses.pulse_correction` reads
        ``correction`` at each pulse's position through it.
    """

    phase_error: np.ndarray
    support: np.ndarray
    iterations: int
    rms_phase_error: float
    converged: bool
    lines: int
    window: list[int]
    deramp: bool = False
    dominance_db: float = float("inf")
    applied: bool = True
    linear_shift_m: float | None = None
    reference: tuple[float, float, float] | None = None
    linear_bound_m: float | None = None
    refusal: str = ""
    correction: np.ndarray | None = None
    aperture_position: np.ndarray | None = None

    def as_metadata(self) -> dict[str, Any]:
        """The record kept in ``image.metadata["autofocus"]`` (JSON types)."""
        return {"method": "pga", "iterations": self.iterations, "rms_phase_error_rad": self.rms_phase_error,
                "converged": self.converged, "lines": self.lines, "window_samples": self.window,
                "deramp": self.deramp, "applied": self.applied, "refusal": self.refusal,
                "dominance_db": round(float(self.dominance_db), 2) if np.isfinite(self.dominance_db) else None,
                "phase_error_rad": [round(float(v), 6) for v in self.phase_error],
                "linear_part": self._linear_record()}

    def _linear_record(self) -> dict[str, Any]:
        """What became of the linear part of the phase error (docs/physics.md (PGA5))."""
        if self.linear_shift_m is not None:
            return {"estimated": True, "shift_m": round(float(self.linear_shift_m), 4),
                    "reference": [float(v) for v in self.reference]}
        bound = None if self.linear_bound_m is None else round(float(self.linear_bound_m), 3)
        return {"estimated": False, "bound_m": bound,
                "note": "not estimated (PGA cannot see a linear phase): the image may be shifted along track by "
                        "up to ground range x max |de/ds| of the motion error (bound_m where the metadata record "
                        "it); give pga a reference point to remove it"}


def pga(image: SarImage, *, reference: Any = None, max_iterations: int = MAX_ITERATIONS,
        tolerance: float = TOLERANCE, progress: bool = False,
        aperture_cells: int | None = None) -> tuple[SarImage, AutofocusReport]:
    """Phase gradient autofocus of ``image`` along its azimuth axis (docs/physics.md (PGA)).

    Parameters
    ----------
    image : SarImage
        Focused complex image ``[n_azimuth, n_range]`` of a straight (nominal) track, its azimuth
        axis along the track (any focuser: backprojection, FFBP, omega-K, RDA).
    reference : 3 floats, m, optional
        World position of a known point-like scatterer in the image (a surveyed corner
        reflector): the linear part of the phase error, which PGA cannot see, is then estimated
        from where that point appears and removed (docs/physics.md (PGA5)). Without it the image
        may be shifted along track, and ``metadata["autofocus"]["linear_part"]`` says so.
    max_iterations : int, default 20
        1 .. 100.
    tolerance : float, rad, default 0.05
        Stop when an iteration's correction has a smaller rms (> 0).
    progress : bool, default False
        A :mod:`tqdm` bar over the iterations.
    aperture_cells : int, optional
        On a deramped image, the narrowest window: the one whose spectral cell is the track's
        length over ``aperture_cells`` (:data:`APERTURE_CELLS` through the pulses,
        docs/physics.md (PGA6)); default: the window shrinks as in (PGA).

    Returns
    -------
    (SarImage, AutofocusReport)
        The corrected image (complex64, same grid; ``metadata["autofocus"]`` =
        :meth:`AutofocusReport.as_metadata`) and the estimate.

    Raises
    ------
    ValueError
        The image comes from a circular track (``metadata["radar"]["trajectory"] == "circular"``:
        its azimuth axis is not an aperture, use backprojection on the true track), has fewer
        than 8 azimuth samples, or an option is out of range.
    ParameterError
        ``reference`` is not 3 finite numbers or appears outside the image (a ValueError).

    Warns
    -----
    AutofocusWarning
        The image is returned unchanged (``metadata["autofocus"]["applied"]`` false) when it holds
        no dominant scatterer (its brightest pixel less than :data:`DOMINANCE_DB` above the
        median intensity of its signal, docs/physics.md (PGA3)) or fewer than :data:`MIN_LINES`
        point-like range lines (docs/physics.md (PGA4)). A warning too when PGA does not
        converge within ``max_iterations``.

    Notes
    -----
    The phase error must be common to the targets used. A backprojected image (its
    ``metadata["focus"]["track"]``) is deramped first (docs/physics.md (PGA2)), so that an error
    that is a function of the antenna's position along the track is common to every target, and
    defocus spread over metres is still a Fourier pair of the aperture; other images (omega-K,
    RDA) are processed as they are, which holds for a spotlight image or for targets within a
    small part of one synthetic aperture. The estimate uses only the point-like range lines
    (eq. (PGA4)): clutter, rims and walls spread along a line are left out. A constant phase is
    not estimated, nor, without ``reference``, a linear one (a shift, eq. (PGA5)). Measured
    (benchmarks/trajectory.py, table ``pga``): a 2 cm, 40 m sinusoidal motion error on a 69 m
    airborne X-band aperture, PSLR -39.6 dB after PGA against -39.4 dB on the true track.
    """
    data, options = _check(image, max_iterations, tolerance)
    frame = _fresnel_frame(image)
    if frame is not None:
        data = upsample(data, frame.factor) * np.exp(-1j * frame.phase)     # deramped, eq. (PGA2)
    target = reference_azimuth(image, reference)
    intensity = np.abs(data).astype(np.float64) ** 2
    signal = signal_pixels(intensity)
    dominance = _dominance_db(intensity, signal)
    lines = point_lines(intensity, signal)
    reason, refusal = _refusal(dominance, lines.size)
    if refusal:
        warnings.warn(refusal, AutofocusWarning, stacklevel=2)
        report = AutofocusReport(phase_error=np.zeros(data.shape[0]), support=np.zeros(data.shape[0], bool),
                                 iterations=0, rms_phase_error=0.0, converged=False, lines=int(lines.size), window=[],
                                 deramp=frame is not None, dominance_db=dominance, applied=False,
                                 refusal=reason, linear_bound_m=_linear_bound(image))
        return _with_report(image, image.data, report)
    spectrum = np.fft.fftshift(np.fft.fft(data.astype(np.complex128), axis=0), axes=0)   # centred order
    step = _row_step(image, frame)
    aperture = _aperture(image, frame, step, lines, intensity)
    options.update(_track_limits(image, aperture, step, aperture_cells))
    total, support, centred, widths, converged = _iterate(spectrum, lines, options, progress)
    if not converged:
        warnings.warn(f"PGA did not converge in {len(widths)} iterations (last correction above "
                      f"{options['tolerance']:g} rad rms): the error may vary across the image",
                      AutofocusWarning, stacklevel=2)
    total = _extend(_detrend(total, support, _power(centred)), support)
    shift = None if target is None else reference_shift(_apply(spectrum, total), image, step, target)
    linear = 0.0 if shift is None else shift_phase(total.size, step, shift)
    out = _apply(spectrum, total + linear)
    if frame is not None:
        out = (out * np.exp(1j * frame.phase))[::frame.factor]
    report = AutofocusReport(phase_error=total, support=support, iterations=len(widths),
                             rms_phase_error=_rms(total, support, centred), converged=converged,
                             lines=int(lines.size), window=widths, deramp=frame is not None, dominance_db=dominance,
                             linear_shift_m=shift, reference=None if shift is None else tuple(target[1]),
                             linear_bound_m=None if shift is not None else _linear_bound(image), correction=total + linear,
                             aperture_position=aperture)
    return _with_report(image, out.astype(np.complex64), report)


def _refusal(dominance: float, lines: int) -> tuple[str, str]:
    """Why PGA may not run and its warning (docs/physics.md (PGA3), (PGA4)), or ('', '')."""
    if not dominance >= DOMINANCE_DB:
        return "no dominant scatterer", (
            f"PGA not applied: no dominant scatterer, the brightest pixel is {dominance:.1f} dB above the "
            f"image's median intensity (PGA needs >= {DOMINANCE_DB:g} dB; clutter alone reaches about 14 dB): "
            f"the image is returned unchanged. PGA estimates the phase error from point-like targets "
            f"(corner reflectors, isolated strong scatterers)")
    if lines < MIN_LINES:
        return f"{lines} point-like range line(s)", (
            f"PGA not applied: only {lines} range line(s) hold a point-like scatterer (PGA needs >= {MIN_LINES}: "
            f"a peak >= {POINT_DB:g} dB above the clutter with >= {POINT_SHARE:g} of the line's energy near it; "
            f"rims, walls and clutter spread it along the line): the image is returned unchanged. Add a corner "
            f"reflector, or focus on the true track")
    return "", ""


def _with_report(image: SarImage, data: np.ndarray, report: AutofocusReport) -> tuple[SarImage, AutofocusReport]:
    metadata = copy.deepcopy(image.metadata)
    metadata["autofocus"] = report.as_metadata()
    return dataclasses.replace(image, data=data, metadata=metadata), report


def _iterate(spectrum: np.ndarray, lines: np.ndarray, options: dict[str, Any],
             progress: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int], bool]:
    """Steps 1-4 of (PGA), iterated on the point-like ``lines``: the summed correction, its support,
    the last centred lines, the window widths and whether it converged."""
    from tqdm.auto import tqdm
    total = np.zeros(spectrum.shape[0])
    widths: list[int] = []
    converged = False
    width = first = None
    floor = MIN_WINDOW
    bar = tqdm(total=options["max_iterations"], desc="PGA", unit="iteration", disable=not progress)
    try:
        for _ in range(options["max_iterations"]):
            centred = _centre(_apply(spectrum, total)[:, lines])
            if width is None:
                width = first = _window_width(centred)
            else:
                width = max(MIN_WINDOW, first // FLOOR, int(width * SHRINK))
            width = min(max(width, floor), centred.shape[0])
            widths.append(width)
            step, support = _estimate(centred, width, options["band"])
            if options["cells"]:                     # eq. (PGA6): the estimate's span over cells
                floor = max(MIN_WINDOW, int(np.ceil(centred.shape[0] * options["cells"] / max(support.sum(), 1))))
            total += step
            bar.update(1)
            if len(widths) >= MIN_ITERATIONS and _rms(step, support, centred) < options["tolerance"]:
                converged = True
                break
    finally:
        bar.close()
    return total, support, centred, widths, converged


def _check(image: SarImage, max_iterations: Any, tolerance: Any) -> tuple[np.ndarray, dict[str, Any]]:
    if not isinstance(image, SarImage):
        raise TypeError(f"image must be a sarmitsuba SarImage, got {type(image).__name__}")
    radar = image.metadata.get("radar") if isinstance(image.metadata, dict) else None
    if isinstance(radar, dict) and radar.get("trajectory") == "circular":
        raise ValueError("PGA needs an image of a straight track (its azimuth axis the aperture); this one is "
                         "of a circular track: focus it with bp or ffbp on the true track instead")
    if image.data.shape[0] < 8:
        raise ValueError(f"PGA needs >= 8 azimuth samples, the image has {image.data.shape[0]}")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) \
            or not 1 <= max_iterations <= 100:
        raise ValueError(f"max_iterations must be an integer in 1 .. 100, got {max_iterations!r}")
    if not (isinstance(tolerance, (int, float)) and np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be a positive number of radians, got {tolerance!r}")
    return np.asarray(image.data), {"max_iterations": int(max_iterations), "tolerance": float(tolerance)}


@dataclasses.dataclass(frozen=True)
class _Fresnel:
    """The deramp of an image: upsampling ``factor`` in azimuth and the phase ``k x^2 / R0``
    [n_az * factor, n_rg] (rad) of every upsampled pixel."""

    factor: int
    phase: np.ndarray
    r0: np.ndarray


#: Largest azimuth upsampling for the deramp (beyond it PGA runs on the image as it is).
MAX_UPSAMPLE = 8


def _fresnel_frame(image: SarImage) -> _Fresnel | None:
    """The deramp of a backprojected image (``metadata["focus"]["track"]``: mid-aperture position,
    direction and length of the straight track, and ``fc``), or None for other images.

    ``x`` is each pixel's along-track coordinate from the mid-aperture position and ``R0`` its
    closest-approach range; the deramped spectrum spans ``k (X + L) / (pi R0)`` cycles per metre
    (``X`` the image's azimuth extent, ``L`` the track's length), which the azimuth sampling must
    hold: the image is upsampled by the smallest integer that does so with 10 % to spare."""
    focus = image.metadata.get("focus") if isinstance(image.metadata, dict) else None
    track = focus.get("track") if isinstance(focus, dict) else None
    if not (isinstance(track, dict) and track.get("direction") is not None and focus.get("fc")):
        return None
    position, direction = np.asarray(track["position"], float), np.asarray(track["direction"], float)
    k = 2.0 * np.pi * float(focus["fc"]) / SPEED_OF_LIGHT
    columns = image.origin + image.range[:, None] * image.range_direction - position        # [n_rg, 3]
    r0 = np.linalg.norm(columns - np.outer(columns @ direction, direction), axis=1)
    step = float(np.median(np.abs(np.diff(image.azimuth)))) if image.azimuth.size > 1 else 0.0
    extent = float(np.ptp(image.azimuth)) + float(track.get("length", 0.0))
    factor = max(1, int(np.ceil(1.1 * k * extent / (np.pi * float(r0.min())) * step)))
    if not (step > 0 and np.all(r0 > 0)) or factor > MAX_UPSAMPLE:
        return None
    rows = image.azimuth[0] + step / factor * np.arange(image.azimuth.size * factor)
    along = (columns @ direction)[None, :] + rows[:, None] * float(image.azimuth_direction @ direction)
    return _Fresnel(factor, k * along ** 2 / r0[None, :], r0)


def _apply(spectrum: np.ndarray, phase: np.ndarray) -> np.ndarray:
    """The image of the centred-order azimuth ``spectrum`` [n_az, n] with ``exp(-j phase)`` removed."""
    return np.fft.ifft(np.fft.ifftshift(spectrum * np.exp(-1j * phase)[:, None], axes=0), axis=0)


def _dominance_db(intensity: np.ndarray, signal: np.ndarray) -> float:
    """The brightest pixel's intensity over the median intensity of the pixels that hold signal
    (:func:`signal_pixels`) [dB] (eq. (PGA3)); -inf for an image without signal. Empty parts of
    the image (beyond the scene, in shadow, outside every beam), which only sidelobes reach, are
    not clutter and do not pull the median down."""
    if not signal.any():
        return float("-inf")
    return float(10.0 * np.log10(intensity.max() / np.median(intensity[signal])))


def _centre(lines: np.ndarray) -> np.ndarray:
    """Step 1: every column circularly shifted so that its brightest sample sits at index 0 (the
    origin of the FFT: no linear phase is left in its spectrum)."""
    n = lines.shape[0]
    rows = (np.arange(n)[:, None] + np.argmax(np.abs(lines), axis=0)[None, :]) % n
    return np.take_along_axis(lines, rows, axis=0)


def _distance(n: int) -> np.ndarray:
    """Circular distance [samples] of each index from index 0."""
    k = np.arange(n)
    return np.minimum(k, n - k)


def _window_width(centred: np.ndarray) -> int:
    """Step 2, first iteration: the width of the summed intensity above -:data:`WINDOW_DB` dB,
    times :data:`WIDEN` (at least :data:`MIN_WINDOW`, at most the image)."""
    intensity = np.sum(np.abs(centred) ** 2, axis=1)
    above = intensity >= intensity.max() * 10.0 ** (-WINDOW_DB / 10.0)
    width = int(np.ceil(WIDEN * (2 * np.max(_distance(centred.shape[0])[above]) + 1)))
    return int(np.clip(width, MIN_WINDOW, centred.shape[0]))


def _estimate(centred: np.ndarray, width: int, band: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Steps 2-3: the windowed lines' spectra and the integrated maximum-likelihood gradient
    (zero-mean, no linear trend, over the supported samples), and the support (within ``band``,
    bool [n], where given); centred order."""
    keep = _distance(centred.shape[0]) <= width // 2
    spectra = np.fft.fft(np.where(keep[:, None], centred, 0.0), axis=0)
    spectra = np.fft.fftshift(spectra, axes=0)                       # contiguous about zero frequency
    power = np.sum(np.abs(spectra) ** 2, axis=1)
    support = power >= power.max() * 10.0 ** (-SUPPORT_DB / 10.0)
    if band is not None:
        support &= band
    gradient = np.angle(np.sum(spectra[1:] * np.conj(spectra[:-1]), axis=1))
    gradient = np.where(support[1:] & support[:-1], gradient, 0.0)    # no estimate across gaps
    phase = np.concatenate([[0.0], np.cumsum(gradient)])
    phase = _extend(_detrend(phase, support, power), support)
    return phase, support


def _extend(phase: np.ndarray, support: np.ndarray) -> np.ndarray:
    """``phase`` on ``support``, interpolated linearly across its gaps and held constant beyond its
    ends (the weak spectral samples just outside still get the error of their neighbours)."""
    k = np.arange(phase.size)
    return np.interp(k, k[support], phase[support]) if support.any() else np.zeros_like(phase)


def _detrend(phase: np.ndarray, support: np.ndarray, power: np.ndarray) -> np.ndarray:
    """``phase`` less its power-weighted mean and linear trend over ``support`` (centred order)."""
    k = np.arange(phase.size, dtype=float)
    w = np.where(support, power, 0.0)
    if not w.sum() > 0:
        return np.zeros_like(phase)
    slope, offset = np.polyfit(k[support], phase[support], 1, w=np.sqrt(w[support]))
    return phase - (slope * k + offset)


def _power(centred: np.ndarray) -> np.ndarray:
    """Summed spectral power of the centred lines, centred order."""
    return np.fft.fftshift(np.sum(np.abs(np.fft.fft(centred, axis=0)) ** 2, axis=1))


def _rms(phase: np.ndarray, support: np.ndarray, centred: np.ndarray) -> float:
    """Power-weighted rms of ``phase`` (centred order) over the samples within :data:`RMS_DB` of the
    peak power (the weak samples of ``support`` carry too little signal to say whether it converged)."""
    power = _power(centred)
    w = np.where(support & (power >= power.max() * 10.0 ** (-RMS_DB / 10.0)), power, 0.0)
    return float(np.sqrt(np.sum(w * phase ** 2) / w.sum())) if w.sum() > 0 else 0.0


#: The narrowest window smooths the estimate over no more than its support (the along-track span
#: the used targets were seen from) over this many spectral cells (docs/physics.md (PGA6)). A
#: window cut to a focused point's few samples smooths it over metres, most at the band's ends,
#: where the estimate then stalls (a 60 m sway at -49.5 dB, true track -58.1); 24 cells gave
#: -55.5 dB on a 1.4 cm, 30 m sway where 48 give -58.2 (true track -57.6).
APERTURE_CELLS = 48


def _track_limits(image: SarImage, aperture: np.ndarray | None, step: float, cells: int | None) -> dict[str, Any]:
    """``{"band": bool [n] or None, "cells": int or None}``: with a deramp, the spectral samples
    that stand for positions on the track (``|s| <= L / 2`` and one cell) and ``cells``, which sets
    the narrowest window (eq. (PGA6): the window whose smoothing of the spectrum is the estimate's
    support over ``cells``); without one, no band and no floor."""
    length = float(image.metadata["focus"]["track"].get("length", 0.0)) if aperture is not None else 0.0
    if aperture is None or not length > 0 or aperture.size < 2:
        return {"band": None, "cells": None}
    cell = float(np.abs(aperture[1] - aperture[0]))        # lambda R0 / (2 n |step|)
    return {"band": np.abs(aperture) <= length / 2.0 + cell, "cells": cells}


def _aperture(image: SarImage, frame: _Fresnel | None, step: float, lines: np.ndarray,
              intensity: np.ndarray) -> np.ndarray | None:
    """The antenna's along-track position [m] of every spectral sample of a deramped image (eq.
    (PGA2)): ``-f lambda R0 / 2`` on rows ``step`` apart (times the sign of the image's azimuth
    axis along the track), ``R0`` the closest-approach range of the used ``lines`` weighted by their
    intensity; None without a deramp."""
    if frame is None:
        return None
    focus = image.metadata["focus"]
    wavelength = SPEED_OF_LIGHT / float(focus["fc"])
    weight = intensity[:, lines].sum(axis=0)
    r0 = float(np.sum(weight * frame.r0[lines]) / weight.sum())
    sense = float(np.sign(image.azimuth_direction @ np.asarray(focus["track"]["direction"], float)) or 1.0)
    f = np.fft.fftshift(np.fft.fftfreq(intensity.shape[0], d=step))
    return -sense * f * wavelength * r0 / 2.0


def _row_step(image: SarImage, frame: _Fresnel | None) -> float:
    """Azimuth spacing [m, signed] of the rows PGA works on (upsampled by the deramp's factor)."""
    step = float(np.median(np.diff(image.azimuth))) if image.azimuth.size > 1 else 1.0
    return step / (frame.factor if frame is not None else 1)


def _linear_bound(image: SarImage) -> float | None:
    """The largest shift [m] the unestimated linear part can leave (eq. (PGA5)) where the metadata
    record a sinusoidal motion error (``radar["motion_error"]``) and the track; else None."""
    radar = image.metadata.get("radar") if isinstance(image.metadata, dict) else None
    focus = image.metadata.get("focus") if isinstance(image.metadata, dict) else None
    track = focus.get("track") if isinstance(focus, dict) else None
    if not (isinstance(radar, dict) and isinstance(track, dict) and track.get("direction") is not None):
        return None
    try:
        error = MotionError.parse(radar.get("motion_error"))
    except ValueError:
        return None
    if error is None or error.kind != "sinusoid":
        return None
    direction = np.asarray(track["direction"], float)
    offset = np.asarray(image.origin, float) - np.asarray(track["position"], float)
    across = offset - (offset @ direction) * direction
    return linear_shift_bound(float(np.hypot(across[0], across[1])), 2.0 * np.pi * error.amplitude / error.length)
