"""Sigma nought of a randomly rough dielectric surface: the improved integral equation model
(I2EM) for HH and VV, monostatic and bistatic, its cross-polarised multiple-scattering term for
HV, and geometric optics beyond the model's range (docs/physics.md (RS1)-(RS5)).

Plain NumPy (float64/complex128) on the host; the tracer reads the values as tables
(:mod:`sarmitsuba.scene.rough_tables`). Sources:

* A. K. Fung, W. Y. Liu, K. S. Chen and M. K. Tsay, "An improved IEM model for bistatic
  scattering from rough surfaces", J. Electromagn. Waves Appl. 16(5), 689-702, 2002;
* A. K. Fung and K. S. Chen, *Microwave Scattering and Emission Models for Users*, Artech House,
  2010;
* F. T. Ulaby and D. G. Long, *Microwave Radar and Radiometric Remote Sensing*, University of
  Michigan Press, 2014, section 10-3 (and its codes 10.1 and 10.3, the independent check of
  ``tests/data/i2em``);
* T. D. Wu, K. S. Chen, J. Shi and A. K. Fung, "A transition model for the reflection
  coefficient in surface scattering", IEEE TGRS 39(9), 2001 (the transition coefficients);
* B. G. Smith, "Geometrical shadowing of a random rough surface", IEEE TAP 15(5), 1967.

Conventions: time dependence ``exp(+j omega t)``, permittivity ``eta = eps' - j eps''``
(``Im <= 0``) as in :mod:`sarmitsuba.scene.fresnel`; angles from the mean surface's normal;
the incident wave travels in the plane ``phi = 0`` and ``phi_s`` is the scattered direction's
azimuth from it (backscatter: ``theta_s = theta_i``, ``phi_s = 180 deg``; specular:
``phi_s = 0``). Sigma nought is linear (m^2/m^2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import erf, erfc, gammaln

from .fresnel import MaterialError, check_eta

__all__ = ["RoughSurface", "RoughSurfaceWarning", "KS_LIMIT", "SLOPE_LIMIT", "CROSS_KS_LIMIT", "outside_range",
           "roughness_spectrum", "spectral_terms", "transition_reflection",
           "slope_averaged_reflection", "i2em_backscatter", "i2em_bistatic", "i2em_cross",
           "geometric_optics", "sigma0_backscatter", "sigma0_bistatic"]

#: Largest ``k s`` where the I2EM is used; beyond it geometric optics, eq. (RS5).
KS_LIMIT = 3.0
#: Largest ``s / l`` of the I2EM's validated range, eq. (RS5): the bound Ulaby and Long put on their
#: I2EM codes 10.1-10.3 ("realistic surfaces").
SLOPE_LIMIT = 0.25
#: Largest ``k s`` of the cross-polarised term's validated range, eq. (RS5): the bound of Ulaby and
#: Long's backscatter code 10.1, the one that computes it.
CROSS_KS_LIMIT = 1.0
#: A spectral series stops where ``(k s)^2n (cos_i + cos_s)^2n / n!`` falls below this.
_SERIES_TOLERANCE = 1e-8
_CORRELATIONS = ("exponential", "gaussian")


class RoughSurfaceWarning(UserWarning):
    """A rough surface outside the validated range of its model at the carrier, docs/physics.md (RS5)."""


@dataclass(frozen=True)
class RoughSurface:
    """A randomly rough surface's statistics (a stationary, isotropic Gaussian height field).

    Attributes
    ----------
    rms_height : float
        Standard deviation ``s`` of the height [m], > 0.
    correlation_length : float
        ``l`` of the autocorrelation ``rho(r)`` [m], > 0.
    correlation : {"exponential", "gaussian"}
        ``rho(r) = exp(-r / l)`` or ``exp(-r^2 / l^2)``.

    Raises
    ------
    MaterialError
        If a length is not finite and positive or the correlation is not one of the two.
    """

    rms_height: float
    correlation_length: float
    correlation: str = "exponential"

    def __post_init__(self):
        for name in ("rms_height", "correlation_length"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise MaterialError(f"rough surface: {name} must be a finite length > 0 in m, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.correlation not in _CORRELATIONS:
            raise MaterialError(f"rough surface: correlation must be one of {_CORRELATIONS}, "
                                f"got {self.correlation!r}")

    @property
    def rms_slope(self) -> float:
        """The rms slope (dimensionless): ``sqrt(2) s / l`` (Gaussian), ``s / l`` (exponential,
        whose true slope variance diverges; the value the model's shadowing uses), eq. (RS4)."""
        return (math.sqrt(2.0) if self.correlation == "gaussian" else 1.0) * self.rms_height / self.correlation_length


def outside_range(surface: RoughSurface, wavenumber: float, cross: bool = False) -> tuple[str, ...]:
    """The bounds of the I2EM's validated range (docs/physics.md (RS5)) that ``surface`` exceeds at
    the wavenumber ``k`` [rad/m]: ``k s <= KS_LIMIT`` (beyond it sigma nought is geometric optics),
    ``s / l <= SLOPE_LIMIT`` and, for ``cross`` (HV traced), ``k s <= CROSS_KS_LIMIT``. Each as a
    phrase such as ``"k s = 201 > 3"``; empty inside the range."""
    ks, ratio = wavenumber * surface.rms_height, surface.rms_height / surface.correlation_length
    out = []
    if ks > KS_LIMIT:
        out.append(f"k s = {ks:.3g} > {KS_LIMIT:g}")
    if ratio > SLOPE_LIMIT:
        out.append(f"s / l = {ratio:.3g} > {SLOPE_LIMIT:g}")
    if cross and CROSS_KS_LIMIT < ks <= KS_LIMIT:
        out.append(f"k s = {ks:.3g} > {CROSS_KS_LIMIT:g} for HV")
    return tuple(out)


def roughness_spectrum(n, wavenumber, surface: RoughSurface) -> np.ndarray:
    """The ``n``-th roughness spectrum ``W^(n)(K) = int_0^inf rho(r)^n J0(K r) r dr`` [m^2], eq. (RS2).

    Parameters
    ----------
    n : int or array of int, >= 1
        The power of the autocorrelation.
    wavenumber : float or array, rad/m
        ``K``, the surface wavenumber (broadcast with ``n``).
    surface : RoughSurface

    Returns
    -------
    float64 array of the broadcast shape: Gaussian ``l^2 / (2 n) exp(-K^2 l^2 / (4 n))``,
    exponential ``(l / n)^2 (1 + (K l / n)^2)^(-3/2)`` (Fung and Chen 2010, table 2.1).
    """
    n = np.asarray(n, dtype=np.float64)
    kl = np.asarray(wavenumber, dtype=np.float64) * surface.correlation_length
    l2 = surface.correlation_length ** 2
    if surface.correlation == "gaussian":
        return l2 / (2.0 * n) * np.exp(-kl * kl / (4.0 * n))
    return l2 / (n * n) * (1.0 + (kl / n) ** 2) ** -1.5


def spectral_terms(ks: float, cos_sum) -> int:
    """Number of terms of the series (RS1): the least ``N >= 2`` with
    ``(ks^2 (cos_i + cos_s)^2)^N / N! < 1e-8`` for the largest ``cos_sum`` given."""
    x = ks * ks * float(np.max(cos_sum)) ** 2
    n = 2
    while n < 200 and n * math.log(max(x, 1e-300)) - math.lgamma(n + 1) >= math.log(_SERIES_TOLERANCE):
        n += 1
    return n


def _fresnel(cos_t, sin_t, eta):
    """``(r_v, r_h, sqrt(eta - sin^2))`` of the flat interface, the model's sign convention
    (``r_v = (eta cos - root) / (eta cos + root)``, ``r_h = (cos - root) / (cos + root)``)."""
    root = np.sqrt(eta - sin_t * sin_t + 0j)
    root = np.where(root.imag > 0, np.conj(root), root)
    return (eta * cos_t - root) / (eta * cos_t + root), (cos_t - root) / (cos_t + root), root


def _series(ks, cos_a, spectrum_n):
    """``[(ks cos_a)^(2n) / n!]`` for n = 1..N (rows) as float64, ``spectrum_n`` of shape (N, ...)."""
    n = np.arange(1, spectrum_n.shape[0] + 1, dtype=np.float64).reshape((-1,) + (1,) * (spectrum_n.ndim - 1))
    return np.exp(2.0 * n * np.log(ks * cos_a) - gammaln(n + 1.0))


def transition_reflection(eta, cos_i, ks, spectra):
    """The transition reflection coefficients ``(R_v^T, R_h^T)`` of Wu, Chen, Shi and Fung (2001),
    eq. (RS3): from the local-incidence Fresnel value toward the normal-incidence one as the
    roughness grows. ``spectra``: ``W^(n)(2 k sin theta) / l^2`` stacked on a first axis
    (n = 1..N); ``cos_i`` the incidence cosine (backscatter). Complex128 arrays."""
    sin_i = np.sqrt(1.0 - cos_i * cos_i)
    r_v, r_h, root = _fresnel(cos_i, sin_i, eta)
    r0 = (np.sqrt(eta + 0j) - 1.0) / (np.sqrt(eta + 0j) + 1.0)
    ft = 8.0 * r0 * r0 * sin_i * (cos_i + root) / (cos_i * root)
    weights = _series(ks, cos_i, spectra) * spectra
    n = np.arange(1, spectra.shape[0] + 1).reshape((-1,) + (1,) * (spectra.ndim - 1))
    lead = np.abs(ft / 2.0 + 2.0 ** (n + 1) * r0 / cos_i * np.exp(-(ks * cos_i) ** 2)) ** 2
    st = 0.25 * np.abs(ft) ** 2 * weights.sum(0) / (lead * weights).sum(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        st0 = 1.0 / np.abs(1.0 + 8.0 * r0 / (cos_i * ft)) ** 2
        # at normal incidence (ft = 0) R^T is R(0) whatever tf is: take tf = 0
        tf = np.where(sin_i > 0.0, 1.0 - st / st0, 0.0)
    return r_v + (r0 - r_v) * tf, r_h + (-r0 - r_h) * tf


_AVERAGE_NODES = np.polynomial.legendre.leggauss(32)
#: Nodes per axis and panel where some slopes of the average face away from the incident wave.
_STEEP_NODES = np.polynomial.legendre.leggauss(128)
#: Incidence cosines averaged at once on the finer rule.
_STEEP_BLOCK = 64


def slope_averaged_reflection(eta, cos_i, slope):
    """Fresnel coefficients ``(<R_v>, <R_h>)`` averaged over the local slopes ``(Z_x, Z_y)`` of a
    surface, eq. (RS3): each slope Gaussian with standard deviation ``slope`` and the average taken
    over ``|Z_x|, |Z_y| <= 3 slope`` without renormalising, as the bistatic model defines it
    (Ulaby and Long 2014, code 10.3, with ``slope = 1.1 s / l``). Complex128 arrays of ``cos_i``'s shape.

    Gauss-Legendre, 32 x 32 nodes; where some facet within the three standard deviations turns
    away from the incident wave (``Z_x < -cot theta``), 2 x 128 x 128: the ``Z_x`` axis split where
    the local incidence cosine ``cos theta + Z_x sin theta`` changes sign, at which the integrand
    steps (a good conductor's ``R_v`` from +1 to -1) and near which it peaks. There the 32-point
    rule misses the average by up to 3 dB (near grazing, ``slope`` 0.275); the split rule agrees
    with Ulaby and Long's adaptive integration to 1e-4 dB (tests/data/i2em)."""
    shape = np.shape(cos_i)
    c = np.asarray(cos_i, dtype=np.float64).reshape(-1)
    edge = 3.0 * slope
    turn = -c / np.sqrt(np.maximum(1.0 - c * c, 1e-300))            # Z_x of the facet edge-on to the wave
    steep = turn > -edge
    out_v, out_h = np.zeros(c.shape, np.complex128), np.zeros(c.shape, np.complex128)
    if np.any(~steep):
        lo = np.full(c[~steep].shape, -edge)
        out_v[~steep], out_h[~steep] = _slope_sum(eta, c[~steep], slope, lo, -lo, _AVERAGE_NODES)
    where = np.flatnonzero(steep)
    for block in range(0, where.size, _STEEP_BLOCK):                 # bounded memory: 2^15 nodes a value
        at = where[block:block + _STEEP_BLOCK]
        lo = np.full(at.shape, -edge)
        below = _slope_sum(eta, c[at], slope, lo, turn[at], _STEEP_NODES)
        above = _slope_sum(eta, c[at], slope, turn[at], -lo, _STEEP_NODES)
        out_v[at], out_h[at] = below[0] + above[0], below[1] + above[1]
    return out_v.reshape(shape), out_h.reshape(shape)


def _slope_sum(eta, c, slope, lo, hi, nodes):
    """The slope average's part over ``lo <= Z_x <= hi`` (float64 arrays of ``c``'s 1-D shape) and
    ``|Z_y| <= 3 slope``, by the product Gauss-Legendre rule of ``nodes`` per axis: ``(<R_v>, <R_h>)``."""
    x, w = nodes
    half = (0.5 * (hi - lo))[:, None, None]
    zx = half * x[None, :, None] + (0.5 * (hi + lo))[:, None, None]
    zy = 3.0 * slope * x[None, None, :]
    density = np.exp(-(zx * zx + zy * zy) / (2.0 * slope * slope)) / (2.0 * np.pi * slope * slope)
    weight = half * 3.0 * slope * w[None, :, None] * w[None, None, :] * density
    c = c[:, None, None]
    s = np.sqrt(1.0 - c * c)
    a = c + zx * s                                    # the local incidence cosine, unnormalised
    root = np.sqrt(eta * (1.0 + zx * zx + zy * zy) - (s * s - 2 * zx * s * c + zx * zx * c * c + zy * zy) + 0j)
    root = np.where(root.imag > 0, np.conj(root), root)
    r_v = (eta * a - root) / (eta * a + root)
    r_h = (a - root) / (a + root)
    return (r_v * weight).sum((-1, -2)), (r_h * weight).sum((-1, -2))


def _complementary(eta, k, geometry, side: int, up: int, r_v, r_h):
    """The complementary field coefficients ``F_pp^(up/down)(incident or scattered side)`` of the
    I2EM (Fung et al. 2002), eq. (RS1): ``side`` 1 (the incident wave's spectral point) or 2 (the
    scattered), ``up`` +1 or -1. Returns ``(F_vv, F_hh)``."""
    s, c, ss, cs, cp, sp = geometry
    kz, ksz = k * c, k * cs
    tilt = ss * cp - s                                 # sin_s cos(phi_s) - sin_i
    if side == 1:
        q = up * kz
        g, gt = q, up * k * np.sqrt(eta - s * s + 0j)
        c1 = k * cp * (ksz - q)
        c2 = [c * (cp * (k * k * s * tilt + gg * (k * cs - q)) + k * k * s * ss * sp * sp) for gg in (g, gt)]
        c3 = [k * s * (s * cp * (k * cs - q) - g * (cp * tilt + ss * sp * sp)),
              k * s * (s * cp * (k * cs - q) - gt * (cp * tilt - ss * sp * sp))]
        c4 = k * c * (cp * cs * (k * cs - q) + k * ss * tilt)
        c5 = [gg * (cp * cs * (q - k * cs) - k * ss * tilt) for gg in (g, gt)]
    else:
        q = up * ksz
        g, gt = q, up * k * np.sqrt(eta - ss * ss + 0j)
        c1 = k * cp * (kz + q)
        c2 = [gg * (cp * (c * (kz + q) - k * s * tilt) - k * s * ss * sp * sp) for gg in (g, gt)]
        c3 = [k * ss * (k * c * tilt + s * (kz + q))] * 2
        c4 = k * cs * (cp * (c * (kz + q) - k * s * tilt) - k * s * ss * sp * sp)
        c5 = [-cs * (k * k * ss * tilt + gg * cp * (kz + q)) for gg in (g, gt)]
    q0, qt = kz, k * np.sqrt(eta - s * s + 0j)
    rp, rm = 1.0 + r_v, 1.0 - r_v
    f_vv = (rp * (-rm * c1 / q0 + rp * c1 / qt) + rm * (rm * c2[0] / q0 - rp * c2[1] / qt)
            + rp * (rm * c3[0] / q0 - rp * c3[1] / (eta * qt)) + rm * (rp * c4 / q0 - eta * rm * c4 / qt)
            + rp * (rp * c5[0] / q0 - rm * c5[1] / qt))
    hp, hm = 1.0 + r_h, 1.0 - r_h
    f_hh = (hp * (hm * c1 / q0 - eta * hp * c1 / qt) - hm * (hm * c2[0] / q0 - hp * c2[1] / qt)
            - hp * (hm * c3[0] / q0 - hp * c3[1] / qt) - hm * (hp * c4 / q0 - hm * c4 / qt)
            - hp * (hp * c5[0] / q0 - hm * c5[1] / qt))
    return f_vv, f_hh


def _geometry(cos_i, cos_s, phi_s):
    """``(sin_i, cos_i, sin_s, cos_s, cos phi_s, sin phi_s)`` as broadcast float64 arrays."""
    c, cs, p = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (cos_i, cos_s, phi_s)))
    return np.sqrt(1.0 - c * c), c, np.sqrt(1.0 - cs * cs), cs, np.cos(p), np.sin(p)


