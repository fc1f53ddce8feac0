"""Radio materials: ITU-R P.2040 permittivities and reflection coefficients.

Everything here is plain NumPy (float64/complex128) and runs on the host. A
Dr.Jit kernel uses it through :func:`reflection_table`, a complex64 lookup
table of the reflection coefficient sampled uniformly in cos(theta), which the
kernel interpolates linearly (:func:`interpolate_table` is the NumPy
reference of that interpolation).

Public API
----------
MaterialError
    ``ValueError`` for unknown materials, out-of-range frequencies and bad
    arguments.
Material
    Frozen dataclass: name, complex relative permittivity, model
    (``"half_space"``, ``"slab"`` or ``"pec"``) and slab thickness.
itu_material_names, itu_valid_ranges, itu_permittivity
    The ITU-R P.2040 Table 3 material models.
fresnel_half_space, slab_reflection
    Reflection coefficients of a vacuum/half-space interface and of a
    single-layer slab in vacuum.
reflection_coefficient
    Dispatch on ``Material.model`` and on the polarisation (HH -> TE,
    VV -> TM).
reflection_table, interpolate_table, table_error_bound
    Lookup table for the tracer, its interpolation and its error.

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
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sarmitsuba.constants import SPEED_OF_LIGHT, VACUUM_PERMITTIVITY

__all__ = [
    "MaterialError",
    "Material",
    "ITU_MATERIALS",
    "itu_material_names",
    "itu_valid_ranges",
    "itu_permittivity",
    "fresnel_half_space",
    "slab_reflection",
    "reflection_coefficient",
    "reflection_table",
    "interpolate_table",
    "table_error_bound",
]

#: ITU-R P.2040 material models: name -> rows of
#: ``(f_min [GHz], f_max [GHz], a, b, c, d)`` with
#: ``eps_r = a * f_GHz**b`` and ``sigma = c * f_GHz**d`` [S/m].
#: Source: ITU-R P.2040-3, Annex 1, Table 3, with the additional rows of
#: P.2040-4 (100-450 GHz fits, acrylic, tiles, asphalt) as tabulated by
#: Sionna RT 2.2 (``sionna/rt/radio_materials/itu.py``), whose names this
#: table matches. Where ranges overlap, the first matching row applies (as in
#: Sionna). The ground types are defined for 1-10 GHz only.
ITU_MATERIALS: dict[str, tuple[tuple[float, float, float, float, float, float], ...]] = {
    "vacuum": ((0.001, 100.0, 1.0, 0.0, 0.0, 0.0),),
    "concrete": ((1.0, 100.0, 5.24, 0.0, 0.0462, 0.7822),
                 (110.0, 330.0, 5.17, 0.0, 0.0145, 1.0900)),
    "brick": ((1.0, 40.0, 3.91, 0.0, 0.0238, 0.16),
              (110.0, 330.0, 4.15, 0.0, 0.0006, 1.5712)),
    "plasterboard": ((1.0, 100.0, 2.73, 0.0, 0.0085, 0.9395),
                     (110.0, 330.0, 2.56, 0.0, 0.0001, 1.7799),
                     (100.0, 400.0, 2.65, 0.0, 0.0002, 1.598)),
    "wood": ((0.001, 100.0, 1.99, 0.0, 0.0047, 1.0718),
             (110.0, 330.0, 1.82, 0.0, 0.0040, 1.0761),
             (100.0, 400.0, 2.1183, 0.0, 0.0055, 1.1113)),
    "glass": ((0.1, 100.0, 6.31, 0.0, 0.0036, 1.3394),
              (220.0, 450.0, 5.79, 0.0, 0.0004, 1.658),
              (100.0, 400.0, 6.5767, 0.0, 0.0012, 1.4697)),
    "clear_acrylic": ((110.0, 330.0, 2.58, 0.0, 0.0001, 1.6524),),
    "ceiling_board": ((1.0, 100.0, 1.48, 0.0, 0.0011, 1.0750),
                      (220.0, 450.0, 1.52, 0.0, 0.0029, 1.029),
                      (100.0, 400.0, 1.2567, 0.0, 0.00013, 1.454)),
    "chipboard": ((1.0, 100.0, 2.58, 0.0, 0.0217, 0.7800),
                  (100.0, 200.0, 2.16, 0.0, 0.0023, 1.359)),
    "plywood": ((1.0, 40.0, 2.71, 0.0, 0.33, 0.0),
                (110.0, 330.0, 1.94, 0.0, 0.0067, 0.9982),
                (100.0, 400.0, 2.17, 0.0, 0.0063, 1.045)),
    "marble": ((1.0, 60.0, 7.074, 0.0, 0.0055, 0.9262),
               (110.0, 330.0, 7.94, 0.0, 0.0001, 1.7330),
               (100.0, 400.0, 8.62, 0.0, 0.0027, 1.15)),
    "floorboard": ((50.0, 100.0, 3.66, 0.0, 0.0044, 1.3515),
                   (220.0, 300.0, 5.27, 0.0, 2.22e-17, 7.3413),
                   (300.0, 400.0, 5.27, 0.0, 0.0003, 2.0298),
                   (400.0, 450.0, 5.27, 0.0, 49.8726, 0.0),
                   (100.0, 400.0, 3.1575, 0.0, 0.001675, 1.32775)),
    "vinyl_tile": ((1.0, 40.0, 3.62, 0.0, 0.0051, 0.8422),),
    "carpet_tile": ((1.0, 40.0, 2.08, 0.0, 0.0009, 0.8200),),
    "asphalt_concrete": ((1.0, 40.0, 4.83, 0.0, 0.0108, 1.3969),),
    "metal": ((1.0, 100.0, 1.0, 0.0, 1e7, 0.0),),
    "very_dry_ground": ((1.0, 10.0, 3.0, 0.0, 0.00015, 2.52),),
    "medium_dry_ground": ((1.0, 10.0, 15.0, -0.1, 0.035, 1.63),),
    "wet_ground": ((1.0, 10.0, 30.0, -0.4, 0.15, 1.30),),
}

Model = Literal["half_space", "slab", "pec"]
_MODELS = ("half_space", "slab", "pec")
_POLARIZATIONS = {"HH": "te", "TE": "te", "VV": "tm", "TM": "tm"}


class MaterialError(ValueError):
    """Invalid material, frequency or reflection-model argument."""


# --------------------------------------------------------------------------
# Argument validation
# --------------------------------------------------------------------------

def _check_frequency(frequency_hz) -> float:
    try:
        f = float(frequency_hz)
    except (TypeError, ValueError):
        raise MaterialError(
            f"frequency_hz must be a real number in Hz, got {frequency_hz!r}") from None
    if not (math.isfinite(f) and f > 0.0):
        raise MaterialError(
            f"frequency_hz must be finite and > 0 Hz, got {frequency_hz!r}")
    return f


def _check_thickness(thickness) -> float:
    try:
        d = float(thickness)
    except (TypeError, ValueError):
        raise MaterialError(
            f"thickness must be a real number in metres, got {thickness!r}") from None
    if not (math.isfinite(d) and d > 0.0):
        raise MaterialError(
            f"thickness must be finite and > 0 m for a slab, got {thickness!r}")
    return d


def _check_cos(cos_theta) -> np.ndarray:
    c = np.asarray(cos_theta, dtype=np.float64)
    bad = ~((c >= 0.0) & (c <= 1.0))  # also catches NaN
    if np.any(bad):
        first = float(c[bad].flat[0])
        raise MaterialError(
            f"cos_theta must lie in [0, 1] (0 = grazing, 1 = normal incidence);"
            f" got {np.count_nonzero(bad)} value(s) outside, e.g. {first!r}."
            " Use |dot(wi, n)| and clip float32 round-off before calling.")
    return c


def _check_eta(eta) -> np.ndarray:
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


def _check_polarization(polarization) -> str:
    key = str(polarization).upper()
    if key not in _POLARIZATIONS:
        raise MaterialError(
            f"polarization must be one of 'HH', 'VV' (or 'TE', 'TM'); got "
            f"{polarization!r}. Cross-polarised terms are zero in this scalar "
            "model.")
    return _POLARIZATIONS[key]


# --------------------------------------------------------------------------
# ITU-R P.2040 materials
# --------------------------------------------------------------------------

def itu_material_names() -> tuple[str, ...]:
    """Names accepted by :func:`itu_permittivity` (sorted).

    Returns
    -------
    tuple of str
        The same names as Sionna RT's ``itu-radio-material`` ``type``.
    """
    return tuple(sorted(ITU_MATERIALS))


def _lookup(name: str) -> tuple:
    if name not in ITU_MATERIALS:
        raise MaterialError(
            f"unknown ITU material {name!r}; valid names are: "
            f"{', '.join(itu_material_names())}")
    return ITU_MATERIALS[name]


def itu_valid_ranges(name: str) -> tuple[tuple[float, float], ...]:
    """Frequency ranges [GHz] in which an ITU material model is defined.

    Parameters
    ----------
    name : str
        ITU material name, see :func:`itu_material_names`.

    Returns
    -------
    tuple of (float, float)
        ``(f_min, f_max)`` in GHz, inclusive, in table order.
    """
    return tuple((row[0], row[1]) for row in _lookup(name))


def itu_permittivity(name: str, frequency_hz: float) -> complex:
    """Complex relative permittivity of an ITU-R P.2040 material.

    Parameters
    ----------
    name : str
        ITU material name (``"concrete"``, ``"brick"``, ``"metal"``, ...;
        see :func:`itu_material_names`).
    frequency_hz : float
        Frequency [Hz]; must lie in one of the material's valid ranges.

    Returns
    -------
    complex
        ``eta = eps_r - j sigma / (omega eps_0)`` (dimensionless).

    Raises
    ------
    MaterialError
        Unknown name (the message lists the valid names) or frequency
        outside the material's valid ranges (the message names them).

    Notes
    -----
    ITU-R P.2040-3, Annex 1, §2.1.4 and Table 3:

    .. math:: \\varepsilon_r = a f_\\mathrm{GHz}^b, \\quad
              \\sigma = c f_\\mathrm{GHz}^d \\ [\\mathrm{S/m}], \\quad
              \\eta = \\varepsilon_r - j\\frac{\\sigma}{2\\pi f \\varepsilon_0}.

    Examples
    --------
    >>> eta = itu_permittivity("concrete", 9.6e9)
    >>> round(eta.real, 2), round(eta.imag, 3)
    (5.24, -0.507)
    """
    rows = _lookup(name)
    f = _check_frequency(frequency_hz)
    f_ghz = f / 1e9
    for f_min, f_max, a, b, c, d in rows:
        if f_min <= f_ghz <= f_max:
            eps_r = a * f_ghz ** b
            sigma = c * f_ghz ** d
            return complex(eps_r, -sigma / (2.0 * math.pi * f * VACUUM_PERMITTIVITY))
    ranges = ", ".join(f"{lo:g}-{hi:g} GHz" for lo, hi in itu_valid_ranges(name))
    raise MaterialError(
        f"ITU material {name!r} is defined for {ranges} (ITU-R P.2040 Table 3);"
        f" got frequency_hz={f:g} ({f_ghz:g} GHz)")


# --------------------------------------------------------------------------
# Material container
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class Material:
    """A radio material as seen by the tracer.

    Attributes
    ----------
    name : str
        Label (e.g. the ITU name or the scene's material id).
    relative_permittivity : complex or None
        ``eta = eps_r - j sigma/(omega eps_0)`` at the frequency of use
        (dimensionless, ``Im <= 0``); ``None`` for a perfect conductor.
    model : {"half_space", "slab", "pec"}
        ``"half_space"``: Fresnel coefficients of a semi-infinite medium.
        ``"slab"``: a homogeneous slab of ``thickness`` in vacuum
        (ITU-R P.2040 eqs. (43)/(44); what Sionna RT uses for every
        material). ``"pec"``: perfect conductor, ``r = -1``.
    thickness : float or None
        Slab thickness [m], > 0; required for ``"slab"``, ``None`` otherwise.

    Raises
    ------
    MaterialError
        If the fields are inconsistent with the model.
    """

    name: str
    relative_permittivity: complex | None
    model: Model = "half_space"
    thickness: float | None = None

    def __post_init__(self):
        if self.model not in _MODELS:
            raise MaterialError(
                f"Material {self.name!r}: model must be one of {_MODELS}, "
                f"got {self.model!r}")
        if self.model == "pec":
            if self.relative_permittivity is not None or self.thickness is not None:
                raise MaterialError(
                    f"Material {self.name!r}: a 'pec' material takes "
                    "relative_permittivity=None and thickness=None, got "
                    f"{self.relative_permittivity!r} and {self.thickness!r}")
            return
        if self.relative_permittivity is None:
            raise MaterialError(
                f"Material {self.name!r}: model {self.model!r} needs a complex "
                "relative_permittivity (use model='pec' for a perfect conductor)")
        eta = complex(_check_eta(self.relative_permittivity))
        object.__setattr__(self, "relative_permittivity", eta)
        if self.model == "slab":
            object.__setattr__(self, "thickness", _check_thickness(self.thickness))
        elif self.thickness is not None:
            raise MaterialError(
                f"Material {self.name!r}: thickness is only used by model='slab'"
                f" (got thickness={self.thickness!r} with model='half_space')")

    @classmethod
    def itu(cls, name: str, frequency_hz: float, model: Model = "slab",
            thickness: float | None = 0.1) -> "Material":
        """ITU-R P.2040 material evaluated at ``frequency_hz``.

        Parameters
        ----------
        name : str
            ITU material name (:func:`itu_material_names`).
        frequency_hz : float
            Frequency [Hz] at which the permittivity is evaluated.
        model : {"slab", "half_space"}
            Reflection model; the default slab of 0.1 m matches Sionna RT's
            ``itu-radio-material`` default (``DEFAULT_THICKNESS = 0.1``).
        thickness : float or None
            Slab thickness [m]; ignored (set to None) for ``"half_space"``.
        """
        if model == "pec":
            raise MaterialError(
                f"Material.itu({name!r}): use Material.pec() for a perfect "
                "conductor; ITU materials take model='slab' or 'half_space'")
        eta = itu_permittivity(name, frequency_hz)
        return cls(name, eta, model, thickness if model == "slab" else None)

    @classmethod
    def pec(cls, name: str = "pec") -> "Material":
        """Perfect electric conductor (``r_te = r_tm = -1``)."""
        return cls(name, None, "pec", None)


# --------------------------------------------------------------------------
# Reflection coefficients
# --------------------------------------------------------------------------

#: cos_theta below this is treated as exactly grazing (0): its square would
#: underflow and complex division by subnormals overflows.
_COS_FLUSH = 1e-150


def _prepare(cos_theta, eta) -> tuple[np.ndarray, np.ndarray]:
    """Validate, broadcast, and flush ``cos_theta < 1e-150`` to 0."""
    c = _check_cos(cos_theta)
    e = _check_eta(eta)
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
    d = _check_thickness(thickness)
    f = _check_frequency(frequency_hz)
    s = _normal_root(c, e)
    q = (2.0 * math.pi * f * d / SPEED_OF_LIGHT) * s  # eq. (44)
    phase = np.exp(-2j * q)
    one_minus_phase = _one_minus_exp(-2j * q)
    out = []
    for r, g in _interface_terms(c, s, e):  # eq. (43a), rearranged
        out.append(r * _ratio(one_minus_phase, one_minus_phase + g * phase, 1.0))
    return out[0].astype(np.complex128), out[1].astype(np.complex128)


def reflection_coefficient(material: Material, cos_theta, frequency_hz: float,
                           polarization: str) -> np.ndarray:
    """Reflection coefficient of a material for one polarisation.

    Parameters
    ----------
    material : Material
        Dispatches on ``material.model``.
    cos_theta : array_like of float, in [0, 1]
        Cosine of the angle of incidence (1 = normal, 0 = grazing).
    frequency_hz : float
        Frequency [Hz], > 0 (used by the slab phase; validated for all).
    polarization : {"HH", "VV", "TE", "TM"}
        ``"HH"`` -> TE, ``"VV"`` -> TM: the scalar single-polarisation
        approximation for a horizontal surface (see module docstring).

    Returns
    -------
    ndarray of complex128, shape of ``cos_theta``
        ``r`` in the mirror-image convention; ``-1`` for ``"pec"``.
    """
    if not isinstance(material, Material):
        raise MaterialError(
            f"material must be a sarmitsuba.materials.Material, got "
            f"{type(material).__name__}")
    pol = _check_polarization(polarization)
    c = _check_cos(cos_theta)
    f = _check_frequency(frequency_hz)
    if material.model == "pec":
        return np.full(c.shape, -1.0 + 0.0j, dtype=np.complex128)
    if material.model == "half_space":
        r_te, r_tm = fresnel_half_space(c, material.relative_permittivity)
    else:
        r_te, r_tm = slab_reflection(c, material.relative_permittivity,
                                     material.thickness, f)
    return r_te if pol == "te" else r_tm


# --------------------------------------------------------------------------
# Lookup table for the Dr.Jit kernel
# --------------------------------------------------------------------------

def reflection_table(material: Material, frequency_hz: float, polarization: str,
                     n: int = 257) -> np.ndarray:
    """Sample ``r(cos_theta)`` on a uniform grid for linear interpolation.

    Parameters
    ----------
    material : Material
    frequency_hz : float
        Frequency [Hz], > 0.
    polarization : {"HH", "VV", "TE", "TM"}
    n : int
        Number of samples, >= 2; sample ``i`` is at
        ``cos_theta = i / (n - 1)``.

    Returns
    -------
    ndarray of complex64, shape [n]
        ``r(i / (n - 1))``; a kernel evaluates ``r`` at ``u = cos_theta *
        (n - 1)`` as ``(1 - t) T[i] + t T[i + 1]``, ``i = min(floor(u),
        n - 2)``, ``t = u - i`` (see :func:`interpolate_table`).

    Notes
    -----
    The linear-interpolation error is at most ``h**2 / 8 * max |r''|`` with
    ``h = 1 / (n - 1)``, plus ~6e-8 from the complex64 rounding. It is small
    for smooth cases (brick or concrete slab of 0.1 m at 9.6 GHz, n = 257:
    < 1e-4) but grows where ``r`` varies fast in ``cos_theta``: near grazing
    for ``eta`` close to 1 (``r`` goes from -1 to ~0 over
    ``cos_theta ~ sqrt(|eta - 1|)``), for thick slabs (Fabry-Perot
    oscillations, about ``2 d f sqrt(Re eta) / c`` periods over [0, 1]) and,
    above all, for TM on good conductors: ``r_tm`` swings from +1 at
    grazing to about -1 within ``cos_theta ~ 1/sqrt|eta|`` (pseudo-Brewster
    angle; 5e-5 for ITU metal at 9.6 GHz), which no uniform table resolves:
    the error there is O(1) but confined to the first table interval(s).
    :func:`table_error_bound` measures it for a given material, optionally
    excluding a grazing band with ``cos_min``.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise MaterialError(f"n must be an integer >= 2, got {n!r}")
    cos = np.linspace(0.0, 1.0, int(n))
    r = reflection_coefficient(material, cos, frequency_hz, polarization)
    return r.astype(np.complex64)


def interpolate_table(table, cos_theta) -> np.ndarray:
    """Linear interpolation of a :func:`reflection_table` (NumPy reference).

    Parameters
    ----------
    table : array_like of complex, shape [n], n >= 2
        Samples at ``cos_theta = i / (n - 1)``.
    cos_theta : array_like of float, in [0, 1]

    Returns
    -------
    ndarray of complex128, shape of ``cos_theta``
    """
    t = np.asarray(table, dtype=np.complex128)
    if t.ndim != 1 or t.size < 2:
        raise MaterialError(
            f"table must be 1-D with at least 2 samples, got shape {t.shape}")
    c = _check_cos(cos_theta)
    u = c * (t.size - 1)
    i = np.minimum(np.floor(u).astype(np.int64), t.size - 2)
    w = u - i
    return (1.0 - w) * t[i] + w * t[i + 1]


def table_error_bound(material: Material, frequency_hz: float, polarization: str,
                      n: int = 257, oversample: int = 16,
                      cos_min: float = 0.0) -> float:
    """Maximum error of the interpolated table, measured on a dense grid.

    Parameters
    ----------
    material, frequency_hz, polarization, n
        As for :func:`reflection_table`.
    oversample : int
        Evaluation points per table interval (>= 2), including both ends.
    cos_min : float
        Only ``cos_theta >= cos_min`` counts (in [0, 1)); e.g.
        ``2 / (n - 1)`` ignores the grazing band where a good conductor's
        ``r_tm`` cannot be tabulated.

    Returns
    -------
    float
        ``max |interpolate_table(T, c) - r(c)|`` over the ``(n - 1) *
        oversample + 1`` uniformly spaced ``c`` in [0, 1] that are
        ``>= cos_min``, in float64, with the
        complex64 table. It is a sampled estimate of the supremum (dense
        enough that it is within a few % of it for smooth ``r``), not a
        rigorous bound; see :func:`reflection_table` for the analytic bound.
    """
    if isinstance(oversample, bool) or not isinstance(oversample, (int, np.integer)) \
            or oversample < 2:
        raise MaterialError(f"oversample must be an integer >= 2, got {oversample!r}")
    cm = float(cos_min)
    if not 0.0 <= cm < 1.0:
        raise MaterialError(f"cos_min must lie in [0, 1), got {cos_min!r}")
    table = reflection_table(material, frequency_hz, polarization, n)
    cos = np.linspace(0.0, 1.0, (int(n) - 1) * int(oversample) + 1)
    cos = cos[cos >= cm]
    exact = reflection_coefficient(material, cos, frequency_hz, polarization)
    return float(np.max(np.abs(interpolate_table(table, cos) - exact)))
