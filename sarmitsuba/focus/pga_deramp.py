"""The deramp of a backprojected image for phase gradient autofocus, and the antenna positions its
azimuth spectrum stands for (docs/physics.md (PGA2)).

A backprojected image multiplied by ``exp(-j k (x - x_ref)^2 / R0)`` has, on every range line, an
azimuth spectrum indexed by the antenna's along-track position: sample ``f`` [cycles/m] stands for
``s = -f lambda R0 / 2`` (:func:`fresnel_frame`). ``R0`` is the line's own closest-approach range,
so the same position falls on different samples of lines at different ranges: across a swath whose
``R0`` varies by 10 %, a sway's phase at 150 m from mid-aperture lands 15 m apart on the near and
the far lines. :func:`line_spectra` therefore evaluates every line's spectrum at the frequencies of
one common grid of positions (a chirp-z transform per line), and :func:`column_phase` reads a phase
given on that grid at each column's own frequencies.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage

__all__ = ["FresnelFrame", "fresnel_frame", "aperture_grid", "line_spectra", "column_phase", "MAX_UPSAMPLE",
           "BAND_MARGIN"]

#: Largest azimuth upsampling for the deramp (beyond it PGA runs on the image as it is, and the
#: spectrum cannot be read as antenna positions).
MAX_UPSAMPLE = 16
#: The deramped band's sampling margin: the upsampled rows hold ``BAND_MARGIN`` times the band.
BAND_MARGIN = 1.1


@dataclasses.dataclass(frozen=True)
class FresnelFrame:
    """The deramp of a backprojected image (docs/physics.md (PGA2)).

    Attributes
    ----------
    factor : int
        Azimuth upsampling.
    phase : float64 [n_az * factor, n_rg], rad
        ``k x^2 / R0`` of every upsampled pixel (``x`` along track from mid-aperture).
    r0 : float64 [n_rg], m
        Each range column's closest-approach range from the track.
    step : float, m
        Signed spacing of the upsampled rows along the image's azimuth axis.
    sense : float
        +1 where the image's azimuth axis runs along the track's direction, else -1.
    wavelength : float, m
    length : float, m
        The track's length (0 where the metadata do not record it).
    offset : float64 [n_rg], m
        Each column's along-track coordinate at azimuth 0, from mid-aperture.
    rows : float64 [n_az * factor], m
        Each upsampled row's along-track coordinate less the column's ``offset``: pixel ``(i, c)``
        lies at ``offset[c] + rows[i]`` along the track.
    """

    factor: int
    phase: np.ndarray
    r0: np.ndarray
    step: float
    sense: float
    wavelength: float
    length: float
    offset: np.ndarray
    rows: np.ndarray


def fresnel_frame(image: SarImage) -> FresnelFrame | None:
    """The deramp of a backprojected image (``metadata["focus"]["track"]``: mid-aperture position,
    direction and length of the straight track, and ``fc``), or None for other images and for an
    image whose sampling would need more than :data:`MAX_UPSAMPLE`.

    The deramped spectrum of a line at closest-approach range ``R0`` spans the antenna positions
    along the track, ``2 L / (lambda R0)`` cycles per metre for a track ``L`` long (the image's own
    extent where no length is recorded), which the upsampled rows hold with :data:`BAND_MARGIN` to
    spare at the nearest column (docs/physics.md (PGA2))."""
    focus = image.metadata.get("focus") if isinstance(image.metadata, dict) else None
    track = focus.get("track") if isinstance(focus, dict) else None
    if not (isinstance(track, dict) and track.get("direction") is not None and focus.get("fc")):
        return None
    position, direction = np.asarray(track["position"], float), np.asarray(track["direction"], float)
    wavelength = SPEED_OF_LIGHT / float(focus["fc"])
    k = 2.0 * np.pi / wavelength
    columns = image.origin + image.range[:, None] * image.range_direction - position        # [n_rg, 3]
    r0 = np.linalg.norm(columns - np.outer(columns @ direction, direction), axis=1)
    step = float(np.median(np.diff(image.azimuth))) if image.azimuth.size > 1 else 0.0
    length = float(track.get("length", 0.0) or 0.0)
    extent = length if length > 0 else float(np.ptp(image.azimuth))
    if not (step != 0 and np.all(r0 > 0) and extent > 0):
        return None
    factor = max(1, int(np.ceil(BAND_MARGIN * 2.0 * extent / (wavelength * float(r0.min())) * abs(step))))
    if factor > MAX_UPSAMPLE:
        return None
    rows = (image.azimuth[0] + step / factor * np.arange(image.azimuth.size * factor)) \
        * float(image.azimuth_direction @ direction)
    along = (columns @ direction)[None, :] + rows[:, None]
    sense = float(np.sign(image.azimuth_direction @ direction) or 1.0)
    return FresnelFrame(factor, k * along ** 2 / r0[None, :], r0, step / factor, sense, wavelength, length,
                        columns @ direction, rows)


def aperture_grid(frame: FresnelFrame, n: int, r_ref: float) -> np.ndarray:
    """float64 [n], m: the along-track antenna position, from mid-aperture, that each sample of an
    ``n``-sample deramped spectrum (centred order) stands for at closest-approach range ``r_ref``:
    ``-f lambda R0 / 2`` times the sense of the azimuth axis (eq. (PGA2))."""
    f = np.fft.fftshift(np.fft.fftfreq(n, d=frame.step))
    return -frame.sense * f * frame.wavelength * r_ref / 2.0


def line_spectra(lines: np.ndarray, r0: np.ndarray, r_ref: float) -> np.ndarray:
    """complex128 [n, m]: the azimuth spectra (centred order) of the deramped ``lines`` [n, m] (rows
    along azimuth), line ``j`` evaluated at the frequencies ``f r_ref / r0[j]`` so that every line's
    sample ``i`` stands for the same antenna position (:func:`aperture_grid` at ``r_ref``): a
    chirp-z transform per line (scipy.signal.czt); ``numpy.fft.fft`` where ``r0[j] == r_ref``."""
    from scipy.signal import czt
    n = lines.shape[0]
    out = np.empty(lines.shape, complex)
    for j in range(lines.shape[1]):
        rho = float(r_ref) / float(r0[j])
        if rho == 1.0:
            out[:, j] = np.fft.fftshift(np.fft.fft(lines[:, j]))
            continue
        w = np.exp(-2j * np.pi * rho / n)
        a = np.exp(-2j * np.pi * rho * (n // 2) / n)
        out[:, j] = czt(lines[:, j], m=n, w=w, a=a)
    return out


def column_phase(phase: np.ndarray, positions: np.ndarray, r0: np.ndarray, r_ref: float) -> np.ndarray:
    """float64 [n, n_rg], rad: ``phase`` [n], given at the antenna ``positions`` [n] of the grid at
    ``r_ref`` (:func:`aperture_grid`, centred order), read at the positions each column's own
    spectral samples stand for, ``positions r0 / r_ref`` (linear interpolation, held at the ends)."""
    order = np.argsort(positions)
    s, p = positions[order], phase[order]
    return np.stack([np.interp(positions * (float(r) / float(r_ref)), s, p) for r in r0], axis=1)