def _i2em_sum(eta, k, surface: RoughSurface, geometry, coefficients):
    """Eq. (RS1) without shadowing: ``(sigma0_vv, sigma0_hh)`` for the Kirchhoff terms' coefficients
    ``coefficients = (R_v, R_h, R_v^i, R_h^i)`` (the first two in ``f_pp``, the last two, the
    incidence Fresnel values, in the complementary terms)."""
    s, c, ss, cs, cp, sp = geometry
    r_vt, r_ht, r_vi, r_hi = coefficients
    h = surface.rms_height
    kz, ksz = k * c, k * cs
    wavenumber = k * np.sqrt((ss * cp - s) ** 2 + (ss * sp) ** 2)
    terms = spectral_terms(k * h, c + cs)
    n = np.arange(1, terms + 1, dtype=np.float64).reshape((-1,) + (1,) * c.ndim)
    spectra = roughness_spectrum(n, wavenumber, surface)
    kirchhoff = 2.0 * (s * ss - (1.0 + c * cs) * cp) / (c + cs)
    fields = [_complementary(eta, k, geometry, side, up, r_vi, r_hi) for side, up in ((1, 1), (1, -1), (2, 1), (2, -1))]
    dz = ksz - kz
    bases = (ksz - kz, ksz + kz, kz + ksz, kz - ksz)
    decays = (kz * kz - kz * dz, kz * kz + kz * dz, ksz * ksz - ksz * dz, ksz * ksz + ksz * dz)
    scale = np.exp(0.5 * gammaln(n + 1.0))                        # sqrt(n!)
    out = []
    for pol, f_pp in ((0, kirchhoff * r_vt), (1, -kirchhoff * r_ht)):
        # h^n I_pp^n / sqrt(n!), term by term
        term = (h * (kz + ksz)) ** n * f_pp * np.exp(-h * h * kz * ksz)
        for field, base, decay in zip(fields, bases, decays):
            term = term + 0.25 * h * field[pol] * (h * base) ** (n - 1) * np.exp(-h * h * decay)
        total = (np.abs(term / scale) ** 2 * spectra).sum(0)
        out.append(0.5 * k * k * np.exp(-h * h * (kz * kz + ksz * ksz)) * total)
    return out[0], out[1]


