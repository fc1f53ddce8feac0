"""Point-target analysis of focused images (docs/design.md section 8; procedure of [1]_ and [2]_).

:func:`analyze_point_target` measures a point target's impulse response the way ISCE3
(``isce3.cal.point_target_info``) and the Aresys quality toolkit do:

1. cut a ``chip x chip`` window around the target (re-centred once on the brightest pixel
   near it);
2. estimate the linear phase ramp (spectral centroid) of the chip and remove it, so the
   chip is at baseband. A ground-plane backprojected image carries its carrier as a ramp
   of up to tens of radians per pixel, aliased by the pixel grid; without this step the
   FFT interpolation between pixels would be meaningless;
3. interpolate the baseband chip exactly as a band-limited (periodic) signal: the DFT
   interpolant with the Nyquist bin split symmetrically, evaluated by small matrix
   products at any sub-pixel position (equivalent to ``oversample``-fold FFT zero padding,
   without the ``(chip * oversample)^2`` array), and restore the ramp for phases;
4. locate the peak on the ``oversample``-fold grid, then refine it on the interpolant;
5. take azimuth and range cuts through the peak (sampled every ``1 / oversample`` pixel) and
   measure the -3 dB width (IRW), the first nulls, PSLR and ISLR, the peak magnitude and
   phase, the offset from the prediction, and the integrated energy with clutter removed.

Steps 4 and 5 on the interpolant are in :mod:`sarmitsuba.analysis.cut_metrics`; where a world point
appears (:func:`image_coordinates`, :func:`layover_position`) in :mod:`sarmitsuba.core.image`; the
energy widths and the integrated RCS (:func:`energy_widths`, :func:`integrated_rcs`) in
:mod:`sarmitsuba.analysis.impulse_model`. All are importable from here.

Definitions (every report field carries its unit):

* **IRW**: -3 dB width of ``|I|^2`` along the cut, in metres along the image axis.
* **PSLR**: ``10 log10(max sidelobe / peak)`` of ``|I|^2``, sidelobes outside the first
  nulls (found by a null search: the first local minima either side of the peak) and
  within the ISLR extent below.
* **ISLR (1-D, null-bounded)**: ``10 log10(E_side / E_main)``; ``E_main`` is the energy of
  ``|I|^2`` between the first nulls, ``E_side`` the energy from the first nulls out to
  ``sidelobes`` (default 10) null distances beyond them on each side, or to the chip edge
  when that comes first (ISCE3's ``num_sidelobes`` convention). For an unweighted sinc:
  -10.11 dB at 10 null distances, -9.68 dB for infinite extent
  (:func:`sarmitsuba.focus.windows.islr_theory`).
* **Peak phase**: phase of the ramp-restored interpolant at the peak (ISCE3). Between
  pixels this is only physical when the ramp is the true carrier: an estimated ramp is
  wrapped to ``[-pi, pi)`` per pixel, so pass ``carrier`` (e.g. from :func:`carrier_ramp`)
  for ground-plane backprojected images, or read the phase at a pixel centre.
* **Integrated energy**: ``sum |I|^2 * (pixel area)`` over the pixels within
  ``energy_extent`` first-null distances of the peak on each axis (a box), minus the mean
  clutter power of the four ``chip/8``-square chip corners times the box's pixel count.
  Unit: m^2 times the image's intensity unit (m^2 x m^2 in normalised radiometry).
  **RCS** ``= integrated_energy / (rho_E,az rho_E,rg)``, with ``rho_E`` the energy widths
  ``int |h|^2`` of the unit-peak impulse response along each axis: given as ``resolution``, or
  derived from the image metadata by :func:`energy_widths` (docs/physics.md (K2)), so that the
  same target reads the same RCS whatever the focusing window.
* **Target position**: a world point (3 numbers) is looked for where the focuser puts it,
  :func:`image_coordinates`: at the intersection of its zero-Doppler plane with the image
  plane, at its closest-approach slant range from the straight track (a point above a
  ground-plane image lays over toward the sensor, docs/physics.md (G2)).

References
----------
.. [1] ISCE3, ``python/packages/isce3/cal/point_target_info.py`` (chip, ramp estimate,
   Nyquist split, null search, ``num_sidelobes``).
.. [2] Aresys, ``arepyextras-quality`` point-target analysis documentation (clutter from
   the four chip corners, RCS by the integral method).
.. [3] A. L. Gray, P. W. Vachon, C. E. Livingstone and T. I. Lukowski, "Synthetic aperture
   radar calibration using reference reflectors", IEEE TGRS 28(3), 374-383, 1990
   (integral method).
.. [4] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar Data*,
   Artech House, 2005 (sections 2.6 and 4.5: window broadening, Doppler bandwidth and
   azimuth resolution; section 4.2: zero-Doppler geometry).
.. [5] W. G. Carrara, R. S. Goodman and R. M. Majewski, *Spotlight Synthetic Aperture Radar*,
   Artech House, 1995, appendix D (Taylor weighting).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass
from typing import Any, Sequence

import numpy as np

from ..signal.bandlimited import Interpolant2D
from ..core.constants import SPEED_OF_LIGHT
from .cut_metrics import measure_cut, refine_peak
from ..core.image import SarImage, image_coordinates, layover_position
from .impulse_model import ImpulseModel, energy_widths, integrated_rcs

__all__ = ["PointTargetReport", "analyze_point_target", "carrier_ramp", "image_coordinates", "layover_position",
           "energy_widths", "integrated_rcs", "add_arguments", "run", "main"]


# ============================================================================ report
@dataclass(frozen=True)
class PointTargetReport:
    """Result of :func:`analyze_point_target`. All positions are image coordinates in metres
    along the image axes (``SarImage.azimuth`` / ``SarImage.range``) unless named otherwise.

    Attributes
    ----------
    azimuth, range : float, m
        Peak position (range is ground range for ``plane == "ground"``, slant range for
        ``"slant"``).
    row, column : float
        The same as fractional pixel indices of the image.
    world_position : tuple of 3 floats, m
        ``origin + azimuth * azimuth_direction + range * range_direction`` (the image's
        linear grid model; for a slant image a point of the slant plane).
    plane : str
        ``"ground"`` or ``"slant"``.
    predicted_azimuth, predicted_range : float, m
        Where the peak was expected (``predicted``, else the ``target`` argument).
    azimuth_error, range_error : float, m
        Peak minus predicted position.
    azimuth_error_cells, range_error_cells : float
        Errors in resolution cells (divided by the measured IRW).
    irw_azimuth, irw_range : float, m
        -3 dB impulse-response widths.
    first_null_azimuth, first_null_range : float, m
        Mean distance from the peak to the first nulls (null search).
    pslr_azimuth_db, pslr_range_db : float, dB
        Peak sidelobe ratios (sidelobes outside the first nulls).
    islr_azimuth_nullbounded_db, islr_range_nullbounded_db : float, dB
        1-D ISLR with a null-bounded mainlobe and sidelobes out to ``islr_sidelobes``
        null distances beyond the nulls, or to the chip edge.
    islr_sidelobes : float
        Requested sidelobe extent, in first-null distances.
    islr_extent_azimuth, islr_extent_range : float
        Extent actually integrated (smaller when the chip edge came first).
    peak_magnitude : float
        ``|I|`` at the peak (image units; ``|a|`` for a target of amplitude ``a`` focused
        to unit gain).
    peak_phase_deg : float, deg
        Phase at the peak of the ramp-restored interpolant, in (-180, 180].
    predicted_magnitude : float or None
        ``|I|`` at the predicted position (None when it lies outside the chip).
    predicted_phase_deg : float or None, deg
        Phase of the ramp-restored interpolant at the predicted position: with the true
        carrier this is insensitive to small peak offsets, unlike ``peak_phase_deg``.
    phase_ramp_azimuth, phase_ramp_range : float, rad / pixel
        Linear phase ramp removed before interpolation.
    carrier : str
        ``"estimated"`` (spectral centroid of the chip, wrapped) or ``"given"``.
    integrated_energy : float, m^2 x intensity unit
        Clutter-corrected energy in the box of ``energy_extent`` null distances.
    clutter_level : float, intensity unit
        Mean ``|I|^2`` per pixel in the four chip corners.
    energy_extent : float
        Half-size of the energy box, in first-null distances.
    rcs : float or None, m^2
        ``integrated_energy / (rho_az rho_rg)`` when the energy widths are known (given as
        ``resolution``, or from the image metadata, :func:`energy_widths`).
    rcs_db : float or None, dBsm
        ``10 log10(rcs)``.
    chip, oversample : int
        Chip size [pixels] and oversampling factor used.
    energy_width_azimuth, energy_width_range : float or None, m
        The energy widths ``rho_az``, ``rho_rg`` the RCS was divided by.
    energy_fraction : float or None
        With energy widths from the metadata: the share of the unit-peak response's energy
        inside the integration box (model of :func:`energy_widths`), also divided out, so that
        a rect image's sidelobes beyond the box do not bias its RCS low (None when
        ``resolution`` was given: then nothing is assumed about the response's shape).
    """

    azimuth: float
    range: float
    row: float
    column: float
    world_position: tuple[float, float, float]
    plane: str
    predicted_azimuth: float
    predicted_range: float
    azimuth_error: float
    range_error: float
    azimuth_error_cells: float
    range_error_cells: float
    irw_azimuth: float
    irw_range: float
    first_null_azimuth: float
    first_null_range: float
    pslr_azimuth_db: float
    pslr_range_db: float
    islr_azimuth_nullbounded_db: float
    islr_range_nullbounded_db: float
    islr_sidelobes: float
    islr_extent_azimuth: float
    islr_extent_range: float
    peak_magnitude: float
    peak_phase_deg: float
    predicted_magnitude: float | None
    predicted_phase_deg: float | None
    phase_ramp_azimuth: float
    phase_ramp_range: float
    carrier: str
    integrated_energy: float
    clutter_level: float
    energy_extent: float
    rcs: float | None
    rcs_db: float | None
    chip: int
    oversample: int
    energy_width_azimuth: float | None = None
    energy_width_range: float | None = None
    energy_fraction: float | None = None

    def summary(self) -> str:
        """One line: peak position and error, IRW, PSLR, ISLR (azimuth / range) and RCS."""
        rcs = "n/a" if self.rcs_db is None else f"{self.rcs_db:.1f} dBsm"
        return (f"peak at azimuth {self.azimuth:.2f} m, range {self.range:.2f} m (off by {self.azimuth_error:+.2f}, "
                f"{self.range_error:+.2f} m); IRW {self.irw_azimuth:.2f} / {self.irw_range:.2f} m, PSLR "
                f"{self.pslr_azimuth_db:.1f} / {self.pslr_range_db:.1f} dB, ISLR {self.islr_azimuth_nullbounded_db:.1f}"
                f" / {self.islr_range_nullbounded_db:.1f} dB (azimuth / range); RCS {rcs}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable dict of all fields (floats, ints, strings, lists, None)."""
        out: dict[str, Any] = {}
        for key, value in asdict(self).items():
            if isinstance(value, tuple):
                value = [float(v) for v in value]
            elif isinstance(value, (np.floating, np.integer)):
                value = value.item()
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            out[key] = value
        return out


