"""Spectral weighting windows and their impulse-response figures (docs/design.md section 8).

A window weights the processed band of a SAR dimension (range or azimuth) to trade
resolution for sidelobe level. Every window here is defined on the normalised frequency
``x = f / B`` over ``|x| <= 1/2`` (zero outside) and has unit value at band centre:

===========  =================================================  ==============================
name         w(x), ``|x| <= 1/2``                               parameters (default)
===========  =================================================  ==============================
``rect``     1                                                  --
``hamming``  alpha + (1 - alpha) cos(2 pi x)                    ``alpha`` (0.54)
``hann``     0.5 + 0.5 cos(2 pi x)                              --
``taylor``   (1 + 2 sum_m F_m cos(2 pi m x)) / (same at x = 0)  ``nbar`` (4), ``sll`` (-35 dB)
``kaiser``   I0(beta sqrt(1 - (2x)^2)) / I0(beta)               ``beta`` (2.5)
===========  =================================================  ==============================

The compressed pulse (unit-peak impulse response) of a window over a band ``B`` is

.. math::

    p(t) = \\frac{\\int_{-B/2}^{B/2} w(f/B)\\, e^{j 2 \\pi f t}\\, df}
                 {\\int_{-B/2}^{B/2} w(f/B)\\, df},

in closed form here (:func:`compressed_pulse`): cosine-series windows give a weighted sum
of shifted sincs and the Kaiser window gives ``sinh(sqrt(beta^2 - (pi B t)^2)) /
sqrt(...)``. From it the standard figures of each window ([1]_-[3]_) are computed
numerically: -3 dB width (:func:`impulse_response_width`), broadening against rect
(:func:`broadening_factor`), first null (:func:`first_null`), PSLR (:func:`pslr_theory`)
and null-bounded ISLR (:func:`islr_theory`).

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005, section 2.6 (Kaiser window, beta = 2.5 default).
.. [2] W. G. Carrara, R. S. Goodman and R. M. Majewski, *Spotlight Synthetic Aperture
   Radar*, Artech House, 1995, appendix D (Taylor weighting coefficients F_m).
.. [3] F. J. Harris, "On the use of windows for harmonic analysis with the discrete
   Fourier transform", Proc. IEEE 66(1), 51-83, 1978 (Kaiser transform).
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any, Mapping

import numpy as np
import scipy.integrate
import scipy.optimize
import scipy.signal.windows as _sw
import scipy.special

__all__ = ["WINDOWS", "window", "spectral_window", "compressed_pulse", "impulse_response_width",
           "broadening_factor", "first_null", "pslr_theory", "islr_theory", "energy_width", "window_mean",
           "check_window", "window_spec", "window_label"]

#: Window names and their parameters with defaults.
WINDOWS: dict[str, dict[str, float]] = {
    "rect": {},
    "hamming": {"alpha": 0.54},
    "hann": {},
    "taylor": {"nbar": 4, "sll": -35.0},
    "kaiser": {"beta": 2.5},
}


# ============================================================================ parameters
def check_window(name: str, **params: Any) -> tuple[str, dict[str, float]]:
    """Validate a window name and its parameters; fill in the defaults.

    Parameters
    ----------
    name : str
        One of :data:`WINDOWS` (case-insensitive; ``"none"``, ``"boxcar"`` and
        ``"rectangular"`` mean ``"rect"``).
    **params
        Window parameters (see the module table). Unknown keys are errors.

    Returns
    -------
    name : str
        The canonical name.
    params : dict
        All parameters of the window with defaults filled in (``nbar`` an int, the
        others floats; ``sll`` negative, in dB).

    Raises
    ------
    ValueError
        Unknown name or parameter, or a parameter outside its valid range:
        ``alpha`` in [0, 1], ``nbar`` an integer >= 1, ``|sll|`` in (13.27, 150] dB
        (a Taylor window cannot go above the -13.26 dB of rect), ``beta`` in [0, 50].
    """
    if not isinstance(name, str):
        raise ValueError(f"window name must be a string, one of {sorted(WINDOWS)}, got {name!r}")
    key = name.strip().lower()
    key = {"none": "rect", "boxcar": "rect", "rectangular": "rect", "uniform": "rect", "hanning": "hann"}.get(key, key)
    if key not in WINDOWS:
        raise ValueError(f"unknown window {name!r}; valid windows: {sorted(WINDOWS)}")
    unknown = set(params) - set(WINDOWS[key])
    if unknown:
        valid = sorted(WINDOWS[key]) or "none"
        raise ValueError(f"window {key!r} has no parameter(s) {sorted(unknown)}; valid parameters: {valid}")
    full: dict[str, float] = {**WINDOWS[key], **params}
    if key == "hamming":
        full["alpha"] = _finite("alpha", full["alpha"], 0.0, 1.0)
    elif key == "kaiser":
        full["beta"] = _finite("beta", full["beta"], 0.0, 50.0)
    elif key == "taylor":
        nbar = full["nbar"]
        if isinstance(nbar, bool) or not float(nbar).is_integer() or not 1 <= int(nbar) <= 100:
            raise ValueError(f"taylor nbar must be an integer in [1, 100], got {nbar!r}")
        full["nbar"] = int(nbar)
        sll = abs(_finite("sll", full["sll"], -150.0, 150.0))
        if sll <= 13.27:
            raise ValueError(f"taylor sll must be a sidelobe level in dB with |sll| in (13.27, 150] "
                             f"(e.g. -35), got {full['sll']!r}")
        full["sll"] = -sll
    return key, full


def window_spec(spec: Any) -> tuple[str, dict[str, float]]:
    """A window option, ``"name"`` or ``("name", {params})``, as the canonical ``(name, params)`` of
    :func:`check_window`. Raises ValueError for any other form, an unknown name or a bad parameter."""
    if isinstance(spec, str):
        return check_window(spec)
    if isinstance(spec, (tuple, list)) and len(spec) == 2 and isinstance(spec[1], Mapping):
        return check_window(spec[0], **dict(spec[1]))
    raise ValueError(f"a window must be a name or (name, {{params}}), e.g. 'rect' or ('kaiser', {{'beta': 2.5}}), "
                     f"got {spec!r}")


def window_label(name: str, params: Mapping[str, float]) -> str:
    """Short label of a window for titles and metadata: ``"taylor(nbar=4, sll=-35)"``, ``"rect"``."""
    return name if not params else f"{name}(" + ", ".join(f"{k}={v:g}" for k, v in sorted(params.items())) + ")"


def _finite(label: str, value: Any, low: float, high: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"window parameter {label} must be a number in [{low}, {high}], got {value!r}") from None
    if not (np.isfinite(v) and low <= v <= high):
        raise ValueError(f"window parameter {label} must be a finite number in [{low}, {high}], got {value!r}")
    return v


def _key(name: str, params: dict[str, Any]) -> tuple[str, tuple[tuple[str, float], ...]]:
    key, full = check_window(name, **params)
    return key, tuple(sorted(full.items()))


# ============================================================================ windows
def window(name: str, n: int, **params: Any) -> np.ndarray:
    """Sampled symmetric window of ``n`` points (scipy.signal.windows), unit centre value.

    Parameters
    ----------
    name : str
        ``"rect"``, ``"hamming"`` (``alpha``), ``"hann"``, ``"taylor"`` (``nbar``,
        ``sll`` [dB]) or ``"kaiser"`` (``beta``).
    n : int
        Number of samples, >= 1.
    **params
        Window parameters; see :func:`check_window`.

    Returns
    -------
    float64 [n]
        Symmetric window: rect, hamming, hann and kaiser sample ``w(x)`` of the module
        table at ``x = k / (n - 1) - 1/2``; taylor is ``scipy.signal.windows.taylor``
        (``norm=True``), which samples ``x = (k - (n - 1) / 2) / n``.

    Raises
    ------
    ValueError
        Bad name, parameter or ``n``.
    """
    key, full = check_window(name, **params)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"window length n must be an integer >= 1, got {n!r}")
    if key == "rect":
        w = _sw.boxcar(n)
    elif key == "hamming":
        w = _sw.general_hamming(n, full["alpha"])
    elif key == "hann":
        w = _sw.hann(n)
    elif key == "taylor":
        w = _sw.taylor(n, nbar=full["nbar"], sll=-full["sll"], norm=True)
    else:
        w = _sw.kaiser(n, full["beta"])
    return np.asarray(w, dtype=np.float64)


@lru_cache(maxsize=64)
def _cosine_series(key: str, items: tuple[tuple[str, float], ...]) -> np.ndarray | None:
    """Coefficients c_m of w(x) = sum_m c_m cos(2 pi m x), unit centre value; None for kaiser."""
    p = dict(items)
    if key == "rect":
        c = np.array([1.0])
    elif key == "hamming":
        c = np.array([p["alpha"], 1.0 - p["alpha"]])
    elif key == "hann":
        c = np.array([0.5, 0.5])
    elif key == "taylor":
        c = np.concatenate([[1.0], 2.0 * _taylor_coefficients(p["nbar"], -p["sll"])])
        c /= c.sum()
    else:
        return None
    return c


def _taylor_coefficients(nbar: int, sll_db: float) -> np.ndarray:
    """Taylor F_m, m = 1 .. nbar - 1, for sidelobes ``sll_db`` (> 0) below the peak.

    Carrara et al. (1995) eq. (D.6); the same formula as ``scipy.signal.windows.taylor``.
    """
    b = 10.0 ** (sll_db / 20.0)
    a = np.arccosh(b) / np.pi
    s2 = nbar ** 2 / (a ** 2 + (nbar - 0.5) ** 2)
    ma = np.arange(1, nbar, dtype=np.float64)
    fm = np.empty(nbar - 1)
    for i, m in enumerate(ma):
        numer = (-1.0) ** i * np.prod(1.0 - m ** 2 / s2 / (a ** 2 + (ma - 0.5) ** 2))
        others = np.delete(ma, i)
        denom = 2.0 * np.prod(1.0 - m ** 2 / others ** 2)
        fm[i] = numer / denom
    return fm


def spectral_window(name: str, freqs: np.ndarray, bandwidth: float, **params: Any) -> np.ndarray:
    """Window evaluated at arbitrary frequencies: ``w(f / B)`` over ``|f| <= B/2``, 0 outside.

    Parameters
    ----------
    name : str
        Window name; see :func:`check_window`.
    freqs : array_like of float, Hz
        Baseband frequencies (any shape), e.g. ``numpy.fft.fftfreq(n, 1 / fs)``.
    bandwidth : float, Hz
        Processed bandwidth ``B`` > 0.
    **params
        Window parameters.

    Returns
    -------
    float64, same shape as ``freqs``
        ``w(f / B)`` of the module table (unit value at ``f = 0``); 0 where ``|f| > B/2``.

    Raises
    ------
    ValueError
        Bad window, or ``bandwidth`` not finite and positive.
    """
    key, items = _key(name, params)
    b = float(bandwidth)
    if not (np.isfinite(b) and b > 0):
        raise ValueError(f"bandwidth must be a finite positive number of Hz, got {bandwidth!r}")
    x = np.asarray(freqs, dtype=np.float64) / b
    inside = np.abs(x) <= 0.5
    c = _cosine_series(key, items)
    if c is None:
        beta = dict(items)["beta"]
        arg = beta * np.sqrt(np.clip(1.0 - (2.0 * x) ** 2, 0.0, None))
        w = scipy.special.i0(arg) / scipy.special.i0(beta)
    else:
        w = np.zeros_like(x)
        for m, cm in enumerate(c):
            w = w + cm * np.cos(2.0 * np.pi * m * x)
    return np.where(inside, w, 0.0)


def compressed_pulse(t: np.ndarray, bandwidth: float, name: str = "rect", **params: Any) -> np.ndarray:
    """Unit-peak compressed pulse of a windowed rect spectrum, in closed form.

    Parameters
    ----------
    t : array_like of float, s
        Time from the pulse centre (any shape). Pass ``u`` with ``bandwidth=1`` to work
        in units of ``1 / B``.
    bandwidth : float, Hz
        Band ``B`` > 0.
    name : str, default "rect"
        Window applied over the band.
    **params
        Window parameters.

    Returns
    -------
    float64, same shape as ``t``
        ``p(t)`` of the module docstring; real because every window is even. For rect,
        ``sinc(B t)`` (NumPy's normalised sinc).

    Notes
    -----
    Cosine series: ``p(u) = sum_m c_m [sinc(u - m) + sinc(u + m)] / (2 c_0)`` with
    ``u = B t`` (the ``m = 0`` term counted once). Kaiser (Harris 1978):
    ``p(u) = [sinh(z) / z] / [sinh(beta) / beta]``, ``z = sqrt(beta^2 - (pi u)^2)``
    (complex square root; ``sinh(z)/z -> sin|z|/|z|`` past the mainlobe).
    """
    key, items = _key(name, params)
    b = float(bandwidth)
    if not (np.isfinite(b) and b > 0):
        raise ValueError(f"bandwidth must be a finite positive number, got {bandwidth!r}")
    u = np.asarray(t, dtype=np.float64) * b
    c = _cosine_series(key, items)
    if c is None:
        beta = dict(items)["beta"]
        z = np.sqrt(beta ** 2 - (np.pi * u) ** 2 + 0j)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(np.abs(z) < 1e-8, 1.0 + z ** 2 / 6.0, np.sinh(z) / np.where(z == 0, 1.0, z))
        norm = np.sinh(beta) / beta if beta > 0 else 1.0
        return np.real(ratio) / norm
    p = c[0] * np.sinc(u)
    for m, cm in enumerate(c[1:], start=1):
        p = p + 0.5 * cm * (np.sinc(u - m) + np.sinc(u + m))
    return p / c[0]


# ============================================================================ figures (units of 1/B)
@lru_cache(maxsize=64)
def _mean(key: str, items: tuple[tuple[str, float], ...]) -> float:
    """``int_{-1/2}^{1/2} w(x) dx`` of the canonical window ``key`` with parameters ``items``."""
    return scipy.integrate.quad(lambda x: spectral_window(key, x, 1.0, **dict(items)), -0.5, 0.5,
                                epsabs=0, epsrel=1e-13, limit=200)[0]


@lru_cache(maxsize=64)
def _figures(key: str, items: tuple[tuple[str, float], ...]) -> dict[str, float]:
    params = dict(items)

    def p(u):
        return compressed_pulse(u, 1.0, key, **params)

    # first null: first sign change of the (real, even) pulse for u > 0
    u = np.arange(1, 200001) * 1e-4  # up to 20 / B
    values = p(u)
    crossing = np.flatnonzero(np.sign(values[1:]) != np.sign(values[:-1]))
    if crossing.size == 0:
        raise ValueError(f"window {key!r} {params}: no null of the compressed pulse within 20 / B")
    k = crossing[0]
    null = scipy.optimize.brentq(p, u[k], u[k + 1], xtol=1e-13)
    half = scipy.optimize.brentq(lambda x: p(x) ** 2 - 0.5, 1e-9, null, xtol=1e-13)
    # peak sidelobe: dense scan past the null, then a bounded refinement around the max
    us = null + np.arange(1, 400001) * 1e-4  # 40 / B of sidelobes
    power = p(us) ** 2
    j = int(np.argmax(power))
    lo, hi = us[max(j - 1, 0)], us[min(j + 1, us.size - 1)]
    best = scipy.optimize.minimize_scalar(lambda x: -p(x) ** 2, bounds=(lo, hi), method="bounded",
                                          options={"xatol": 1e-12})
    peak_sidelobe = max(float(-best.fun), float(power[j]))
    main = 2.0 * scipy.integrate.quad(lambda x: p(x) ** 2, 0.0, null, epsabs=0, epsrel=1e-12, limit=200)[0]
    # total energy by Parseval: int p^2 du = int w^2 dx / (int w dx)^2 over |x| <= 1/2
    w1 = _mean(key, items)
    w2 = scipy.integrate.quad(lambda x: spectral_window(key, x, 1.0, **params) ** 2, -0.5, 0.5,
                              epsabs=0, epsrel=1e-13, limit=200)[0]
    return {"null": null, "irw": 2.0 * half, "peak_sidelobe": peak_sidelobe, "main": main,
            "total": w2 / w1 ** 2, "mean": w1}


def impulse_response_width(name: str = "rect", **params: Any) -> float:
    """-3 dB width of ``|p|^2`` in units of ``1 / B`` (0.8859 for rect).

    Multiply by ``c / (2 B)`` for slant range [m] or by the azimuth resolution cell.
    Raises ``ValueError`` on a bad window.
    """
    return _figures(*_key(name, params))["irw"]


def broadening_factor(name: str = "rect", **params: Any) -> float:
    """IRW of the window divided by the IRW of rect (``k_w``; Cumming and Wong 2005, section 2.6).

    Returns 1.0 for rect, about 1.177 for Kaiser 2.5, 1.337 for Taylor (4, -35 dB),
    1.471 for Hamming. Raises ``ValueError`` on a bad window.
    """
    return impulse_response_width(name, **params) / impulse_response_width("rect")


def first_null(name: str = "rect", **params: Any) -> float:
    """Distance from the peak to the first null of ``p``, in units of ``1 / B`` (1.0 for rect)."""
    return _figures(*_key(name, params))["null"]


def pslr_theory(name: str = "rect", **params: Any) -> float:
    """Peak sidelobe ratio [dB] of the compressed pulse: highest sidelobe outside the first
    nulls over the peak (-13.26 dB for rect). Raises ``ValueError`` on a bad window."""
    return float(10.0 * np.log10(_figures(*_key(name, params))["peak_sidelobe"]))


def islr_theory(name: str = "rect", sidelobes: float | None = None, **params: Any) -> float:
    """Null-bounded 1-D integrated sidelobe ratio [dB] of the compressed pulse.

    Parameters
    ----------
    name : str
        Window name.
    sidelobes : float, optional
        Sidelobe extent on each side, in first-null distances beyond the first null:
        sidelobes are integrated over ``u1 <= |u| <= (1 + sidelobes) u1`` (ISCE3's
        ``num_sidelobes`` convention). None (default): to infinity.
    **params
        Window parameters.

    Returns
    -------
    float
        ``10 log10(E_side / E_main)`` with ``E_main`` the energy of ``|p|^2`` between the
        first nulls ``|u| <= u1``. Rect: -9.68 dB (infinite), -10.11 dB (``sidelobes=10``).

    Notes
    -----
    The infinite-extent total uses Parseval, ``int p^2 du = int w^2 / (int w)^2``.
    """
    f = _figures(*_key(name, params))
    if sidelobes is None:
        side = f["total"] - f["main"]
    else:
        s = float(sidelobes)
        if not (np.isfinite(s) and s > 0):
            raise ValueError(f"sidelobes must be a positive number of null distances or None, got {sidelobes!r}")
        key, items = _key(name, params)
        outer = f["null"] * (1.0 + s)
        edges = np.arange(f["null"], outer, 0.5)
        edges = np.append(edges, outer)
        side = 2.0 * sum(scipy.integrate.quad(
            lambda x: compressed_pulse(x, 1.0, key, **dict(items)) ** 2, a, b, epsabs=0, epsrel=1e-11)[0]
            for a, b in zip(edges[:-1], edges[1:]) if b > a)
    return float(10.0 * np.log10(side / f["main"]))


def window_mean(name: str = "rect", **params: Any) -> float:
    """Mean of the window over its band, ``int_{-1/2}^{1/2} w(x) dx`` (1 for rect, ``alpha``
    for Hamming): the peak gain of the weighted band relative to rect."""
    return _mean(*_key(name, params))


def energy_width(name: str = "rect", **params: Any) -> float:
    """Energy width ``int |p(u)|^2 du`` of the unit-peak pulse, in units of ``1 / B``.

    1.0 for rect. A point target of amplitude ``a`` imaged with unit-peak pulses in two
    dimensions carries the energy ``|a|^2 * (W_az / B_az) * (W_rg / B_rg)``; this is the
    factor ``W`` (``int w^2 / (int w)^2``, Parseval).
    """
    return _figures(*_key(name, params))["total"]
