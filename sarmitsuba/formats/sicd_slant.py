"""The slant-plane SICD grid of a ground-plane image (NGA.STND.0024-1, SICD Volume 1, section "Grid",
``ImagePlane = SLANT``, ``Type = PLANE``; Volume 3, image-to-scene projection; docs/physics.md (GEO4)).

Commercial SICDs of backprojected images are slant-plane grids. sarmitsuba focuses on the ground
(the GeoTIFF keeps that grid); the SICD takes the slant plane at the scene centre point (SCP):

- ``Row/UVectECF`` is the unit line of sight from the antenna at the SCP's centre of aperture
  (COA) to the SCP (slant range, increasing away from the sensor), ``Col/UVectECF`` the
  antenna's velocity there less its part along the line of sight (the plane SICD's
  ``SCPCOA`` slant plane is: spanned by the line of sight and the velocity), signed so that
  ``Row x Col`` points away from the Earth (along the flight looking right, against it looking left);
- each slant-plane pixel shows the ground point that SICD's projection (constant range and range
  rate from the COA antenna position, sarkit's ``r_rdot_to_ground_plane_mono``) gives for it on
  the ground image's plane, so that any SICD reader that projects the pixel to the ground lands
  where the ground image put its scatterer;
- the value there is the ground image's, interpolated as a band-limited signal: the image is
  demodulated by its own carrier (:class:`~sarmitsuba.formats.sicd_resample.Carrier` fitted on the
  ground grid), the baseband interpolated (cubic spline, :func:`scipy.ndimage.map_coordinates`,
  after an exact FFT upsampling by :data:`UPSAMPLE` when the image is small enough) and the
  ground carrier's phase at that ground point put back. The pixels so keep the image's phase,
  and their local spectrum is the aperture's support seen in the slant plane (the ground point
  and the slant-plane point differ along the slant plane's normal, to which the two-way wave
  vector is orthogonal).

Why ``Type = PLANE`` and not ``RGZERO``: an RGZERO grid belongs to ``ImageFormAlgo = RMA`` with
``RMA/INCA`` (time of closest approach, ``DRateSFPoly``, a Doppler centroid tied to
``DeltaKCOAPoly``, ``Col/KCtr = 0``: sarpy's checks), a range/zero-Doppler frame of one
straight track. Backprojection along a circular arc or a measured track has no closest-approach
line, and a PLANE grid in the slant plane is what every SICD reader projects for
``ImageFormAlgo = OTHER``.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ..core import georef
from ..core.image import SarImage
from .sicd_resample import Carrier, flatten, linear_cycles
from .sicd_support import Aperture, SupportError, Track

__all__ = ["slant_frame", "resample_to_slant", "UPSAMPLE", "SlantError"]

#: FFT upsampling of the demodulated ground image before the spline (in both directions).
UPSAMPLE = 2
#: Largest upsampled image (pixels) for which :data:`UPSAMPLE` is applied.
_UPSAMPLE_MAX = 1 << 23
#: Ground pixels kept as a margin between the slant grid's ground footprint and the image's edge.
_MARGIN = 2.0


class SlantError(ValueError):
    """The image admits no slant-plane grid (the line of sight is along the track)."""


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def coa_state(image: SarImage, track: Track, scp: np.ndarray, spotlight: bool) -> tuple[np.ndarray, np.ndarray]:
    """(position [3], velocity [3]) of the antenna (local frame, m, m/s) at the SCP's centre of aperture,
    from the quadratic fit of the track against time that ``Position/ARPPoly`` is."""
    t = float(Aperture(image, track).coa_time(scp, spotlight=spotlight)[0])
    times = track.pulse_time - track.pulse_time[0]
    fit = np.polynomial.polynomial.polyfit(times, track.position, 2 if len(times) > 2 else 1)
    position = np.polynomial.polynomial.polyval(t, fit)
    velocity = np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyder(fit))
    return np.asarray(position, float), np.asarray(velocity, float)


def slant_frame(image: SarImage, track: Track, scp: np.ndarray, spotlight: bool) -> SarImage:
    """A SarImage (pixels zero, complex64) spanning the slant plane at the SCP ``scp`` [3] m (local
    frame) of the ground image ``image``: ``origin`` the SCP, ``range_direction`` the line of sight,
    ``azimuth_direction`` the velocity across it (module docstring), odd axes centred on 0 whose
    ground footprint lies inside ``image`` with a margin of two pixels. Raises SlantError when the
    antenna moves along its line of sight to the SCP."""
    arp, varp = coa_state(image, track, scp, spotlight)
    row = _unit(scp - arp)
    across = varp - (varp @ row) * row
    if not np.linalg.norm(across) > 1e-9 * max(np.linalg.norm(varp), 1e-300):
        raise SlantError("the antenna moves along its line of sight to the scene centre: no slant plane")
    col = _unit(across)
    if np.cross(row, col)[2] < 0:               # Row x Col points away from the Earth (SICD volume 1, Grid):
        col = -col                              # columns along the flight looking right, against it looking left
    d_rg, d_az = float(np.diff(image.range).mean()), float(np.diff(image.azimuth).mean())
    e_rg, e_az = np.asarray(image.range_direction, float), np.asarray(image.azimuth_direction, float)
    origin = np.asarray(image.origin, float)
    ends_rg = np.array([image.range[0], image.range[-1]]) + np.array([1.0, -1.0]) * _MARGIN * d_rg
    ends_az = np.array([image.azimuth[0], image.azimuth[-1]]) + np.array([1.0, -1.0]) * _MARGIN * d_az
    corners = np.array([origin + a * e_az + r * e_rg for a in ends_az for r in ends_rg]) - scp
    half_x = float(np.min(np.abs(corners @ row)))
    half_y = float(np.min(np.abs(corners @ col)))
    step_x = d_rg * abs(float(e_rg @ row))
    n_x, n_y = int(math.floor(half_x / step_x)), int(math.floor(half_y / d_az))
    if n_x < 1 or n_y < 1:
        raise SupportError("the image is too small for a slant-plane SICD grid")
    x = np.arange(-n_x, n_x + 1, dtype=np.float64) * step_x
    y = np.arange(-n_y, n_y + 1, dtype=np.float64) * d_az
    return dataclasses.replace(image, data=np.zeros((y.size, x.size), np.complex64), azimuth=y, range=x,
                               origin=np.asarray(scp, float), azimuth_direction=col, range_direction=row,
                               plane="slant")


def _upsampled(base: np.ndarray, factor: int) -> np.ndarray:
    """``base`` [n, m] (baseband, complex128) on a grid ``factor`` times finer, exactly (its spectrum
    zero-padded; sample ``k`` of the result is at ``k / factor`` of the input's samples)."""
    if factor == 1:
        return base
    from scipy.signal import resample
    out = resample(base, base.shape[0] * factor, axis=0)
    return resample(out, base.shape[1] * factor, axis=1)


def resample_to_slant(image: SarImage, carrier: Carrier, ground_scp: tuple[float, float], tree: Any,
                      rows: np.ndarray, cols: np.ndarray, slant_scp: tuple[float, float],
                      removed: tuple[float, float], ref: georef.GeoReference,
                      gains: tuple = (None, None)) -> np.ndarray:
    """The slant-plane SICD pixels (complex64 [len(rows), len(cols)]) of the ground image ``image``
    (module docstring): ``carrier`` the image's carrier about ``ground_scp`` (range, azimuth) [m],
    ``tree`` the SICD XML (Grid, Position, SCPCOA set) whose grid positions ``rows``, ``cols`` [m]
    about ``slant_scp`` are projected to the ground, ``removed`` the carrier [cycles/m] taken out of
    the SICD pixels (as :func:`~sarmitsuba.formats.sicd_resample.resample`); the demodulated ground
    image's spectrum is first multiplied by ``gains`` (functions of the ground image's range and
    azimuth frequencies, :func:`~sarmitsuba.formats.sicd_resample.flatten`): the weighting taken
    out on the ground, where the image's support and its ``WgtFunct`` are known."""
    import sarkit.sicd.projection as skproj
    from scipy.ndimage import map_coordinates
    params = skproj.MetadataParams.from_xml(tree)
    x_s, y_s = rows - slant_scp[0], cols - slant_scp[1]
    grid = np.stack(np.meshgrid(x_s, y_s, indexing="ij"), axis=-1)
    sets = skproj.compute_projection_sets(params, grid)
    e_rg, e_az = np.asarray(image.range_direction, float), np.asarray(image.azimuth_direction, float)
    normal = np.cross(e_rg, e_az)
    normal = normal if normal[2] >= 0 else -normal
    axes = georef.enu_axes(ref)
    ground = skproj.r_rdot_to_ground_plane_mono(-1 if params.SideOfTrack == "R" else 1, sets,
                                                georef.enu_to_ecef(np.asarray(image.origin, float), ref),
                                                normal @ axes)
    local = georef.ecef_to_enu(ground, ref) - np.asarray(image.origin, float)
    rg, az = local @ e_rg, local @ e_az                                   # [rows, cols] on the image's axes
    x_old, y_old = image.range - ground_scp[0], image.azimuth - ground_scp[1]
    phase = linear_cycles(carrier.kctr, x_old, y_old) + carrier.cycles(x_old, y_old)
    base = image.data.T.astype(np.complex128) * np.exp(-2j * np.pi * phase)      # [n_range, n_azimuth]
    d_rg, d_az = float(np.diff(image.range).mean()), float(np.diff(image.azimuth).mean())
    base = flatten(base, (d_rg, d_az), gains)
    factor = UPSAMPLE if base.size * UPSAMPLE ** 2 <= _UPSAMPLE_MAX else 1
    fine = _upsampled(base, factor)
    where = [factor * (rg - image.range[0]) / d_rg, factor * (az - image.azimuth[0]) / d_az]
    envelope = (map_coordinates(fine.real, where, order=3, mode="constant", cval=0.0)
                + 1j * map_coordinates(fine.imag, where, order=3, mode="constant", cval=0.0))
    x_g, y_g = rg - ground_scp[0], az - ground_scp[1]
    cycles = (np.mod(carrier.kctr[0] * x_g, 1.0) + np.mod(carrier.kctr[1] * y_g, 1.0)
              + np.polynomial.polynomial.polyval2d(x_g, y_g, carrier.phi)
              - np.mod(removed[0] * x_s, 1.0)[:, None] - np.mod(removed[1] * y_s, 1.0)[None, :])
    return np.ascontiguousarray((envelope * np.exp(2j * np.pi * cycles)).astype(np.complex64))