def _smith(cos_t, slope):
    """Smith's (1967) shadowing function ``Lambda(theta)`` for rms slope ``slope``."""
    x = cos_t / np.sqrt(np.maximum(1.0 - cos_t * cos_t, 1e-300)) / (math.sqrt(2.0) * slope)
    return 0.5 * (np.exp(-x * x) / (math.sqrt(math.pi) * x) - erfc(x))


def _check_cos(name, value):
    c = np.asarray(value, dtype=np.float64)
    if np.any(~((c > 0.0) & (c <= 1.0))):
        raise MaterialError(f"rough surface: {name} must lie in (0, 1] (above the surface), got "
                            f"{c[~((c > 0.0) & (c <= 1.0))].flat[0]!r}")
    return c


def i2em_backscatter(surface: RoughSurface, eta, wavenumber: float, cos_theta):
    """Monostatic I2EM sigma nought ``(sigma0_vv, sigma0_hh)``, eq. (RS1) with the transition
    reflection coefficients (RS3) and Smith's shadowing (RS4); Fung and Chen 2010, Ulaby and Long
    2014 section 10-3.9 (its code 10.1).

    Parameters
    ----------
    surface : RoughSurface
    eta : complex
        Relative permittivity of the half-space below (``Im <= 0``).
    wavenumber : float
        Free-space wavenumber ``k = 2 pi f / c`` [rad/m].
    cos_theta : float or array in (0, 1]
        Incidence cosine.

    Returns
    -------
    (sigma0_vv, sigma0_hh) : float64 arrays of ``cos_theta``'s shape, linear m^2/m^2.

    Raises
    ------
    MaterialError
        For a cosine outside (0, 1] or an invalid permittivity.
    """
    eta = complex(check_eta(eta))
    c = _check_cos("cos_theta", cos_theta)
    geometry = _geometry(c, c, math.pi)
    ks = wavenumber * surface.rms_height
    n = np.arange(1, spectral_terms(ks, 2.0 * c) + 1, dtype=np.float64).reshape((-1,) + (1,) * c.ndim)
    spectra = roughness_spectrum(n, 2.0 * wavenumber * geometry[0], surface)
    r_vt, r_ht = transition_reflection(eta, c, ks, spectra)
    r_vi, r_hi, _ = _fresnel(c, geometry[0], eta)
    vv, hh = _i2em_sum(eta, wavenumber, surface, geometry, (r_vt, r_ht, r_vi, r_hi))
    shadow = 1.0 / (1.0 + 2.0 * _smith(c, surface.rms_slope))
    return vv * shadow, hh * shadow


