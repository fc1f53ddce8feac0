"""Phase gradient autofocus (PGA) of a focused image: estimate and remove an azimuth phase error.

A processor that focuses on the nominal track of a platform that did not fly it leaves in every
echo the phase of the antenna's deviation along the line of sight (docs/physics.md (J4)). When
that phase error is the same for every target in the image, it multiplies the image's azimuth
spectrum, and PGA recovers it from the image alone (docs/physics.md (PGA)):

1. per range line, circularly shift the brightest azimuth sample to the centre (its position
   is a linear phase in the spectrum, not part of the error);
2. keep a window about the centre, distances measured round the periodic line, that holds the
   defocused response and rejects the other targets and clutter (its width from the summed
   intensity: every sample above -:data:`WINDOW_DB` dB of its peak and :data:`BACKGROUND` times
   its median, times :data:`WIDEN`; shrinking every iteration);
3. take the azimuth spectrum ``G_n(u)`` of every line and estimate the error's gradient by the
   maximum-likelihood kernel ``dphi(u) = arg sum_n G_n(u) G_n*(u - 1)``;
4. integrate, remove mean and linear trend (a constant phase and a shift), and multiply the
   image's spectrum by ``exp(-j phi)``; repeat until the correction is small.

Backprojected images are first deramped (docs/physics.md (PGA2)): multiplied by
``exp(-j k (x - x_ref)^2 / R0)`` so that their azimuth spectrum is indexed by the antenna's position
along the track, where the error of a motion is one function for every target; every line's
spectrum is read at the same positions whatever its range (:mod:`~sarmitsuba.focus.pga_deramp`).
The kernel lives in :mod:`~sarmitsuba.focus.pga_kernel`.

PGA runs only where the image holds a dominant scatterer (docs/physics.md (PGA3)): its brightest
pixel at least :data:`DOMINANCE_DB` above the median intensity of its signal. It learns only from
the point-like range lines (docs/physics.md (PGA4), :func:`~sarmitsuba.focus.pga_lines.point_lines`):
a peak well above the clutter whose response fills the beam's Doppler band, as a point's does
however smeared; rims and the double bounce of walls, extended along the line, fill little of it
and are left out. With fewer than :data:`MIN_LINES`
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

from ..core.image import SarImage
from ..core.trajectory import MotionError
from .pga_deramp import FresnelFrame, aperture_grid, column_phase, fresnel_frame, line_spectra
from .pga_kernel import apply_phase, detrend_phase, extend_phase, iterate, spectral_power, weighted_rms
from .pga_lines import (POINT_BAND, POINT_DB, band_occupancy, dominance_db, doppler_band, linear_shift_bound, point_lines,
                        reference_azimuth, reference_shift, shift_phase, signal_pixels, upsample)

__all__ = ["signal_pixels", "point_lines", "pga", "pga_estimate", "kernel_options", "refusal_of", "AutofocusReport",
           "AutofocusWarning"]

#: Largest number of iterations.
MAX_ITERATIONS = 20
#: Iterations run at least (the window shrinks in each: a wide first window biases the estimate).
MIN_ITERATIONS = 4
#: Stop when the rms of an iteration's correction falls below this [rad].
TOLERANCE = 0.05
#: The window's first width: the azimuth samples where the summed, centred intensity lies within
#: this many dB of its peak and above :data:`BACKGROUND` times its median (what surrounds the
#: response), times :data:`WIDEN`. Wahl et al. (section III-C) take -10 dB, which holds the gross
#: error: refining a response to -55 dB sidelobes needs its paired echoes 20 dB down in the
#: window; the background keeps the window off the clutter about a point far above it.
WINDOW_DB = 20.0
WIDEN = 1.5
BACKGROUND = 4.0
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
    line_index : int [lines] or None
        The range columns PGA learnt from; None where it was not applied.
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
    line_index: np.ndarray | None = None

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
        tolerance: float = TOLERANCE, progress: bool = False, aperture_cells: int | None = None,
        max_window: float | None = None) -> tuple[SarImage, AutofocusReport]:
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
    max_window : float, m, optional
        The widest window (> 0): the first iteration's window is the defocused response's extent
        (that of the summed intensity above -:data:`WINDOW_DB` dB and :data:`BACKGROUND` times its
        median, times :data:`WIDEN`) but no wider.

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
    defocus spread over metres is still a Fourier pair of the aperture; each line's spectrum is
    read at the antenna positions of one common grid, whatever its range
    (:func:`~sarmitsuba.focus.pga_deramp.line_spectra`). Other images (omega-K, RDA) are
    processed as they are, which holds for a spotlight image or for targets within a small part
    of one synthetic aperture. The estimate uses only the point-like range lines (eq. (PGA4)):
    clutter, rims and walls spread along a line are left out. A constant phase is not estimated,
    nor, without ``reference``, a linear one (a shift, eq. (PGA5)). Measured
    (benchmarks/trajectory.py, table ``pga``): a 2 cm, 40 m sinusoidal motion error on a 69 m
    airborne X-band aperture, PSLR -39.6 dB after PGA against -39.4 dB on the true track.
    """
    target = reference_azimuth(image, reference)
    found = _estimate(image, max_iterations, tolerance, aperture_cells, max_window, progress, stacklevel=3)
    if not found.report.applied:
        return _with_report(image, image.data, found.report)
    report, data, frame = found.report, found.data, found.frame
    out = _corrected(data, report.phase_error, frame, report.aperture_position, found.r_ref)
    shift = None if target is None else reference_shift(out, image, found.step, target)
    linear = 0.0 if shift is None else shift_phase(data.shape[0], found.step, shift)
    if shift is not None:                         # eq. (PGA5): the same shift on every column
        out = apply_phase(np.fft.fftshift(np.fft.fft(out, axis=0), axes=0), linear)
    if frame is not None:
        out = (out * np.exp(1j * frame.phase))[::frame.factor]
    report = dataclasses.replace(report, linear_shift_m=shift, reference=None if shift is None else tuple(target[1]),
                                 linear_bound_m=None if shift is not None else report.linear_bound_m,
                                 correction=report.phase_error + linear)
    return _with_report(image, out.astype(np.complex64), report)


