"""The rough-surface model (:mod:`sarmitsuba.scene.roughness`) tabulated for the tracer, per
material row: the monostatic sigma nought of HH, VV and HV over the incidence cosine, the bistatic
one of HH and VV over the incidence and scattering cosines and the cosine of the azimuth between
them (docs/physics.md (RS6)). The kernel interpolates sigma nought linearly (a zero, such as HH
scattered normally at 90 deg azimuth, stays one; a logarithm would spread it over a cell).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .roughness import RoughSurface, sigma0_backscatter, sigma0_bistatic

__all__ = ["RoughTables", "rough_tables", "CONDUCTOR_PERMITTIVITY", "MONO_SIZE", "COS_SIZE", "PHI_SIZE", "COS_FLOOR",
           "coherent_factor"]

#: Samples of the monostatic table over cos(theta) in [0, 1].
MONO_SIZE = 257
#: Samples of the bistatic table over each of cos(theta_i) and cos(theta_s) in [0, 1].
COS_SIZE = 33
#: Samples of the bistatic table over cos(phi_s) in [-1, 1].
PHI_SIZE = 17
#: The permittivity a perfect conductor's rough surface scatters with (a good conductor's limit).
CONDUCTOR_PERMITTIVITY = 1.0 - 1e6j
#: The node at cos = 0 (grazing) is evaluated at this cosine (89.4 deg): the model's limit there.
COS_FLOOR = 0.01


@dataclass(frozen=True)
class RoughTables:
    """Sigma nought tables of the rough materials, for the kernel (docs/physics.md (RS6)).

    Attributes
    ----------
    mono : float32 [n_rows, 3, MONO_SIZE]
        Sigma nought (linear) of HH, VV and HV at ``cos(theta) = i / (MONO_SIZE - 1)`` (node 0 at
        ``COS_FLOOR``); 0 for a row without a rough surface.
    bistatic : float32 [n_rows, 2, COS_SIZE, COS_SIZE, PHI_SIZE]
        Sigma nought of HH and VV at ``cos(theta_i) = i / (COS_SIZE - 1)``, ``cos(theta_s) =
        j / (COS_SIZE - 1)``, ``cos(phi_s) = -1 + 2 m / (PHI_SIZE - 1)``.
    rough : bool [n_rows]
        Rows with a rough surface.
    """

    mono: np.ndarray
    bistatic: np.ndarray
    rough: np.ndarray


def _cosines(n: int) -> np.ndarray:
    c = np.linspace(0.0, 1.0, n)
    c[0] = COS_FLOOR
    return c


def rough_tables(surfaces: list, permittivities: list, wavenumber: float, cross: bool = True) -> RoughTables:
    """The tables of every material row. Each row's are computed once per process
    (:func:`functools.lru_cache` on the surface, the permittivity and ``k``).

    Parameters
    ----------
    surfaces : list of RoughSurface or None
        Each row's surface (None: not rough).
    permittivities : list of complex or None
        Each row's relative permittivity (``Im <= 0``; None for a perfect conductor, whose rough
        surface is then given ``CONDUCTOR_PERMITTIVITY``).
    wavenumber : float
        ``k`` [rad/m].
    cross : bool
        Whether to tabulate HV (polarimetric runs); False leaves it 0.

    Returns
    -------
    RoughTables
    """
    rows = len(surfaces)
    mono = np.zeros((rows, 3, MONO_SIZE), np.float32)
    bistatic = np.zeros((rows, 2, COS_SIZE, COS_SIZE, PHI_SIZE), np.float32)
    for row, (surface, eta) in enumerate(zip(surfaces, permittivities)):
        if surface is not None:
            mono[row], bistatic[row] = _row_tables(surface, CONDUCTOR_PERMITTIVITY if eta is None else complex(eta),
                                                   float(wavenumber), bool(cross))
    return RoughTables(mono, bistatic, np.array([s is not None for s in surfaces], bool))


@functools.lru_cache(maxsize=64)
def _row_tables(surface: RoughSurface, eta: complex, wavenumber: float, cross: bool):
    c_mono, c = _cosines(MONO_SIZE), _cosines(COS_SIZE)
    ci, cs, cp = c[:, None, None], c[None, :, None], np.linspace(-1.0, 1.0, PHI_SIZE)[None, None, :]
    one = sigma0_backscatter(surface, eta, wavenumber, c_mono, cross=cross)
    two = sigma0_bistatic(surface, eta, wavenumber, ci, cs, np.arccos(cp))
    mono = np.array([one[p] for p in ("HH", "VV", "HV")], np.float32)
    bistatic = np.array([two[p] for p in ("HH", "VV")], np.float32)
    mono.flags.writeable = bistatic.flags.writeable = False
    return mono, bistatic


def coherent_factor(surface: RoughSurface, wavenumber: float, cos_theta) -> np.ndarray:
    """The factor ``exp(-2 (k s cos theta)^2)`` on a rough surface's specular (coherent) reflection
    coefficient (the Kirchhoff mean field of a Gaussian height field; Ament, Proc. IRE 41(1),
    1953), eq. (RS6). Float64 array of ``cos_theta``'s shape."""
    ks = wavenumber * surface.rms_height
    return np.exp(-2.0 * (ks * np.asarray(cos_theta, np.float64)) ** 2)