#: The slope of the bistatic coefficients' average, in units of ``s / l`` (Ulaby and Long 2014, code 10.3).
AVERAGE_SLOPE = 1.1


def i2em_bistatic(surface: RoughSurface, eta, wavenumber: float, cos_i, cos_s, phi_s):
    """Bistatic I2EM sigma nought ``(sigma0_vv, sigma0_hh)``, eq. (RS1) with the slope-averaged
    reflection coefficients (RS3) and no shadowing (Fung et al. 2002; Ulaby and Long 2014 code 10.3).

    Parameters
    ----------
    surface : RoughSurface
    eta : complex
        Relative permittivity (``Im <= 0``).
    wavenumber : float
        ``k`` [rad/m].
    cos_i, cos_s : float or array in (0, 1]
        Incidence and scattering cosines.
    phi_s : float or array, rad
        Azimuth of the scattered direction from the plane of incidence (pi: back toward the source).

    Returns
    -------
    (sigma0_vv, sigma0_hh) : float64 arrays of the broadcast shape, linear.

    Raises
    ------
    MaterialError
        For a cosine outside (0, 1] or an invalid permittivity.
    """
    eta = complex(check_eta(eta))
    cos_i = _check_cos("cos_i", cos_i)
    geometry = _geometry(cos_i, _check_cos("cos_s", cos_s), phi_s)
    slope = AVERAGE_SLOPE * surface.rms_height / surface.correlation_length
    r_va, r_ha = slope_averaged_reflection(eta, cos_i, slope)      # on cos_i's own (unbroadcast) shape
    r_vi, r_hi, _ = _fresnel(geometry[1], geometry[0], eta)
    return _i2em_sum(eta, wavenumber, surface, geometry, (r_va, r_ha, r_vi, r_hi))


