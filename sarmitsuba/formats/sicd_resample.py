"""The SICD grid of an image: spacings that sample the impulse response 1.1 to 2.2 times, and the
complex image resampled onto it with its carrier (NGA.STND.0024-1, SICD Volume 1, section "Grid":
``SS``, ``DeltaK1``/``DeltaK2``, ``DeltaKCOAPoly``; docs/physics.md (S3), (K)).

**Spacings.** SICD advises an oversampling ratio ``1 / (SS ImpRespBW)`` of 1.1 to 2.2; the grid
here samples about :data:`OVERSAMPLING` (2) times in both directions (the upper side keeps more of
the image's pixels for a point-target chip). Among the spacings within 1.15 to 2.15 times, the one
nearest that which makes ``KCtr SS`` an integer is taken, so that the carrier at the scene centre
point (SCP) is 1 on every sample and the pixels can keep the image's own phase.

**Carrier.** A backprojected image carries its carrier: near ``x`` it is ``B(x) exp(j psi(x))`` with
``B`` band limited to ``+-ImpRespBW / 2`` about 0 and ``grad psi / 2 pi`` the centre of the local
support (:class:`sarmitsuba.formats.sicd_support.Aperture`), which drifts across the image (the
incidence angle changes over the swath, the track cuts the beam at the image's ends). With
``x, y`` the row (range) and column (azimuth) coordinates from the SCP [m],

    psi(x, y) = 2 pi (KCtr_row x + KCtr_col y + Phi(x, y)),

``Phi`` a polynomial (degree :data:`PHI_DEGREE`) fitted so that its gradient is the local centre
minus ``KCtr`` on a lattice of points over the image. FFT focusers' images are at baseband:
``Phi`` is then linear, their mean spectral centre. The image is demodulated by ``exp(-j psi)``,
interpolated exactly as a band-limited signal (:func:`sarmitsuba.signal.bandlimited.dft_rows`, the
spectrum cut to the new grid's Nyquist band) and modulated again, so a sample of the SICD is the
image's own value there. The SICD pixels are that image times ``exp(-j 2 pi f . (x, y))``, with
``f = KCtr - round(KCtr SS) / SS`` (zero where ``KCtr SS`` is an integer): the carrier SICD takes
as removed. Their local spectrum is then centred at ``grad Phi`` (less a whole number of
``1 / SS``): ``DeltaKCOAPoly``; ``DeltaK1``/``DeltaK2`` are its extremes over the image's corners
-+ ``ImpRespBW / 2`` (the whole band ``+-1 / (2 SS)`` where the support wraps), as SICD and
sarkit's ``sicdcheck`` compute them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.image import SarImage
from ..signal.bandlimited import dft_rows

__all__ = ["OVERSAMPLING", "PHI_DEGREE", "sicd_spacing", "centred_axis", "Carrier", "fit_carrier",
           "data_carrier", "resample", "flatten", "linear_cycles", "deltak_limits", "poly2d_gradient", "ResampleError"]

#: Oversampling ratio ``1 / (SS ImpRespBW)`` aimed at (SICD advises 1.1 to 2.2).
OVERSAMPLING = 2.0
#: Oversampling ratios a spacing that makes ``KCtr SS`` an integer may give.
_OSR_RANGE = (1.15, 2.15)
#: Degree of the carrier polynomial ``Phi`` (its gradient, ``DeltaKCOAPoly``, one less).
PHI_DEGREE = 3
#: Output positions interpolated at once (bounds the interpolation matrices' memory).
_BLOCK = 1024
#: Blocks along an axis whose spectral centres :func:`flatten` fits a line through.
_CENTRE_BLOCKS = 8


class ResampleError(ValueError):
    """The image cannot be put on a SICD grid (too small, or a zero bandwidth)."""


def sicd_spacing(bandwidth: float, kctr: float) -> float:
    """Sample spacing [m] that samples a support of ``bandwidth`` [cycles/m] about
    :data:`OVERSAMPLING` times, ``m / |kctr|`` for the integer ``m`` nearest that when one gives an
    oversampling ratio within 1.15 to 2.15. Raises ResampleError for a bandwidth that is not positive."""
    if not (math.isfinite(bandwidth) and bandwidth > 0):
        raise ResampleError(f"the impulse-response bandwidth is {bandwidth!r} cycles/m: no SICD grid samples it")
    ideal = 1.0 / (OVERSAMPLING * bandwidth)
    k = abs(float(kctr))
    if k == 0.0:
        return ideal
    low, high = math.ceil(k / (_OSR_RANGE[1] * bandwidth)), math.floor(k / (_OSR_RANGE[0] * bandwidth))
    candidates = [m for m in range(max(low, 1), high + 1)]
    return min((m / k for m in candidates), key=lambda s: abs(s - ideal)) if candidates else ideal


def centred_axis(axis: np.ndarray, centre: float, spacing: float) -> np.ndarray:
    """Uniform axis of ``spacing`` through ``centre`` (float64 [2h + 1], centre in the middle), as long as
    ``axis`` (increasing, float [n]) holds it on both sides. Raises ResampleError when fewer than 3 fit."""
    half = int(math.floor(min(centre - axis[0], axis[-1] - centre) / spacing + 1e-9))
    if half < 1:
        raise ResampleError(f"the image is {axis[-1] - axis[0]:.3g} m long: too short for a SICD grid of "
                            f"{spacing:.3g} m spacing")
    return centre + np.arange(-half, half + 1, dtype=np.float64) * spacing


def poly2d_gradient(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d/dx, d/dy) of the Poly2D ``phi`` (coefficients ``[i, j]`` of ``x^i y^j``), same shape."""
    dx, dy = np.zeros_like(phi), np.zeros_like(phi)
    i, j = np.arange(phi.shape[0])[:, None], np.arange(phi.shape[1])[None, :]
    dx[:-1, :] = (phi * i)[1:, :]
    dy[:, :-1] = (phi * j)[:, 1:]
    return dx, dy