# ============================================================================ carrier
def _axis_step(name: str, axis: np.ndarray) -> float:
    """Step [m] of the uniformly spaced, increasing image axis ``image.<name>`` (float [n], n >= 2);
    ValueError otherwise."""
    if axis.size < 2:
        raise ValueError(f"image.{name} must have >= 2 samples for point-target analysis, got {axis.size}")
    step = np.diff(axis)
    d = float(step.mean())
    if not np.allclose(step, d, rtol=1e-6, atol=0.0) or d <= 0:
        raise ValueError(f"image.{name} must be uniformly spaced and increasing; steps span "
                         f"[{step.min()!r}, {step.max()!r}] m")
    return d


def carrier_ramp(raw: Any, image: SarImage, point: Sequence[float], *,
                 pulses: np.ndarray | None = None) -> tuple[float, float]:
    """Carrier phase gradient [rad/m] of a backprojected image around a world point.

    A backprojected image of a target at ``X`` is, near ``X``, ``a e(x) exp(j k . (x - X))``
    with ``k = (2 pi fc / c) <grad L_p(X)>`` the pulse-averaged gradient of the two-way
    length, and ``e`` a smooth envelope. Pass the result as ``carrier=`` to
    :func:`analyze_point_target` to read phases between pixels correctly.

    Parameters
    ----------
    raw : RawData
        The data that were focused (``tx_position``, ``rx_position``, ``fc``).
    image : SarImage
        The image (its axis directions).
    point : 3 floats, m
        World position of the target.
    pulses : bool [n_pulses] or index array, optional
        Pulses that contributed (e.g. those in the beam); default all.

    Returns
    -------
    (k_azimuth, k_range) : tuple of float, rad/m
        ``k`` projected on ``image.azimuth_direction`` and ``image.range_direction``.
    """
    x = np.asarray(point, dtype=np.float64).reshape(3)
    tx, rx = raw.tx_position, raw.rx_position
    if pulses is not None:
        tx, rx = tx[pulses], rx[pulses]
    if tx.shape[0] == 0:
        raise ValueError("carrier_ramp: no pulses selected")
    grad = ((x - tx) / np.linalg.norm(x - tx, axis=1)[:, None]
            + (x - rx) / np.linalg.norm(x - rx, axis=1)[:, None]).mean(axis=0)
    k = 2.0 * np.pi * raw.fc / SPEED_OF_LIGHT * grad
    return float(k @ image.azimuth_direction), float(k @ image.range_direction)