_LEGENDRE = np.polynomial.legendre.leggauss(64)


def i2em_cross(surface: RoughSurface, eta, wavenumber: float, cos_theta):
    """Monostatic cross-polarised sigma nought ``sigma0_hv`` (= ``sigma0_vh``), the multiple
    scattering term of the IEM (Fung and Chen 2010; Ulaby and Long 2014 section 10-3.9, code 10.1's
    IEMX), eq. (RS1x), with Smith's shadowing (RS4) on the single and the multiple bounce.

    The spectral integral over the propagating directions ``u^2 + v^2 <= 1`` is a product Gauss-
    Legendre rule (64 x 64) in ``r = sin t`` and azimuth; its double series factorises into the
    product of two single ones.

    Parameters
    ----------
    surface, eta, wavenumber, cos_theta
        As in :func:`i2em_backscatter` (``cos_theta`` a scalar or 1-D array).

    Returns
    -------
    float64 array of ``cos_theta``'s shape, linear.

    Raises
    ------
    MaterialError
        For a cosine outside (0, 1] or an invalid permittivity.
    """
    eta = complex(check_eta(eta))
    c = np.atleast_1d(_check_cos("cos_theta", cos_theta))
    x, w = _LEGENDRE
    t = 0.25 * math.pi * (x + 1.0)                    # r = sin t on [0, 1], dr = cos t dt
    phi = 0.5 * math.pi * (x + 1.0)                   # [0, pi]; the integrand is even in phi
    weight = (0.25 * math.pi * w)[:, None] * (0.5 * math.pi * w)[None, :]
    r, q = np.sin(t)[:, None], np.cos(t)[:, None]
    rx, ry = r * np.cos(phi)[None, :], r * np.sin(phi)[None, :]
    ks, kl, m = wavenumber * surface.rms_height, wavenumber * surface.correlation_length, surface.rms_slope
    out = np.empty(c.shape)
    for i, ci in enumerate(c.flat):
        si = math.sqrt(1.0 - ci * ci)
        r_v, r_h, _ = _fresnel(ci, si, eta)
        rvh = (r_v - r_h) / 2.0
        qt = np.sqrt(eta - r * r + 0j)
        a, b, cc, d = (1 + rvh) / q, (1 - rvh) / q, (1 + rvh) / qt, (1 - rvh) / qt
        field = ((b - cc) * (1 - 3 * rvh) - (b - cc / eta) * (1 + rvh)
                 + (a - d) * (1 + 3 * rvh) - (a - d * eta) * (1 - rvh)) * rx * ry / ci
        au = q / (r * math.sqrt(2.0) * m)
        bounce = 1.0 / (1.0 + 0.5 * (np.exp(-au * au) / (math.sqrt(math.pi) * au) - erfc(au)))
        x2 = (ks * ci) ** 2
        terms = spectral_terms(ks, 2.0 * ci)
        n = np.arange(1, terms + 1, dtype=np.float64)[:, None, None]
        factor = np.exp(n * math.log(x2) - gammaln(n + 1.0))
        series = [(factor * roughness_spectrum(n, wavenumber * np.hypot(rx + sign * si, ry), surface)).sum(0)
                  for sign in (-1.0, 1.0)]
        integrand = np.abs(field) ** 2 * series[0] * series[1] * wavenumber ** 4 * bounce * r * q
        total = 4.0 * math.exp(-2.0 * x2) / (16.0 * math.pi) * (integrand * weight).sum()
        out.flat[i] = total / (1.0 + _smith(ci, m))
    return out.reshape(np.shape(cos_theta)) if np.ndim(cos_theta) else out[0]