@dataclass(frozen=True)
class Carrier:
    """The carrier of an image on its own plane, with ``x, y`` the row (range) and column (azimuth)
    coordinates [m] from the SCP: ``kctr`` (row, col) [cycles/m] and ``phi`` (Poly2D coefficients
    [D + 1, D + 1], cycles) so that the phase is ``2 pi (kctr . (x, y) + Phi(x, y))``."""

    kctr: tuple[float, float]
    phi: np.ndarray

    def cycles(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``Phi(x, y)`` [cycles] on the grid ``x`` [n] x ``y`` [m] (float64 [n, m])."""
        return np.polynomial.polynomial.polygrid2d(x, y, self.phi)


def fit_carrier(kctr: tuple[float, float], x: np.ndarray, y: np.ndarray, centre_row: np.ndarray,
                centre_col: np.ndarray) -> Carrier:
    """The :class:`Carrier` whose ``Phi`` has the gradient nearest (least squares) to the local support
    centres ``centre_row``, ``centre_col`` [cycles/m] minus ``kctr`` at the points ``x``, ``y`` [m]
    (float [n] each)."""
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    scale = max(float(np.max(np.abs(np.concatenate([x, y])))), 1e-9)
    u, v = x / scale, y / scale
    terms = [(i, j) for i in range(PHI_DEGREE + 1) for j in range(PHI_DEGREE + 1 - i) if i + j > 0]
    d_u = np.stack([i * u ** max(i - 1, 0) * v ** j for i, j in terms], axis=1)
    d_v = np.stack([j * u ** i * v ** max(j - 1, 0) for i, j in terms], axis=1)
    target = np.concatenate([np.ravel(centre_row) - kctr[0], np.ravel(centre_col) - kctr[1]]) * scale
    coefficients = np.linalg.lstsq(np.vstack([d_u, d_v]), target, rcond=None)[0]
    phi = np.zeros((PHI_DEGREE + 1, PHI_DEGREE + 1))
    for (i, j), c in zip(terms, coefficients):
        phi[i, j] = c / scale ** (i + j)
    return Carrier((float(kctr[0]), float(kctr[1])), phi)


def data_carrier(image: SarImage, kctr: tuple[float, float]) -> Carrier:
    """The :class:`Carrier` of an image at baseband (FFT focusers): ``Phi`` linear, the mean spectral
    centre of the data (lag-one correlation phase along each axis, within its Nyquist band) minus ``kctr``."""
    z = image.data.astype(np.complex128)
    d_rg, d_az = float(np.diff(image.range).mean()), float(np.diff(image.azimuth).mean())
    f_rg = float(np.angle(np.sum(z[:, 1:] * np.conj(z[:, :-1])))) / (2.0 * np.pi * d_rg)
    f_az = float(np.angle(np.sum(z[1:, :] * np.conj(z[:-1, :])))) / (2.0 * np.pi * d_az)
    phi = np.zeros((PHI_DEGREE + 1, PHI_DEGREE + 1))
    phi[1, 0], phi[0, 1] = f_rg - kctr[0], f_az - kctr[1]
    return Carrier((float(kctr[0]), float(kctr[1])), phi)


def _interpolate(samples: np.ndarray, axis: int, step: float, positions: np.ndarray, cutoff: float) -> np.ndarray:
    """Band-limited values of ``samples`` (complex [.., n, ..], spacing ``step`` [m] along ``axis``, the
    first at 0) at ``positions`` [m], the spectrum cut to ``|f| <= cutoff`` [cycles/m]."""
    n = samples.shape[axis]
    keep = np.abs(np.fft.fftfreq(n, step)) <= cutoff * (1.0 + 1e-9)
    spectrum = np.moveaxis(np.fft.fft(samples, axis=axis), axis, 0) * keep[:, None]
    out = np.empty((positions.size, spectrum.shape[1]), dtype=np.complex128)
    for start in range(0, positions.size, _BLOCK):
        out[start:start + _BLOCK] = dft_rows(n, positions[start:start + _BLOCK] / step) @ spectrum
    return np.moveaxis(out, 0, axis)


def _centre_cycles(base: np.ndarray, axis: int, step: float) -> np.ndarray:
    """The data's own spectral centre along ``axis`` of ``base`` (complex [n_range, n_azimuth]), as
    the phase [cycles, float64 [n]] of a carrier integrated from the first sample: the lag-one
    correlation's phase over the whole image (a constant frequency) or, where at least three of
    :data:`_CENTRE_BLOCKS` blocks along the axis hold a tenth of the strongest block's
    correlation (distributed clutter, not a lone target whose empty blocks would set a slope), a
    line through those blocks' own centres, weighted by their correlations."""
    n = base.shape[axis]
    edges = np.linspace(0, n, _CENTRE_BLOCKS + 1).astype(int)
    where, lags = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        z = base[a:b] if axis == 0 else base[:, a:b]
        if b - a >= 2:
            where.append(0.5 * (a + b - 1))
            lags.append(np.sum(z[1:] * np.conj(z[:-1])) if axis == 0 else np.sum(z[:, 1:] * np.conj(z[:, :-1])))
    lags = np.asarray(lags)
    weight = np.abs(lags)
    if not weight.size or not weight.sum() > 0:
        return np.zeros(n)
    centre = np.angle(lags) / (2.0 * np.pi * step)
    strong = weight >= 0.1 * weight.max()
    if np.count_nonzero(strong) >= 3:
        line = np.polyfit(np.asarray(where)[strong], centre[strong], 1, w=weight[strong])
    else:
        line = np.array([0.0, float(np.angle(lags.sum())) / (2.0 * np.pi * step)])
    return np.polyval(np.polyint(line), np.arange(n, dtype=np.float64)) * step


def flatten(base: np.ndarray, steps: tuple[float, float], gains: tuple) -> np.ndarray:
    """``base`` (complex [n_range, n_azimuth], an image demodulated by its carrier, sample spacings
    ``steps`` [m]) with its spectrum along each axis multiplied by ``gains`` (functions of the
    frequency [cycles/m] from the support's centre, :func:`~sarmitsuba.formats.sicd_support.flattening_gain`;
    None leaves the axis alone): the weighting taken out for a uniform SICD (docs/physics.md (K3')).

    The gain is centred on the data's own spectral centre along the axis (:func:`_centre_cycles`:
    the residual carrier is taken out before and put back after): the carrier model can be a few
    percent of the band off (clutter above the image plane leans its spectrum), and where the
    weighting is steep (18 nepers per band near a stripmap pattern's nulls) that would tilt the
    flattened spectrum by dB. Each axis is zero-padded by half its length first, so the flattened
    responses' longer tails do not wrap."""
    from scipy.fft import fft, ifft, next_fast_len
    for axis, (step, gain) in enumerate(zip(steps, gains)):
        if gain is None:
            continue
        n = base.shape[axis]
        size = next_fast_len(n + n // 2)
        ramp = np.exp(-2j * np.pi * _centre_cycles(base, axis, step))
        ramp = ramp[:, None] if axis == 0 else ramp[None, :]
        g = gain(np.fft.fftfreq(size, step))
        spectrum = fft(base * ramp, size, axis=axis) * (g[:, None] if axis == 0 else g[None, :])
        base = (ifft(spectrum, axis=axis)[:n] if axis == 0 else ifft(spectrum, axis=axis)[:, :n]) * np.conj(ramp)
    return base


def resample(image: SarImage, carrier: Carrier, scp: tuple[float, float], rows: np.ndarray,
             cols: np.ndarray, removed: tuple[float, float], gains: tuple = (None, None)) -> np.ndarray:
    """The SICD pixels (complex64 [len(rows), len(cols)], rows = range): ``image`` interpolated at the
    range positions ``rows`` and azimuth positions ``cols`` [m, image axes] with its carrier (module
    docstring), times ``exp(-j 2 pi removed . (x, y))``; ``scp`` = (range, azimuth) of the SCP [m];
    the baseband's spectrum first multiplied by ``gains`` (:func:`flatten`).

    Cost: two FFTs of the image and products with ``[len(rows), n_range]`` and
    ``[len(cols), n_azimuth]`` interpolation matrices (in blocks of 1024 positions).
    """
    same = (rows.size == image.range.size and cols.size == image.azimuth.size
            and np.allclose(rows, image.range, rtol=0, atol=1e-9 * abs(rows[1] - rows[0]))
            and np.allclose(cols, image.azimuth, rtol=0, atol=1e-9 * abs(cols[1] - cols[0])))
    x_old, y_old = image.range - scp[0], image.azimuth - scp[1]
    x_new, y_new = rows - scp[0], cols - scp[1]
    if same and removed == (0.0, 0.0) and gains == (None, None):
        return np.ascontiguousarray(image.data.T.astype(np.complex64))
    old_phase = linear_cycles(carrier.kctr, x_old, y_old) + carrier.cycles(x_old, y_old)       # [n_rg, n_az]
    base = image.data.T.astype(np.complex128) * np.exp(-2j * np.pi * old_phase)
    d_rg, d_az = float(np.diff(image.range).mean()), float(np.diff(image.azimuth).mean())
    base = flatten(base, (d_rg, d_az), gains)
    if not same:
        d_rows, d_cols = float(rows[1] - rows[0]), float(cols[1] - cols[0])
        base = _interpolate(base, 0, d_rg, rows - image.range[0], 0.5 / d_rows)
        base = _interpolate(base, 1, d_az, cols - image.azimuth[0], 0.5 / d_cols)
    kept = (carrier.kctr[0] - removed[0], carrier.kctr[1] - removed[1])
    new_phase = linear_cycles(kept, x_new, y_new) + carrier.cycles(x_new, y_new)
    return np.ascontiguousarray((base * np.exp(2j * np.pi * new_phase)).astype(np.complex64))


def linear_cycles(k: tuple[float, float], x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``k . (x, y)`` [cycles] on the grid ``x`` [n] x ``y`` [m], less its whole cycles (float64 [n, m])."""
    gx, gy = np.mod(k[0] * x, 1.0), np.mod(k[1] * y, 1.0)
    return np.mod(gx[:, None] + gy[None, :], 1.0)


def deltak_limits(deltakcoa: np.ndarray, vertices_x: np.ndarray, vertices_y: np.ndarray, bandwidth: float,
                  spacing: float) -> tuple[float, float]:
    """(DeltaK1, DeltaK2) [cycles/m]: ``DeltaKCOAPoly`` at the vertices (row and column coordinates
    [m]) -+ ``bandwidth / 2``, the whole band ``+-1 / (2 spacing)`` when that wraps (SICD volume 1,
    Grid; the same rule as sarkit's and sarpy's consistency checks)."""
    values = np.polynomial.polynomial.polyval2d(vertices_x, vertices_y, deltakcoa)
    low, high = float(values.min()) - 0.5 * bandwidth, float(values.max()) + 0.5 * bandwidth
    if low < -0.5 / spacing or high > 0.5 / spacing:
        return -0.5 / spacing, 0.5 / spacing
    return low, high
