"""The grazing wave across a face of finite conductivity: Norton's ground-wave attenuation,
the weight of the double diffraction across a face, docs/physics.md (E6).

Edge 1 diffracts a wave that grazes the face toward edge 2. Over a perfect conductor it arrives
whole; over a surface of normalised impedance ``Delta`` the direct and reflected grazing waves
cancel and what arrives is the ground wave, the free wave times Norton's attenuation function
``F(w)`` of the numerical distance ``w = -j k d Delta^2 / 2`` over the path length ``d``
(Norton, Proc. IRE 24(10), 1936 and 25(9), 1937; Wait, IEEE Antennas Propag. Mag. 40(5), 1998):

* :func:`norton_attenuation` -- ``F(w) = 1 - j sqrt(pi w) exp(-w) erfc(j sqrt(w))``, through
  Faddeeva's function (:func:`scipy.special.wofz`): the NumPy reference;
* :func:`grazing_weight` -- ``F`` for a face's ``Delta`` and ``k d``;
* :func:`grazing_table` -- the per-row table in ``log10 |w|`` the Dr.Jit kernel interpolates
  (:func:`lookup`), tested against :func:`grazing_weight`.

A good conductor (``|Delta|`` about 2e-4 for ITU metal at X band) keeps ``|F|`` within 0.1 % of 1
across a hundred metres, as ``pec`` does; a dielectric (``|Delta|`` about 0.4) keeps a fifth of the
wave across four wavelengths and none across a wall: ``F -> -1 / (2 w)``.

Time dependence ``exp(+j omega t)``.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import wofz

__all__ = ["LOG_RANGE", "PER_DECADE", "N_SAMPLES", "norton_attenuation", "numerical_distance", "grazing_weight",
           "unlit_tm", "grazing_table", "table_tangent", "lookup"]

#: The table's span in ``log10 |w|``: below 1e-8, ``1 - F`` is under 2e-4; above 1e6, ``|F|`` is
#: under 1e-6 (the last sample is used beyond either end).
LOG_RANGE = (-8.0, 6.0)
#: Samples per decade of ``|w|``: linear interpolation of ``F`` in ``log |w|`` within 1e-3.
PER_DECADE = 16
#: Samples per material row of :func:`grazing_table`.
N_SAMPLES = int(round((LOG_RANGE[1] - LOG_RANGE[0]) * PER_DECADE)) + 1


def norton_attenuation(w) -> np.ndarray:
    """Norton's attenuation function ``F(w) = 1 - j sqrt(pi w) exp(-w) erfc(j sqrt(w))`` (complex128,
    shape of ``w``), with ``exp(-w) erfc(j sqrt(w)) = wofz(-sqrt(w))`` (principal root). A passive
    half space puts ``w`` in ``-pi <= arg w <= 0`` (on the positive real axis for a good conductor,
    the negative imaginary one for a lossless dielectric), where ``-sqrt(w)`` lies in the upper
    half plane and ``wofz`` is bounded. ``F -> 1`` as ``w -> 0`` and ``-1 / (2 w) - 3 / (4 w^2)``
    as ``|w| -> oo``."""
    root = np.sqrt(np.asarray(w, np.complex128))
    return 1.0 - 1j * np.sqrt(np.pi) * root * wofz(-root)


def numerical_distance(delta, k_distance) -> np.ndarray:
    """Norton's numerical distance ``w = -j k d Delta^2 / 2`` (complex128) of a grazing path of
    ``k d`` radians over a surface of normalised impedance ``delta``
    (:func:`sarmitsuba.scene.materials.grazing_impedance`)."""
    delta = np.asarray(delta, np.complex128)
    return -0.5j * np.asarray(k_distance, float) * delta * delta


def grazing_weight(delta, k_distance) -> np.ndarray:
    """The grazing wave's share at the end of a path of ``k d`` radians across a face of normalised
    impedance ``delta``, relative to a perfect conductor's: ``F(w)`` (complex128); exactly 1 for
    ``delta = 0``. Docs/physics.md (E6)."""
    return norton_attenuation(numerical_distance(delta, k_distance))


def unlit_tm(delta, k_distance) -> np.ndarray:
    """The TM reflection coefficient at grazing that a face of normalised impedance ``delta``
    presents over ``k d`` radians, ``1 - 2 F(w)`` (complex128; the mirror-image convention, -1 on
    a perfect conductor): what a wedge's face the wave does not reach contributes to Keller's
    coefficient (E2). ``(1 - r) / 2 = F`` is the grazing wave's share (E6); as ``k d -> oo`` it
    tends to the exact-grazing ``+1`` of every finite impedance, as ``delta -> 0`` to ``-1``."""
    return 1.0 - 2.0 * grazing_weight(delta, k_distance)


def grazing_table(deltas) -> tuple[np.ndarray, np.ndarray]:
    """Each material row's ``F`` sampled in ``log10 |w|`` for the kernel.

    Parameters
    ----------
    deltas : complex [n_rows]
        Each row's normalised surface impedance at grazing.

    Returns
    -------
    offset : float32 [n_rows]
        ``log10 |Delta^2 / 2|``: ``log10 |w| = log10(k d) + offset`` (0 for a perfect conductor).
    table : complex64 [n_rows, n]
        ``F`` at ``|w| = 10^(LOG_RANGE[0] + i / PER_DECADE)`` along the row's phase of ``w``; all
        ones for a perfect conductor.
    """
    deltas = np.atleast_1d(np.asarray(deltas, np.complex128))
    scale = 0.5 * deltas * deltas
    n = N_SAMPLES
    magnitude = 10.0 ** (LOG_RANGE[0] + np.arange(n) / PER_DECADE)
    table = np.ones((deltas.size, n), np.complex128)
    offset = np.zeros(deltas.size)
    for row in np.flatnonzero(scale != 0):
        offset[row] = math.log10(abs(scale[row]))
        table[row] = norton_attenuation(-1j * scale[row] / abs(scale[row]) * magnitude)
    return offset.astype(np.float32), table.astype(np.complex64)


def table_tangent(delta, d_ln_delta) -> tuple[float, np.ndarray]:
    """The derivative of one row of :func:`grazing_table` when ``ln Delta`` moves by
    ``d_ln_delta`` (complex): ``(d offset, d table)`` (float, complex128 [n]). ``w = c |w| / |c|``
    with ``c = -j Delta^2 / 2``: the offset moves by ``Re(d ln c) / ln 10`` and each sample, at its
    fixed ``|w|``, by ``F'(w) w j Im(d ln c)``, with ``F'(w) = (F - 1)(1 / (2 w) - 1) - 1`` (from
    ``d/dw exp(-w) erfc(j sqrt w) = -exp(-w) erfc(j sqrt w) - j / sqrt(pi w)``). Zero for a perfect
    conductor, whose row is all ones."""
    delta = complex(delta)
    n = N_SAMPLES
    if delta == 0:
        return 0.0, np.zeros(n, np.complex128)
    d_ln_c = 2.0 * complex(d_ln_delta)
    c = -0.5j * delta * delta
    w = c / abs(c) * 10.0 ** (LOG_RANGE[0] + np.arange(n) / PER_DECADE)
    f = norton_attenuation(w)
    slope = (f - 1.0) * (0.5 / w - 1.0) - 1.0
    return d_ln_c.real / math.log(10.0), slope * w * 1j * d_ln_c.imag


def lookup(offset, table_re, table_im, row, k_distance, sinks=(None, None, None)):
    """The Dr.Jit evaluation of :func:`grazing_weight` from :func:`grazing_table` (flattened
    ``table_re``, ``table_im`` as ``mi.Float``): ``F`` of each lane's material ``row``
    (``mi.UInt32``) over ``k_distance`` (``mi.Float``, > 0), linear in ``log10 |w|``; a
    ``mi.Complex2f``. ``sinks``: the three tables' reverse-mode sinks
    (:class:`sarmitsuba.tracing.deposit.adjoint.AdjointSink`, or None), docs/physics.md (D7)."""
    import drjit as dr
    import mitsuba as mi
    from ..deposit.adjoint import read
    n = N_SAMPLES
    u = (dr.log2(dr.maximum(k_distance, 1e-30)) * math.log10(2.0) + read(offset, row, True, sinks[0])
         - LOG_RANGE[0]) * PER_DECADE
    u = dr.clip(u, 0.0, n - 1.0)
    i = dr.minimum(mi.UInt32(dr.floor(u)), n - 2)
    t = u - mi.Float(i)
    at = row * n + i
    re = dr.lerp(read(table_re, at, True, sinks[1]), read(table_re, at + 1, True, sinks[1]), t)
    im = dr.lerp(read(table_im, at, True, sinks[2]), read(table_im, at + 1, True, sinks[2]), t)
    return mi.Complex2f(re, im)