def geometric_optics(surface: RoughSurface, eta, cos_i, cos_s, phi_s):
    """Geometric-optics (Kirchhoff stationary-phase) sigma nought ``(sigma0_vv, sigma0_hh)``, eq. (RS5):
    ``pi |R(iota)|^2 |q|^4 / q_z^4 p(-q_x / q_z, -q_y / q_z)``, ``q = k (k_s - k_i)``, ``p`` the
    Gaussian slope density of rms slope ``surface.rms_slope`` per axis and ``R`` the Fresnel
    coefficient (``R_v`` for VV, ``R_h`` for HH) at the specular facet's local incidence
    ``cos iota = |q| / 2k`` (Barrick, IEEE TAP 16(4), 1968; Ulaby and Long 2014, chapter 10).
    Monostatic: ``|R(0)|^2 exp(-tan^2 theta / 2 m^2) / (2 m^2 cos^4 theta)``. Independent of ``k``.
    Arguments and return as :func:`i2em_bistatic` (without the wavenumber)."""
    eta = complex(check_eta(eta))
    s, c, ss, cs, cp, sp = _geometry(_check_cos("cos_i", cos_i), _check_cos("cos_s", cos_s), phi_s)
    qx, qy, qz = ss * cp - s, ss * sp, cs + c                    # q / k
    q2 = qx * qx + qy * qy + qz * qz
    cos_local = np.sqrt(q2) / 2.0
    r_v, r_h, _ = _fresnel(cos_local, np.sqrt(np.maximum(1.0 - cos_local ** 2, 0.0)), eta)
    m2 = surface.rms_slope ** 2
    density = np.exp(-(qx * qx + qy * qy) / (2.0 * qz * qz * m2)) / (2.0 * math.pi * m2)
    level = math.pi * q2 * q2 / qz ** 4 * density
    return np.abs(r_v) ** 2 * level, np.abs(r_h) ** 2 * level