def pga_estimate(image: SarImage, *, max_iterations: int = MAX_ITERATIONS, tolerance: float = TOLERANCE,
                 aperture_cells: int | None = None, max_window: float | None = None, lines: Any = None,
                 progress: bool = False) -> AutofocusReport:
    """The estimate of :func:`pga` without the corrected image (the rounds through the pulses,
    docs/physics.md (PGA6), need only the estimate): same parameters but ``reference``, same
    checks, warnings and refusals; ``correction`` is ``phase_error``. ``lines`` (int [k], range
    columns), where given, are the lines to learn from instead of the point-like ones (eq. (PGA4)),
    and the image's dominance is not asked for (the caller found them,
    :func:`~sarmitsuba.focus.pga_lines.smeared_lines`): the rounds keep the lines chosen on the
    nominal track's image, so that a wall made to look point-like by a poor first estimate cannot
    join in and drive the next."""
    return _estimate(image, max_iterations, tolerance, aperture_cells, max_window, progress, stacklevel=3,
                     chosen=lines).report


@dataclasses.dataclass(frozen=True)
class _Estimate:
    """What :func:`_estimate` found: the report, the (deramped) data it worked on, the deramp, the
    rows' spacing [m] and the range the spectrum's positions are read at [m]."""

    report: AutofocusReport
    data: np.ndarray
    frame: FresnelFrame | None
    step: float
    r_ref: float


