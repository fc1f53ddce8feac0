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
    single-layer slab in vacuum (defined in :mod:`sarmitsuba.scene.fresnel`,
    with ``MaterialError``).
reflection_coefficient
    Dispatch on ``Material.model`` and on the polarisation (HH -> TE,
    VV -> TM).
reflection_table, interpolate_table, table_error_bound
    Lookup table for the tracer, its interpolation and its error.
grazing_impedance
    The normalised surface impedance a wave grazing the surface sees (the ground wave's
    numerical distance, docs/physics.md (E6)).

Conventions
-----------
Time dependence ``exp(+j omega t)`` (lossy media have ``Im(eta) < 0``), the mirror-image sign
convention of the coefficients (a perfect conductor has ``r_te = r_tm = -1``) and the scalar
polarisation model (``"HH"`` uses ``r_te``, ``"VV"`` ``r_tm``): see :mod:`sarmitsuba.scene.fresnel`,
where the coefficients live.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sarmitsuba.core.constants import VACUUM_PERMITTIVITY
from sarmitsuba.core.valid_ranges import unknown_name
from sarmitsuba.scene.fresnel import (MaterialError, check_cos, check_eta, check_frequency, check_thickness,
                                      fresnel_half_space, slab_reflection)

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
    "grazing_impedance",
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


# --------------------------------------------------------------------------
# Argument validation
# --------------------------------------------------------------------------

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
        raise MaterialError(unknown_name("ITU material", name, itu_material_names()))
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
    f = check_frequency(frequency_hz)
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
        eta = complex(check_eta(self.relative_permittivity))
        object.__setattr__(self, "relative_permittivity", eta)
        if self.model == "slab":
            object.__setattr__(self, "thickness", check_thickness(self.thickness))
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
            f"material must be a sarmitsuba.scene.materials.Material, got "
            f"{type(material).__name__}")
    pol = _check_polarization(polarization)
    c = check_cos(cos_theta)
    f = check_frequency(frequency_hz)
    if material.model == "pec":
        return np.full(c.shape, -1.0 + 0.0j, dtype=np.complex128)
    if material.model == "half_space":
        r_te, r_tm = fresnel_half_space(c, material.relative_permittivity)
    else:
        r_te, r_tm = slab_reflection(c, material.relative_permittivity,
                                     material.thickness, f)
    return r_te if pol == "te" else r_tm


def grazing_impedance(material: Material, frequency_hz: float) -> complex:
    """The normalised surface impedance ``Delta = sqrt(eta - 1) / eta`` (dimensionless,
    ``Re >= 0``) that a TM wave grazing the material sees: the impedance boundary whose TM
    coefficient ``(Delta - cos) / (Delta + cos)`` (mirror-image convention) is the half space's
    as ``cos_theta -> 0`` (Norton, Proc. IRE 25(9), 1937; Wait, IEEE Antennas Propag. Mag. 40(5),
    1998). A slab's grazing wave is taken as over a half space of its material; 0 for ``pec``.
    It sets the numerical distance of the grazing wave across a face, docs/physics.md (E6').

    Parameters
    ----------
    material : Material
    frequency_hz : float
        Frequency [Hz], > 0 (checked; the permittivity is the material's own).

    Returns
    -------
    complex
        ``Delta`` (principal root); ``0j`` for a perfect conductor.
    """
    check_frequency(frequency_hz)
    if material.model == "pec":
        return 0j
    eta = complex(material.relative_permittivity)
    return complex(np.sqrt(eta - 1.0) / eta)


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
    c = check_cos(cos_theta)
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
