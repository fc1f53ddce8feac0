"""SICD ``Radiometric`` scale factors of a sarmitsuba image (NGA.STND.0024-1, SICD Volume 1,
section "Radiometric": ``RCSSFPoly``, ``BetaZeroSFPoly``, ``SigmaZeroSFPoly``, ``GammaZeroSFPoly``;
docs/physics.md (K), (K2), (K3)).

sarmitsuba's images are calibrated to unit peak gain (K): a point target of RCS ``sigma`` peaks
at ``sqrt(sigma)`` and carries ``int |I|^2 dA = sigma rho_row rho_col`` over the image plane, the
energy widths being ``rho = W / ImpRespBW`` with ``W = mean(w^2) / mean(w)^2`` of the direction's
weighting ``w`` (``WgtFunct``; 1 without one) (K2). So, SICD's scale factors (pixel power to each
quantity), constant over the image and computed at the SCP:

- ``RCSSF = 1``: the RCS is the power of a point target's peak, equivalently its integrated power
  ``sum |p|^2 SS_row SS_col`` over the impulse response's energy area ``A = rho_row rho_col``;
- ``BetaZeroSF = RCSSF / A_spn``: radar brightness is RCS per unit area of the slant plane, and a
  resolution cell's energy area in the slant plane is ``A_spn = A |n_image . n_slant|`` (the
  image plane's support projects onto the slant plane's with that cosine; 1 for a slant-plane
  image, ``cos(SlopeAng)`` for a ground-plane one);
- ``SigmaZeroSF = BetaZeroSF cos(SlopeAng)`` (RCS per unit ground area) and
  ``GammaZeroSF = BetaZeroSF cos(SlopeAng) / sin(GrazeAng)`` (per unit area normal to the line of
  sight), with the SCPCOA angles.

NGA's sarpy (``GridType.get_slant_plane_area``) and MATLAB SAR toolbox take the same energy area,
weighting factors included (from ``WgtFunct``, or from ``WgtType`` when it names a window they
know), but ``A_spn = A`` for any image plane: the slant-plane grid that :func:`write_sicd` writes
by default is consistent under their checks; a GROUND grid (``plane="image"``) is reported
with ``BetaZeroSFPoly`` and ``RCSSFPoly`` inconsistent by exactly ``cos(SlopeAng)``.

A point target's integrated RCS (the integral method, (K3)) is ``BetaZeroSF sum |p|^2 SS_row
SS_col`` over its response on a slant-plane grid. sarpy's RCS tool (``sarpy.annotation.rcs``,
``TotalRCS``) computes ``RCSSF sum |p|^2 / (OSR_row OSR_col)`` instead, with ``OSR = 1 / (SS
ImpRespBW)``: that is ``W_row W_col`` times the integrated RCS (3.7 dB for sarmitsuba's Taylor
windows) under sarpy's own ``BetaZeroSF = RCSSF / A`` relation. No ``RCSSF`` satisfies both on a
weighted image; the one written here is the one sarpy's consistency check and the standard's
``Radiometric`` relations agree with. On such a SICD (``weighting="image"``) read the integrated
RCS from sarpy's ``TotalRCS`` as ``TotalRCS / (W_row W_col)``; the default SICD is uniform
(``W = 1``, no ``WgtFunct``: docs/physics.md (K3')), and every reading coincides.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["weight_factor", "slant_plane_area", "radiometric"]


def weight_factor(weights: np.ndarray | None) -> float:
    """``mean(w^2) / mean(w)^2`` of a ``WgtFunct`` (float [n]); 1 without one (uniform weighting)."""
    if weights is None:
        return 1.0
    w = np.asarray(weights, dtype=np.float64)
    return float(np.mean(w ** 2) / np.mean(w) ** 2)


def slant_plane_area(tree: Any) -> tuple[float, float]:
    """``(A_spn [m^2], |n_image . n_slant|)`` of a SICD XML tree whose ``SCPCOA`` is set: the energy area
    of a resolution cell in the slant plane (module docstring), the slant plane spanned by the
    line of sight and the velocity at the SCP's centre of aperture."""
    import sarkit.sicd as sksicd
    xml = sksicd.XmlHelper(tree)
    area = 1.0
    for direction in ("Row", "Col"):
        area *= weight_factor(xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}WgtFunct")) / xml.load(
            f"{{*}}Grid/{{*}}{direction}/{{*}}ImpRespBW")
    image_normal = np.cross(xml.load("{*}Grid/{*}Row/{*}UVectECF"), xml.load("{*}Grid/{*}Col/{*}UVectECF"))
    slant_normal = np.cross(xml.load("{*}GeoData/{*}SCP/{*}ECF") - xml.load("{*}SCPCOA/{*}ARPPos"),
                            xml.load("{*}SCPCOA/{*}ARPVel"))
    norms = float(np.linalg.norm(image_normal) * np.linalg.norm(slant_normal))
    cosine = abs(float(image_normal @ slant_normal)) / norms
    return area * cosine, cosine


def radiometric(tree: Any) -> dict[str, np.ndarray]:
    """The ``Radiometric`` element (sarkit's dictionary form) of a sarmitsuba image's SICD XML tree,
    its ``Grid`` and ``SCPCOA`` set: constant Poly2D scale factors (module docstring)."""
    import sarkit.sicd as sksicd
    xml = sksicd.XmlHelper(tree)
    slope, graze = (np.radians(xml.load(f"{{*}}SCPCOA/{{*}}{name}")) for name in ("SlopeAng", "GrazeAng"))
    rcs = 1.0
    beta = rcs / slant_plane_area(tree)[0]
    return {"RCSSFPoly": np.array([[rcs]]), "SigmaZeroSFPoly": np.array([[beta * np.cos(slope)]]),
            "BetaZeroSFPoly": np.array([[beta]]),
            "GammaZeroSFPoly": np.array([[beta * np.cos(slope) / np.sin(graze)]])}