def _estimate(image: SarImage, max_iterations: Any, tolerance: Any, aperture_cells: int | None,
              max_window: Any, progress: bool, stacklevel: int, chosen: Any = None) -> _Estimate:
    """Steps 1-4 of (PGA) on ``image``, deramped where it can be ((PGA2)), on its point-like lines
    ((PGA3), (PGA4)); the refusal (warned) where PGA may not run."""
    data, options = _check(image, max_iterations, tolerance, max_window)
    frame = fresnel_frame(image)
    if frame is not None:
        data = upsample(data, frame.factor) * np.exp(-1j * frame.phase)     # deramped, eq. (PGA2)
    intensity = np.abs(data).astype(np.float64) ** 2
    signal = signal_pixels(intensity)
    dominance = dominance_db(intensity, signal)
    lines = point_lines(intensity, signal, band_occupancy(image.data, doppler_band(image))) if chosen is None \
        else np.asarray(chosen, int)
    step = frame.step if frame is not None else _row_step(image)
    reason, refusal = refusal_of(dominance if chosen is None else np.inf, lines.size)
    if refusal:
        warnings.warn(refusal, AutofocusWarning, stacklevel=stacklevel)
        return _Estimate(_refused(data.shape[0], frame, dominance, lines.size, reason, image), data, frame, step, 0.0)
    r_ref = _reference_range(frame, lines, intensity)
    aperture = None if frame is None else aperture_grid(frame, data.shape[0], r_ref)
    options.update(_track_limits(frame, aperture, aperture_cells, step, options.pop("max_window_m")))
    found = iterate(_line_spectra(data[:, lines], frame, lines, r_ref), options, progress)
    if not found.converged:
        warnings.warn(f"PGA did not converge in {len(found.widths)} iterations (last correction above "
                      f"{options['tolerance']:g} rad rms): the error may vary across the image",
                      AutofocusWarning, stacklevel=stacklevel)
    power = spectral_power(found.centred)
    total = extend_phase(detrend_phase(found.total, found.support, power), found.support)
    report = AutofocusReport(phase_error=total, support=found.support, iterations=len(found.widths),
                             rms_phase_error=weighted_rms(total, found.support, power, RMS_DB),
                             converged=found.converged, lines=int(lines.size), window=found.widths,
                             deramp=frame is not None, dominance_db=dominance, linear_bound_m=_linear_bound(image),
                             correction=total, aperture_position=aperture, line_index=lines)
    return _Estimate(report, data, frame, step, r_ref)


def refusal_of(dominance: float, lines: int) -> tuple[str, str]:
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
            f"a peak >= {POINT_DB:g} dB above the clutter whose response fills >= {POINT_BAND:g} of the beam's "
            f"Doppler band; the double bounce of walls and the rims of plates are extended along the line and fill "
            f"less): the image is returned unchanged. Add a corner reflector, or focus on the true track")
    return "", ""


def _refused(n: int, frame: FresnelFrame | None, dominance: float, lines: int, reason: str,
             image: SarImage) -> AutofocusReport:
    """The report of an image handed back unchanged (``reason`` why)."""
    return AutofocusReport(phase_error=np.zeros(n), support=np.zeros(n, bool), iterations=0, rms_phase_error=0.0,
                           converged=False, lines=lines, window=[], deramp=frame is not None,
                           dominance_db=dominance, applied=False, refusal=reason, linear_bound_m=_linear_bound(image))


def _with_report(image: SarImage, data: np.ndarray, report: AutofocusReport) -> tuple[SarImage, AutofocusReport]:
    metadata = copy.deepcopy(image.metadata)
    metadata["autofocus"] = report.as_metadata()
    return dataclasses.replace(image, data=data, metadata=metadata), report


def _check(image: SarImage, max_iterations: Any, tolerance: Any, max_window: Any) -> tuple[np.ndarray, dict[str, Any]]:
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
    if max_window is not None and not (isinstance(max_window, (int, float)) and np.isfinite(max_window)
                                         and max_window > 0):
        raise ValueError(f"max_window must be a positive width in metres, got {max_window!r}")
    return np.asarray(image.data), kernel_options(max_iterations, tolerance, max_window)