def sigma0_backscatter(surface: RoughSurface, eta, wavenumber: float, cos_theta, cross: bool = True) -> dict:
    """Monostatic sigma nought per channel, ``{"HH", "VV", "HV"}`` (linear, arrays of
    ``cos_theta``'s shape): the I2EM (:func:`i2em_backscatter`, :func:`i2em_cross`) where
    ``k s <= KS_LIMIT``, geometric optics (:func:`geometric_optics`, no cross-polarised term)
    beyond, docs/physics.md (RS5). ``cross`` False leaves HV out (zeros): its integral is most of
    the cost.

    Raises
    ------
    MaterialError
        For a cosine outside (0, 1] or an invalid permittivity.
    """
    c = _check_cos("cos_theta", cos_theta)
    if wavenumber * surface.rms_height > KS_LIMIT:
        vv, hh = geometric_optics(surface, eta, c, c, math.pi)
        return {"HH": hh, "VV": vv, "HV": np.zeros(c.shape)}
    vv, hh = i2em_backscatter(surface, eta, wavenumber, c)
    return {"HH": hh, "VV": vv, "HV": i2em_cross(surface, eta, wavenumber, c) if cross else np.zeros(c.shape)}


def sigma0_bistatic(surface: RoughSurface, eta, wavenumber: float, cos_i, cos_s, phi_s) -> dict:
    """Bistatic co-polarised sigma nought ``{"HH", "VV"}`` (linear, arrays of the broadcast shape):
    :func:`i2em_bistatic` where ``k s <= KS_LIMIT``, :func:`geometric_optics` beyond (RS5).

    Raises
    ------
    MaterialError
        For a cosine outside (0, 1] or an invalid permittivity.
    """
    if wavenumber * surface.rms_height > KS_LIMIT:
        vv, hh = geometric_optics(surface, eta, cos_i, cos_s, phi_s)
    else:
        vv, hh = i2em_bistatic(surface, eta, wavenumber, cos_i, cos_s, phi_s)
    return {"HH": hh, "VV": vv}
