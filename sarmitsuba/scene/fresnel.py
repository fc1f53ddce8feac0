"""Reflection coefficients of a vacuum/half-space interface and of a single-layer slab in
vacuum (ITU-R P.2040 section 2.2), and the validation of their arguments.

Plain NumPy (float64/complex128) on the host. :mod:`sarmitsuba.scene.materials` builds materials,
dispatches on their model and polarisation and tabulates the coefficients for the tracer;
it re-exports ``MaterialError``, :func:`fresnel_half_space` and :func:`slab_reflection`.

Conventions
-----------
* Time dependence ``exp(+j omega t)``: lossy media have
  ``Im(eta) < 0`` and waves propagate as ``exp(-j k z)`` (as in P.2040).
* **Sign convention (mirror-image convention).** Each coefficient is the
  ratio of the reflected field component to the *mirror image* (in the
  surface plane) of the incident field component. With this convention a
  perfect conductor has ``r_te = r_tm = -1`` at every angle of incidence
  (the reflected field is minus the mirror image of the incident field), and
  at normal incidence ``r_te = r_tm = (1 - sqrt(eta)) / (1 + sqrt(eta))``
  for any material. ``r_te`` equals P.2040's ``R_eTE`` and Born & Wolf's
  ``r_perp``; ``r_tm`` equals **minus** P.2040's ``R_eTM`` and Born & Wolf's
  ``r_par`` (and minus Sionna RT's ``r_tm``). Magnitudes are identical.
  It was chosen because the tracer multiplies scalar coefficients along a
  path: with it a conducting plate or trihedral gives HH = VV, as it should.
* Polarisation: ``"HH"`` uses ``r_te`` and ``"VV"`` uses ``r_tm``. This is
  the scalar, single-polarisation approximation for a horizontal surface
  seen by a horizontally/vertically polarised antenna: it ignores the
  rotation of the polarisation basis between bounces and any
  cross-polarisation (so, for instance, it does not produce the
  HH = -VV signature of a dihedral).
"""
from __future__ import annotations

import math

import numpy as np

from sarmitsuba.core.constants import SPEED_OF_LIGHT

__all__ = ["MaterialError", "check_cos", "check_eta", "check_frequency", "check_thickness",
           "fresnel_half_space", "slab_reflection"]


class MaterialError(ValueError):
    """Invalid material, frequency or reflection-model argument."""


# --------------------------------------------------------------------------
# Argument validation (shared with sarmitsuba.scene.materials)
# --------------------------------------------------------------------------