# ============================================================================ analysis
def analyze_point_target(image: SarImage, target: Sequence[float] | np.ndarray, *, chip: int = 64,
                         oversample: int = 32, predicted: Sequence[float] | np.ndarray | None = None,
                         resolution: tuple[float, float] | None = None,
                         carrier: tuple[float, float] | None = None, sidelobes: float = 10.0,
                         energy_extent: float = 5.0, search_radius: int | None = None) -> PointTargetReport:
    """Measure a point target's impulse response in a focused image (ISCE3/Aresys practice).

    Parameters
    ----------
    image : SarImage
        Focused image with uniformly spaced axes; ``plane`` ``"slant"`` or ``"ground"``.
    target : 3 floats (world position, m) or 2 floats (azimuth, range image coordinates, m)
        Where to cut the chip: a world point at its position in the image,
        :func:`image_coordinates` (its layover position when the metadata record the track).
        The chip is re-centred on the brightest pixel within ``search_radius`` pixels of it.
    chip : int, default 64
        Chip size in pixels (both axes), even, in [16, 1024]; the chip must fit in the
        image (a target nearer than ``chip / 2`` pixels to an edge is an error).
    oversample : int, default 32
        Sampling of the cuts and of the coarse peak grid, per pixel; in [4, 1024].
    predicted : 3 or 2 floats, optional
        Expected peak position (world, or image coordinates); default ``target``.
    resolution : (float, float), m, optional
        ``(rho_az, rho_rg)``: impulse-response energy widths ``int |h|^2`` of the unit-peak
        response along each image axis (rect spectrum: the reciprocal bandwidths,
        ``c / (2 B)`` in slant range, ``/ sin(incidence)`` in ground range; with a window,
        times :func:`sarmitsuba.focus.windows.energy_width`). Default: from the image
        metadata at the peak (:func:`energy_widths`), when it records the focusing; else no
        ``rcs``; the energy outside the integration box is then also restored
        (``energy_fraction``).
    carrier : (float, float), rad/m, optional
        True linear phase gradient of the image along (azimuth, range) near the target,
        e.g. :func:`carrier_ramp` for a backprojected image. Default: estimated from the
        chip (spectral centroid, wrapped to one pixel).
    sidelobes : float, default 10
        ISLR/PSLR sidelobe extent beyond each first null, in first-null distances.
    energy_extent : float, default 5
        Half-size of the energy integration box, in first-null distances (1 = mainlobe
        only; 5 = the Aresys "side area" of about +-5 resolutions).
    search_radius : int, optional
        Pixels around ``target`` searched for the brightest pixel; default ``chip // 4``.

    Returns
    -------
    PointTargetReport

    Raises
    ------
    ValueError
        On a bad argument, non-uniform axes, a chip that does not fit, a zero chip, or a
        response with no null inside the chip.

    Notes
    -----
    Cost: one ``chip x chip`` FFT and a few hundred small matrix-vector products; about
    10 ms for the defaults.

    Examples
    --------
    >>> report = analyze_point_target(image, (0.0, 0.0, 0.0))  # doctest: +SKIP
    >>> report.irw_range, report.pslr_range_db  # doctest: +SKIP
    """
    if not isinstance(image, SarImage):
        raise ValueError(f"image must be a sarmitsuba.core.image.SarImage, got {type(image).__name__}")
    chip, ov, sidelobes, energy_extent, radius = _checked_options(chip, oversample, sidelobes, energy_extent,
                                                                  search_radius)
    d_az = _axis_step("azimuth", image.azimuth)
    d_rg = _axis_step("range", image.range)
    (row_t, col_t), (pred_az, pred_rg) = _target_pixel(image, target, predicted, d_az, d_rg)
    i0, j0, z = _cut_chip(image, row_t, col_t, chip, radius)
    (w_az, w_rg), carrier_source = _phase_ramp(z, carrier, d_az, d_rg)
    interp = _baseband_interpolant(z, w_az, w_rg)
    u_pk, v_pk = _locate_peak(interp, chip, ov)
    peak = _ramp_restored(interp, w_az, w_rg, u_pk, v_pk)
    m_az = measure_cut(interp, 0, u_pk, v_pk, peak, chip, ov, sidelobes)
    m_rg = measure_cut(interp, 1, v_pk, u_pk, peak, chip, ov, sidelobes)
    u_pred, v_pred = (pred_az - image.azimuth[0]) / d_az - i0, (pred_rg - image.range[0]) / d_rg - j0
    inside = 0 <= u_pred <= chip - 1 and 0 <= v_pred <= chip - 1             # the value at the prediction
    at_pred = _ramp_restored(interp, w_az, w_rg, u_pred, v_pred) if inside else None
    energy, clutter, box = _integrated_energy(image, z, (u_pk, v_pk), (m_az.null, m_rg.null), energy_extent,
                                              d_az, d_rg)
    row, col = i0 + u_pk, j0 + v_pk
    az = float(image.azimuth[0] + row * d_az)
    rg = float(image.range[0] + col * d_rg)
    rcs, rcs_db, rho, fraction = _rcs(image, resolution, (az, rg), energy, box, d_az, d_rg)
    world = image.origin + az * image.azimuth_direction + rg * image.range_direction
    irw_az, irw_rg = m_az.irw * d_az, m_rg.irw * d_rg
    return PointTargetReport(
        azimuth=az, range=rg, row=float(row), column=float(col),
        world_position=tuple(float(x) for x in world), plane=image.plane,
        predicted_azimuth=float(pred_az), predicted_range=float(pred_rg),
        azimuth_error=az - pred_az, range_error=rg - pred_rg,
        azimuth_error_cells=(az - pred_az) / irw_az, range_error_cells=(rg - pred_rg) / irw_rg,
        irw_azimuth=irw_az, irw_range=irw_rg,
        first_null_azimuth=m_az.null * d_az, first_null_range=m_rg.null * d_rg,
        pslr_azimuth_db=m_az.pslr_db, pslr_range_db=m_rg.pslr_db,
        islr_azimuth_nullbounded_db=m_az.islr_db, islr_range_nullbounded_db=m_rg.islr_db,
        islr_sidelobes=sidelobes, islr_extent_azimuth=m_az.extent, islr_extent_range=m_rg.extent,
        peak_magnitude=abs(peak), peak_phase_deg=float(np.degrees(np.angle(peak))),
        predicted_magnitude=None if at_pred is None else abs(at_pred),
        predicted_phase_deg=None if at_pred is None else float(np.degrees(np.angle(at_pred))),
        phase_ramp_azimuth=w_az, phase_ramp_range=w_rg, carrier=carrier_source,
        integrated_energy=energy, clutter_level=clutter, energy_extent=energy_extent,
        rcs=rcs, rcs_db=rcs_db, chip=chip, oversample=ov,
        energy_width_azimuth=None if rho is None else float(rho[0]),
        energy_width_range=None if rho is None else float(rho[1]), energy_fraction=fraction)


