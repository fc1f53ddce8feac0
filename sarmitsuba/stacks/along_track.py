"""Along-track interferometry and displaced phase centres: a moving target's radial velocity
from two channels of one pass (docs/physics.md (V6), (V7)).

The sensor's ``ati_baseline`` ``d`` renders a second channel whose phase centre trails the first
by ``d`` along the flight direction (:attr:`sarmitsuba.pipeline.Simulation.aft`), both focused on
one grid. The aft channel passes each point of the track ``d / V`` later than the fore one, so a
still scatterer looks the same to both and a target with range rate ``v_r`` (positive away from
the radar) is ``v_r d / V`` farther away for the aft one:

- :func:`ati_interferogram`: ``I_fore I_aft*``, whose phase is ``4 pi v_r d / (lambda V)`` (V6);
- :func:`radial_velocity`: that phase turned back into ``v_r``;
- :func:`dpca_image`: ``I_fore - I_aft``, in which still clutter cancels and a moving target
  keeps ``2 |sin(phi / 2)|`` of its amplitude (V7).

References: Raney, IEEE TAES 7(3), 1971; Goldstein and Zebker, "Interferometric radar
measurement of ocean surface currents", Nature 328, 1987 (ATI); Cumming & Wong, *Digital
Processing of SAR Data*, 2005, sec. 4.4.
"""
from __future__ import annotations

import numpy as np

from ..core.image import SarImage
from .interferometry import check_pair

__all__ = ["ati_interferogram", "dpca_image", "radial_velocity", "ati_phase"]


def _pair(fore: SarImage, aft: SarImage) -> tuple[np.ndarray, np.ndarray]:
    """The two channels' pixels (complex128), checked to lie on one ground grid
    (:func:`~sarmitsuba.stacks.interferometry.check_pair`)."""
    check_pair(fore, aft)
    return fore.data.astype(np.complex128), aft.data.astype(np.complex128)


def ati_interferogram(fore: SarImage, aft: SarImage) -> np.ndarray:
    """The along-track interferogram ``I_fore I_aft*`` (complex128 [n_az, n_rg]); its phase is
    ``4 pi v_r d / (lambda V)`` at a target of range rate ``v_r`` (positive away from the radar)
    and zero on still scatterers (docs/physics.md (V6)). Raises InterferometryError when the
    images lie on different grids."""
    a, b = _pair(fore, aft)
    return a * np.conj(b)


def ati_phase(v_r, wavelength: float, velocity: float, baseline: float):
    """The ATI phase [rad] of a range rate ``v_r`` [m/s]: ``4 pi v_r d / (lambda V)`` (V6), for a
    wavelength [m], platform speed ``V`` [m/s] and along-track baseline ``d`` [m]."""
    return 4.0 * np.pi * np.asarray(v_r, float) * baseline / (wavelength * velocity)


def radial_velocity(phase, wavelength: float, velocity: float, baseline: float):
    """The range rate [m/s] (positive away from the radar) of an ATI phase [rad], ``phase lambda V
    / (4 pi d)``: unambiguous for ``|v_r| < lambda V / (4 d)`` (V6)."""
    return np.asarray(phase, float) * wavelength * velocity / (4.0 * np.pi * baseline)


def dpca_image(fore: SarImage, aft: SarImage) -> np.ndarray:
    """The displaced-phase-centre image ``I_fore - I_aft`` (complex128 [n_az, n_rg]): still
    scatterers cancel, a moving target keeps ``2 |sin(phi / 2)|`` of its amplitude, ``phi`` its
    ATI phase (docs/physics.md (V7)). Raises InterferometryError for different grids."""
    a, b = _pair(fore, aft)
    return a - b