def _positive(name: str, value, unit: str, what: str = "") -> float:
    """``value`` as a float; MaterialError naming ``name`` unless it is a finite number > 0."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise MaterialError(f"{name} must be a real number in {unit}, got {value!r}") from None
    if not (math.isfinite(x) and x > 0.0):
        raise MaterialError(f"{name} must be finite and > 0 {unit}{what}, got {value!r}")
    return x


def check_frequency(frequency_hz) -> float:
    """``frequency_hz`` as a float [Hz]; MaterialError unless it is a finite number > 0."""
    return _positive("frequency_hz", frequency_hz, "Hz")


def check_thickness(thickness) -> float:
    """A slab ``thickness`` as a float [m]; MaterialError unless it is a finite number > 0."""
    return _positive("thickness", thickness, "m", " for a slab")


def check_cos(cos_theta) -> np.ndarray:
    """``cos_theta`` as float64 (shape kept); MaterialError unless every value lies in [0, 1]."""
    c = np.asarray(cos_theta, dtype=np.float64)
    bad = ~((c >= 0.0) & (c <= 1.0))  # also catches NaN
    if np.any(bad):
        first = float(c[bad].flat[0])
        raise MaterialError(
            f"cos_theta must lie in [0, 1] (0 = grazing, 1 = normal incidence);"
            f" got {np.count_nonzero(bad)} value(s) outside, e.g. {first!r}."
            " Use |dot(wi, n)| and clip float32 round-off before calling.")
    return c


def check_eta(eta) -> np.ndarray:
    """``eta`` as complex128 (shape kept); MaterialError unless finite, non-zero and passive (``Im <= 0``)."""
    try:
        e = np.asarray(eta, dtype=np.complex128)
    except (TypeError, ValueError):
        raise MaterialError(
            f"relative permittivity eta must be a complex number, got {eta!r}"
            " (a perfect conductor is Material.pec(), not eta=None)") from None
    bad = ~np.isfinite(e) | (e.imag > 0.0) | (e == 0.0)
    if np.any(bad):
        first = complex(e[bad].flat[0])
        raise MaterialError(
            "relative permittivity eta must be finite, non-zero and passive, "
            "Im(eta) <= 0 (eta = eps_r - j sigma/(omega eps_0), exp(+j omega t)"
            f" convention); got {first!r}")
    return e


# --------------------------------------------------------------------------
# Reflection coefficients
# --------------------------------------------------------------------------

#: cos_theta below this is treated as exactly grazing (0): its square would
#: underflow and complex division by subnormals overflows.
_COS_FLUSH = 1e-150


def _prepare(cos_theta, eta) -> tuple[np.ndarray, np.ndarray]:
    """Validate, broadcast, and flush ``cos_theta < 1e-150`` to 0."""
    c = check_cos(cos_theta)
    e = check_eta(eta)
    c, e = np.broadcast_arrays(c, e)
    return np.where(c < _COS_FLUSH, 0.0, c), e


def _normal_root(cos_theta: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """``sqrt(eta - sin^2 theta)`` on the branch with ``Im <= 0``.

    This is ``n cos(theta_t)``, the normal wavenumber in the medium in units
    of k0. The branch ``Im <= 0`` makes the transmitted wave decay
    (``exp(-j k0 s z)``) and gives ``Re >= 0`` for passive media. The signed
    zero forces ``sqrt(-x + 0j)`` onto ``-j sqrt(x)``.
    """
    # eta - sin^2 = (eta - 1) + cos^2: exact for eta = 1 (s = cos) and free of
    # cancellation near grazing incidence when eta is close to 1.
    w = np.array((eta - 1.0) + cos_theta * cos_theta, dtype=np.complex128, copy=True)
    w.imag = -np.abs(w.imag)
    return np.sqrt(w)


def _ratio(num: np.ndarray, den: np.ndarray, fill) -> np.ndarray:
    """num / den, with ``fill`` where den == 0 exactly."""
    zero = den == 0
    with np.errstate(divide="ignore", invalid="ignore"):
        out = num / np.where(zero, 1.0, den)
    return np.where(zero, fill, out)


def fresnel_half_space(cos_theta, eta) -> tuple[np.ndarray, np.ndarray]:
    """Fresnel reflection coefficients of a vacuum/half-space interface.

    Parameters
    ----------
    cos_theta : array_like of float, in [0, 1]
        Cosine of the angle of incidence from the surface normal
        (1 = normal incidence, 0 = grazing).
    eta : complex or array_like of complex
        Relative permittivity of the half-space, ``Im(eta) <= 0``;
        broadcast against ``cos_theta``.

    Returns
    -------
    r_te, r_tm : ndarray of complex128, shape ``broadcast(cos_theta, eta)``
        Reflection coefficients for TE (E perpendicular to the plane of
        incidence) and TM, in the mirror-image sign convention of this module
        (``r_tm`` is minus P.2040's ``R_eTM``). ``|r| <= 1``.

    Notes
    -----
    With :math:`s = \\sqrt{\\eta - \\sin^2\\theta}` (``Im s <= 0``),

    .. math:: r_{TE} = \\frac{\\cos\\theta - s}{\\cos\\theta + s}, \\qquad
              r_{TM} = \\frac{s/\\eta - \\cos\\theta}{s/\\eta + \\cos\\theta}
                     = -\\frac{\\eta\\cos\\theta - s}{\\eta\\cos\\theta + s}.

    These are Born & Wolf, *Principles of Optics*, §1.5.2, eq. (21) for
    non-magnetic media, and ITU-R P.2040 §2.2.1.5 (incident wave in air;
    eqs. (37a)/(37b) in the numbering Sionna RT cites), with ``r_tm``
    multiplied by -1 (see the module docstring). Writing ``r_tm`` with the
    TM surface impedance ``s/eta`` (``Re >= 0`` for passive media) makes
    ``|r| <= 1`` hold to rounding error even for ``|eta| ~ 1e10``.
    At ``cos_theta = 0`` (grazing), ``r_te = -1`` and ``r_tm = +1`` for any
    ``eta != 1`` (the reflected field cancels the incident one); for
    ``eta == 1`` there is no interface and both are 0.

    Examples
    --------
    >>> r_te, r_tm = fresnel_half_space(1.0, 4.0)
    >>> float(r_te.real), float(r_tm.real)
    (-0.3333333333333333, -0.3333333333333333)
    """
    c, e = _prepare(cos_theta, eta)
    (r_te, _), (r_tm, _) = _interface_terms(c, _normal_root(c, e), e)
    return r_te, r_tm


def _interface_terms(c: np.ndarray, s: np.ndarray, e: np.ndarray):
    """``(r, 1 - r**2)`` for TE and TM, without cancellation.

    With impedance-like ``p`` (``s`` for TE; TM surface impedance ``s/eta``
    in units of Z0), ``r_te = (c - p)/(c + p)`` and ``r_tm = (p - c)/(p + c)``,
    and ``1 - r**2 = (2c/(c+p)) (2p/(c+p))`` is accurate even where
    ``|r| -> 1`` (grazing). At ``c = p = 0`` (``eta = 1``, grazing):
    ``r = 0``, ``1 - r**2 = 1``.
    """
    out = []
    for p, sign in ((s, 1.0), (s / e, -1.0)):
        r = sign * _ratio(c - p, c + p, 0.0)
        g = _ratio(2.0 * c, c + p, 1.0) * _ratio(2.0 * p, c + p, 1.0)
        out.append((r.astype(np.complex128), g.astype(np.complex128)))
    return out


def _one_minus_exp(x: np.ndarray) -> np.ndarray:
    """``1 - exp(x)`` for complex ``x`` without cancellation near 0."""
    a, b = x.real, x.imag
    expm1 = np.expm1(a) * np.cos(b) - 2.0 * np.sin(0.5 * b) ** 2 \
        + 1j * np.exp(a) * np.sin(b)
    return -expm1


def slab_reflection(cos_theta, eta, thickness, frequency_hz
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Reflection coefficients of a homogeneous slab in vacuum.

    Parameters
    ----------
    cos_theta : array_like of float, in [0, 1]
        Cosine of the angle of incidence (1 = normal, 0 = grazing).
    eta : complex or array_like of complex
        Relative permittivity of the slab, ``Im(eta) <= 0``; broadcast.
    thickness : float
        Slab thickness d [m], > 0.
    frequency_hz : float
        Frequency [Hz], > 0.

    Returns
    -------
    r_te, r_tm : ndarray of complex128, shape ``broadcast(cos_theta, eta)``
        Slab reflection coefficients, same sign convention as
        :func:`fresnel_half_space` (``r_tm`` is minus P.2040's ``R_TM``).

    Notes
    -----
    ITU-R P.2040 §2.2.2.2 (simplified method for a single-layer slab),
    eqs. (43a) and (44):

    .. math:: R = \\frac{R' (1 - e^{-j2q})}{1 - R'^2 e^{-j2q}}, \\qquad
              q = \\frac{2\\pi d}{\\lambda}\\sqrt{\\eta - \\sin^2\\theta},

    where :math:`R'` is the half-space coefficient of the same polarisation.
    The formula is odd in :math:`R'`, so the TM sign convention carries
    over. The branch ``Im(q) <= 0`` keeps :math:`|e^{-j2q}| <= 1`, so thick
    lossy slabs tend to the half-space (``exp`` underflows to 0, no
    overflow). It is evaluated in the algebraically identical form

    .. math:: R = R' \\frac{D}{D + (1 - R'^2) e^{-j2q}}, \\qquad
              D = 1 - e^{-j2q},

    with :math:`D` from ``expm1`` and :math:`1 - R'^2` from
    :math:`(1 - R')(1 + R')`, which avoids the cancellation of the direct
    form for electrically thin slabs and near grazing incidence (where
    :math:`R' \\to \\mp 1`), keeping :math:`|R| \\le 1` to rounding error.
    Where the denominator vanishes exactly (lossless slab at grazing
    incidence on a Fabry-Perot resonance, a 0/0 case) ``R'`` is returned.
    """
    c, e = _prepare(cos_theta, eta)
    d = check_thickness(thickness)
    f = check_frequency(frequency_hz)
    s = _normal_root(c, e)
    q = (2.0 * math.pi * f * d / SPEED_OF_LIGHT) * s  # eq. (44)
    phase = np.exp(-2j * q)
    one_minus_phase = _one_minus_exp(-2j * q)
    out = []
    for r, g in _interface_terms(c, s, e):  # eq. (43a), rearranged
        out.append(r * _ratio(one_minus_phase, one_minus_phase + g * phase, 1.0))
    return out[0].astype(np.complex128), out[1].astype(np.complex128)