def _checked_options(chip: Any, oversample: Any, sidelobes: Any, energy_extent: Any,
                     search_radius: Any) -> tuple[int, int, float, float, int]:
    """The validated (chip, oversample, sidelobes, energy_extent, search radius) of :func:`analyze_point_target`."""
    chip = _int_in("chip", chip, 16, 1024)
    if chip % 2:
        raise ValueError(f"chip must be even (Nyquist-bin split of the interpolant), got {chip}")
    ov = _int_in("oversample", oversample, 4, 1024)
    sidelobes = _float_in("sidelobes", sidelobes, 0.0, 1e3, open_low=True)
    energy_extent = _float_in("energy_extent", energy_extent, 0.0, 1e3, open_low=True)
    radius = chip // 4 if search_radius is None else _int_in("search_radius", search_radius, 0, chip // 2)
    return chip, ov, sidelobes, energy_extent, radius


def _target_pixel(image: SarImage, target: Any, predicted: Any, d_az: float,
                  d_rg: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """Step 0: the target's fractional (row, column), and the predicted (azimuth, range) [m]."""
    n_az, n_rg = image.data.shape
    az0, rg0 = image_coordinates(image, target)
    pred_az, pred_rg = (az0, rg0) if predicted is None else image_coordinates(image, predicted)
    row_t = (az0 - image.azimuth[0]) / d_az
    col_t = (rg0 - image.range[0]) / d_rg
    if not (0 <= row_t <= n_az - 1 and 0 <= col_t <= n_rg - 1):
        raise ValueError(f"target at image coordinates ({az0:.3f}, {rg0:.3f}) m lies outside the image "
                         f"(azimuth [{image.azimuth[0]:.3f}, {image.azimuth[-1]:.3f}] m, range "
                         f"[{image.range[0]:.3f}, {image.range[-1]:.3f}] m)")
    return (row_t, col_t), (pred_az, pred_rg)


def _cut_chip(image: SarImage, row_t: float, col_t: float, chip: int,
              radius: int) -> tuple[int, int, np.ndarray]:
    """Step 1: the ``chip x chip`` window (complex128) centred on the brightest pixel within
    ``radius`` pixels of the target, and its first (row, column)."""
    n_az, n_rg = image.data.shape
    r, c = int(round(row_t)), int(round(col_t))
    r_lo, r_hi = max(0, r - radius), min(n_az, r + radius + 1)
    c_lo, c_hi = max(0, c - radius), min(n_rg, c + radius + 1)
    window = np.abs(image.data[r_lo:r_hi, c_lo:c_hi])
    if not np.any(window):
        raise ValueError(f"the image is zero within {radius} pixels of the target: nothing to analyse")
    i, j = np.unravel_index(int(np.argmax(window)), window.shape)
    r, c = r_lo + int(i), c_lo + int(j)
    i0, j0 = r - chip // 2, c - chip // 2
    if i0 < 0 or j0 < 0 or i0 + chip > n_az or j0 + chip > n_rg:
        raise ValueError(f"the target peak at pixel ({r}, {c}) is closer than chip/2 = {chip // 2} pixels to the "
                         f"edge of the {n_az} x {n_rg} image; reduce chip or enlarge the image")
    return i0, j0, image.data[i0:i0 + chip, j0:j0 + chip].astype(np.complex128)


def _phase_ramp(z: np.ndarray, carrier: Any, d_az: float, d_rg: float) -> tuple[tuple[float, float], str]:
    """Step 2: the linear phase ramp [rad / pixel] of the chip along (azimuth, range): the spectral
    centroid (lag-one correlation phase, wrapped) or the given ``carrier`` [rad/m]; and its source."""
    if carrier is None:
        w_az = float(np.angle(np.sum(z[1:, :] * np.conj(z[:-1, :]))))
        w_rg = float(np.angle(np.sum(z[:, 1:] * np.conj(z[:, :-1]))))
        return (w_az, w_rg), "estimated"
    k = np.asarray(carrier, dtype=np.float64).reshape(-1)
    if k.shape != (2,) or not np.all(np.isfinite(k)):
        raise ValueError(f"carrier must be 2 finite numbers (k_azimuth, k_range) in rad/m, got {carrier!r}")
    return (float(k[0] * d_az), float(k[1] * d_rg)), "given"


def _baseband_interpolant(z: np.ndarray, w_az: float, w_rg: float) -> Interpolant2D:
    """Step 3: the band-limited interpolant of the chip with its phase ramp removed."""
    n = np.arange(z.shape[0], dtype=np.float64)
    return Interpolant2D(z * np.exp(-1j * (w_az * n[:, None] + w_rg * n[None, :])))


def _ramp_restored(interp: Interpolant2D, w_az: float, w_rg: float, u: float, v: float) -> complex:
    """Image value at chip-local fractional pixel ``(u, v)``: the interpolant times the ramp."""
    return complex(interp(u, v)[0, 0]) * np.exp(1j * (w_az * u + w_rg * v))


def _locate_peak(interp: Interpolant2D, chip: int, ov: int) -> tuple[float, float]:
    """Step 4: the peak on the ``ov``-fold grid +-2 pixels about the chip centre, then refined."""
    pr, pc = chip // 2, chip // 2
    fine = np.arange(-2 * ov, 2 * ov + 1) / ov
    grid = np.abs(interp(pr + fine, pc + fine))
    a, b = np.unravel_index(int(np.argmax(grid)), grid.shape)
    return refine_peak(interp, pr + fine[a], pc + fine[b], 1.0 / ov)


def _integrated_energy(image: SarImage, z: np.ndarray, peak: tuple[float, float], nulls: tuple[float, float],
                       energy_extent: float, d_az: float, d_rg: float) -> tuple[float, float, np.ndarray]:
    """Step 6: (energy [m^2 x intensity], clutter [intensity / pixel], box bool [chip, chip]):
    ``sum |I|^2 dA`` over the box of ``energy_extent`` null distances about the peak, minus the
    mean power of the four ``chip/8`` corners per box pixel (integral method, Gray et al. 1990)."""
    n = np.arange(z.shape[0], dtype=np.float64)
    power = np.abs(z) ** 2
    corner = max(2, z.shape[0] // 8)
    clutter = float(np.mean(np.concatenate([
        power[:corner, :corner].ravel(), power[:corner, -corner:].ravel(),
        power[-corner:, :corner].ravel(), power[-corner:, -corner:].ravel()])))
    box = ((np.abs(n - peak[0]) <= energy_extent * nulls[0])[:, None]
           & (np.abs(n - peak[1]) <= energy_extent * nulls[1])[None, :])
    pixel_area = d_az * d_rg * float(np.linalg.norm(np.cross(image.azimuth_direction, image.range_direction)))
    return float((power[box].sum() - clutter * box.sum()) * pixel_area), clutter, box


def _rcs(image: SarImage, resolution: Any, position: tuple[float, float], energy: float, box: np.ndarray,
         d_az: float, d_rg: float) -> tuple[float | None, float | None, np.ndarray | None, float | None]:
    """Step 7: (rcs [m^2], rcs [dBsm], energy widths [2] m, energy fraction): the energy over the
    energy widths, given or from the metadata at ``position`` (then also over the box's share)."""
    rcs = rcs_db = fraction = None
    rho = None
    if resolution is not None:
        rho = np.asarray(resolution, dtype=np.float64).reshape(-1)
        if rho.shape != (2,) or not np.all(np.isfinite(rho)) or np.any(rho <= 0):
            raise ValueError(f"resolution must be 2 positive numbers (rho_az, rho_rg) in m, got {resolution!r}")
    else:
        try:
            model = ImpulseModel(image, position)
        except ValueError:
            model = None
        if model is not None:
            rho = np.array([model.rho_az, model.rho_rg])
            fraction = model.fraction(0.5 * box.any(axis=1).sum() * d_az, 0.5 * box.any(axis=0).sum() * d_rg)
    if rho is not None:
        rcs = energy / float(rho[0] * rho[1] * (fraction or 1.0))
        rcs_db = 10.0 * math.log10(rcs) if rcs > 0 else None
    return rcs, rcs_db, rho, fraction


def _int_in(name: str, value: Any, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def _float_in(name: str, value: Any, low: float, high: float, open_low: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    ok = np.isfinite(v) and (v > low if open_low else v >= low) and v <= high
    if not ok:
        bracket = "(" if open_low else "["
        raise ValueError(f"{name} must be a number in {bracket}{low}, {high}], got {value!r}")
    return v


# ============================================================================ command line
def _floats(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.replace(" ", "").split(",") if x]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    return values


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the ``analyze`` arguments to ``parser`` (a sub-command parser); returns it."""
    parser.add_argument("image", help="focused image: .npz (image.npz, written by SarImage.save) or SICD NITF "
                                      "(.nitf/.ntf, such as the image.nitf of render --sicd)")
    parser.add_argument("--target", default=None, type=_floats, metavar="X,Y,Z|AZ,RG",
                        help="target: world position [m] (looked for at its layover position in the image) or "
                             "image coordinates (azimuth, range) [m]; write --target=-1,2,0 when the first value "
                             "is negative")
    parser.add_argument("--predicted", type=_floats, default=None, metavar="X,Y,Z|AZ,RG",
                        help="expected peak position (default: the target)")
    parser.add_argument("--chip", type=int, default=64, help="chip size in pixels (even; default 64)")
    parser.add_argument("--oversample", type=int, default=32, help="cut sampling per pixel (default 32)")
    parser.add_argument("--resolution", type=_floats, default=None, metavar="RHO_AZ,RHO_RG",
                        help="impulse-response energy widths [m] along the image axes for the RCS (default: from "
                             "the image metadata: bandwidth, windows, antenna pattern, geometry)")
    parser.add_argument("--carrier", type=_floats, default=None, metavar="K_AZ,K_RG",
                        help="true carrier phase gradient [rad/m] (default: estimated from the chip)")
    parser.add_argument("--sidelobes", type=float, default=10.0,
                        help="ISLR/PSLR sidelobe extent in first-null distances (default 10)")
    parser.add_argument("--energy-extent", type=float, default=5.0,
                        help="energy box half-size in first-null distances (default 5)")
    return parser


def run(args: argparse.Namespace, figure=None) -> int:
    """Analyse ``args.image`` and print the report as JSON; returns the exit code (0, or 2 on bad input).

    ``figure``, if given, is called as ``figure(image, report)`` after a successful analysis.
    """
    from ..core.image import SarImageError
    from ..formats.sicd import load_image
    try:
        image = load_image(args.image)
        report = analyze_point_target(
            image, args.target, chip=args.chip, oversample=args.oversample, predicted=args.predicted,
            resolution=None if args.resolution is None else tuple(args.resolution),
            carrier=None if args.carrier is None else tuple(args.carrier),
            sidelobes=args.sidelobes, energy_extent=args.energy_extent)
    except (SarImageError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(report.to_dict(), indent=2))
    if figure is not None:
        figure(image, report)
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m sarmitsuba.analysis.point_target IMAGE.npz --target X,Y,Z``: print the report as JSON."""
    parser = add_arguments(argparse.ArgumentParser(prog="sarmitsuba analyze",
                                                   description="point-target analysis of a focused image"))
    return run(parser.parse_args(argv))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