def kernel_options(max_iterations: int = MAX_ITERATIONS, tolerance: float = TOLERANCE,
                   max_window: float | None = None) -> dict[str, Any]:
    """The options of :func:`~sarmitsuba.focus.pga_kernel.iterate` from this module's constants
    (read at the call, so that a changed :data:`SUPPORT_DB` takes effect); ``max_window_m`` [m]."""
    return {"max_iterations": int(max_iterations), "tolerance": float(tolerance), "min_iterations": MIN_ITERATIONS,
            "window_db": WINDOW_DB, "widen": WIDEN, "shrink": SHRINK, "min_window": MIN_WINDOW, "first_floor": FLOOR,
            "support_db": SUPPORT_DB, "rms_db": RMS_DB, "background": BACKGROUND, "max_window_m": max_window}


#: The narrowest window smooths the estimate over no more than its support (the along-track span
#: the used targets were seen from) over this many spectral cells (docs/physics.md (PGA6)). A
#: window cut to a focused point's few samples smooths it over metres, most at the band's ends,
#: where the estimate then stalls (a 60 m sway at -49.5 dB, true track -58.1); 24 cells gave
#: -55.5 dB on a 1.4 cm, 30 m sway where 48 give -58.2 (true track -57.6).
APERTURE_CELLS = 48


def _track_limits(frame: FresnelFrame | None, aperture: np.ndarray | None, cells: int | None,
                  step: float, first_m: float | None) -> dict[str, Any]:
    """``band`` (bool [n] or None), ``cells`` and ``max_window`` [samples] for :func:`iterate`: with a
    deramp, the spectral samples that stand for positions on the track (``|s| <= L / 2`` and one
    cell) and ``cells``, which sets the narrowest window (eq. (PGA6)); without one, no band and no
    floor. ``first_m``, the first window [m], in rows ``step`` [m] apart."""
    limits: dict[str, Any] = {"band": None, "cells": None,
                              "max_window": None if first_m is None else int(np.ceil(first_m / abs(step)))}
    if frame is not None and aperture is not None and frame.length > 0 and aperture.size >= 2:
        cell = float(np.abs(aperture[1] - aperture[0]))        # lambda R0 / (2 n |step|)
        limits.update(band=np.abs(aperture) <= frame.length / 2.0 + cell, cells=cells)
    return limits


def _reference_range(frame: FresnelFrame | None, lines: np.ndarray, intensity: np.ndarray) -> float:
    """The closest-approach range [m] at which the spectral samples are read as antenna positions:
    that of the used ``lines``, weighted by their intensity (eq. (PGA2)); 0 without a deramp."""
    if frame is None:
        return 0.0
    weight = intensity[:, lines].sum(axis=0)
    return float(np.sum(weight * frame.r0[lines]) / weight.sum())


def _line_spectra(lines_data: np.ndarray, frame: FresnelFrame | None, lines: np.ndarray, r_ref: float) -> np.ndarray:
    """The used lines' azimuth spectra, centred order: on the common grid of antenna positions with a
    deramp (:func:`~sarmitsuba.focus.pga_deramp.line_spectra`), else their FFT."""
    if frame is None:
        return np.fft.fftshift(np.fft.fft(lines_data.astype(np.complex128), axis=0), axes=0)
    return line_spectra(lines_data.astype(np.complex128), frame.r0[lines], r_ref)


def _corrected(data: np.ndarray, phase: np.ndarray, frame: FresnelFrame | None, aperture: np.ndarray | None,
               r_ref: float) -> np.ndarray:
    """The image ``data`` [n, n_rg] (deramped where ``frame``) with ``phase`` (centred order) removed from
    every column's spectrum; with a deramp, read at each column's own antenna positions
    (:func:`~sarmitsuba.focus.pga_deramp.column_phase`)."""
    spectrum = np.fft.fftshift(np.fft.fft(data.astype(np.complex128), axis=0), axes=0)
    if frame is None or aperture is None:
        return apply_phase(spectrum, phase)
    return apply_phase(spectrum, column_phase(phase, aperture, frame.r0, r_ref))


def _row_step(image: SarImage) -> float:
    """Azimuth spacing [m, signed] of the image's rows."""
    return float(np.median(np.diff(image.azimuth))) if image.azimuth.size > 1 else 1.0


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
