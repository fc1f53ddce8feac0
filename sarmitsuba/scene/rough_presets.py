"""Roughness presets: one setting that gives every surface of a scene a rough surface by its ITU-R
P.2040 material class and its role (roof, facade, ground, underside; :mod:`.roles`), docs/physics.md
(RS7), (RS8); the one-line summary of a rough material that ``info`` prints, and the one-line
warning for a rough material outside the model's validated range (RS5).

The ``city`` preset's rows and rules say where their numbers come from; most are assumptions, and
say so. A class takes its own row in every role, except where :data:`CITY_RULES` says that the
class does not describe that role's surface (Sionna's metal roofs): there the role's row of
:data:`CITY_ROLES` applies.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.constants import SPEED_OF_LIGHT
from .fresnel import MaterialError
from .rough_tables import CONDUCTOR_PERMITTIVITY
from .roughness import CROSS_KS_LIMIT, KS_LIMIT, SLOPE_LIMIT, RoughSurface, outside_range, sigma0_backscatter

__all__ = ["PresetRow", "PRESETS", "ROLE_PRESETS", "CITY_ROLES", "CITY_RULES", "preset_row", "preset_surface", "describe_surface", "range_warning", "INVISIBLE_DB"]

#: A sigma nought below this [dB] lies far below the noise floor of any radar: the clutter, though
#: on, adds nothing (said in :func:`range_warning`).
INVISIBLE_DB = -100.0


@dataclass(frozen=True)
class PresetRow:
    """One ITU class's surface in a preset.

    Attributes
    ----------
    surface : RoughSurface or None
        None: the class stays smooth (PO only).
    source : str
        Where the numbers come from, or ``"assumption: ..."``.
    material : str or None
        A role's row only: the ITU class whose permittivity the role's surfaces take where a rule
        applies (a metal-labelled roof of tiles is no conductor); None keeps the class's own.
    """

    surface: RoughSurface | None
    source: str
    material: str | None = None


def _row(s_mm: float, l_mm: float, correlation: str, source: str) -> PresetRow:
    return PresetRow(RoughSurface(s_mm * 1e-3, l_mm * 1e-3, correlation), source)


_SMOOTH_INDOOR = PresetRow(None, "assumption: an indoor finish, smooth at radar wavelengths")

#: ``city``: outdoor surfaces of a European city. rms height and correlation length in mm.
CITY = {
    "asphalt_concrete": _row(0.5, 5.0, "exponential",
                             "road macrotexture: mean profile depth (MPD, ISO 13473-1) about 1 mm for dense asphalt; "
                             "assumption: s = MPD / 2, l = 5 mm, about half an 11 mm maximum aggregate"),
    "concrete": _row(0.5, 5.0, "exponential",
                     "as asphalt_concrete (Sionna's city scenes pave their streets with concrete); assumption: a "
                     "brushed pavement's macrotexture, MPD about 1 mm (ISO 13473-1)"),
    "medium_dry_ground": _row(6.0, 60.0, "exponential",
                              "bare soil fields measured by Oh, Sarabandi and Ulaby (IEEE TGRS 30(2), 1992) span s = "
                              "3.2 to 30 mm; assumption: a lawn as the soil below it, s = 6 mm, l = 60 mm"),
    "very_dry_ground": _row(6.0, 60.0, "exponential", "as medium_dry_ground (assumption)"),
    "wet_ground": _row(6.0, 60.0, "exponential", "as medium_dry_ground (assumption)"),
    "brick": _row(2.0, 20.0, "exponential",
                  "assumption: a brick wall's mortar joints recessed a few millimetres"),
    "marble": _row(1.0, 10.0, "exponential",
                   "assumption: dressed stone or rendered facades (Sionna's city scenes give most walls marble)"),
    "wood": _row(1.0, 10.0, "exponential", "assumption: weathered, sawn boards"),
    "metal": PresetRow(None, "assumption: rolled sheet metal, micrometre roughness, smooth; seams are geometry"),
    "glass": PresetRow(None, "assumption: float glass is optically flat (nanometre roughness), smooth"),
    "clear_acrylic": PresetRow(None, "assumption: cast acrylic is optically smooth"),
    **{name: _SMOOTH_INDOOR for name in ("plasterboard", "ceiling_board", "chipboard", "floorboard", "plywood",
                                         "carpet_tile", "vinyl_tile")},
    "vacuum": PresetRow(None, "assumption: not a surface, smooth"),
}

#: ``city``: the surface of each role (:data:`sarmitsuba.scene.roles.ROLES`) where the class does
#: not describe it (:data:`CITY_RULES`). rms height and correlation length in mm.
CITY_ROLES = {
    "roof": PresetRow(RoughSurface(5e-3, 25e-3, "exponential"),
                      "assumption: a European city's roofs are clay or concrete tiles, or gravel ballast (16-32 mm "
                      "grading, DIN 18531) on a flat roof; s = 5 mm and l = 25 mm stand for a tile's profile and a "
                      "gravel bed alike (k s = 1 at 9.6 GHz), and concrete's permittivity for tile and stone",
                      "concrete"),
    "facade": PresetRow(CITY["marble"].surface, "as marble: rendered or dressed-stone facades (assumption)", "marble"),
    "ground": PresetRow(CITY["concrete"].surface, "as concrete: paved streets and squares (ISO 13473-1 "
                                                  "macrotexture; assumption as for concrete)", "concrete"),
    "underside": PresetRow(CITY["marble"].surface, "assumption: a soffit is finished as the facade above it; "
                                                   "the radar meets it only after another bounce", "marble"),
}

_ROOF_LABEL = ("assumption: Sionna's city scenes label every roof itu_metal (all 1,142 of Munich's) and footprint "
               "cities give a building one class; neither says what covers the roof, so the roof's surface applies")
#: ``city``: (class, role) pairs whose class does not describe the surface; the role's row applies.
CITY_RULES = {
    **{(name, "roof"): _ROOF_LABEL for name in ("metal", "concrete", "marble", "brick", "wood", "asphalt_concrete")},
    ("metal", "ground"): "assumption: metal-labelled ground is a mislabel (no city street is sheet metal)",
    ("asphalt_concrete", "facade"): "assumption: asphalt-labelled walls are a mislabel; the facade's surface applies",
}

#: Presets by name (``--material-set roughness=NAME``); ``none`` makes every material smooth.
PRESETS = {"city": CITY, "none": {}}
#: Each preset's role rows and rules (``none``: none).
ROLE_PRESETS = {"city": (CITY_ROLES, CITY_RULES), "none": ({}, {})}


def preset_row(preset: str, itu_name: str | None, role: str | None = None) -> PresetRow | None:
    """The :class:`PresetRow` the preset gives an ITU class in a role (None: the preset does not
    name the class; ``role`` None: the class's own row). A (class, role) pair of the preset's rules
    takes the role's row, with the rule's source prepended.

    Raises
    ------
    MaterialError
        For an unknown preset name.
    """
    if preset not in PRESETS:
        raise MaterialError(f"roughness preset {preset!r} is unknown; valid: {', '.join(PRESETS)}")
    if itu_name is None or itu_name not in PRESETS[preset]:
        return None
    roles, rules = ROLE_PRESETS[preset]
    if role is not None and (itu_name, role) in rules:
        return PresetRow(roles[role].surface, f"{rules[itu_name, role]}; {roles[role].source}", roles[role].material)
    return PRESETS[preset][itu_name]


def preset_surface(preset: str, itu_name: str | None, role: str | None = None) -> RoughSurface | None:
    """The surface the preset gives an ITU class in a role (None: smooth, or not an ITU material);
    see :func:`preset_row`.

    Raises
    ------
    MaterialError
        For an unknown preset name.
    """
    row = preset_row(preset, itu_name, role)
    return None if row is None else row.surface


def describe_surface(surface: RoughSurface, eta, frequency: float, incidence_deg: float) -> str:
    """One line: the surface's statistics, ``k s``, ``k l`` and its monostatic sigma nought at the
    incidence ``incidence_deg`` (HH and VV, dB), e.g. ``"I2EM s 3 mm, l 20 mm, exponential (ks 0.60,
    kl 4.0): sigma0 HH -13.7 dB, VV -10.2 dB at 45 deg"``. ``eta`` None: a conductor's limit."""
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    eta = CONDUCTOR_PERMITTIVITY if eta is None else complex(eta)
    ks, kl = k * surface.rms_height, k * surface.correlation_length
    model = "I2EM" if ks <= KS_LIMIT else "geometric optics"
    sigma = sigma0_backscatter(surface, eta, k, math.cos(math.radians(incidence_deg)))
    db = {p: 10.0 * math.log10(max(float(sigma[p]), 1e-30)) for p in ("HH", "VV")}
    return (f"{model} s {surface.rms_height * 1e3:g} mm, l {surface.correlation_length * 1e3:g} mm, "
            f"{surface.correlation} (ks {ks:.2f}, kl {kl:.1f}): sigma0 HH {db['HH']:.1f} dB, "
            f"VV {db['VV']:.1f} dB at {incidence_deg:g} deg")


def range_warning(name: str, surface: RoughSurface, eta, frequency: float, incidence_deg: float,
                  cross: bool = False) -> str | None:
    """One line for a rough material outside the I2EM's validated range at the carrier
    (docs/physics.md (RS5); :func:`sarmitsuba.scene.roughness.outside_range`), or None inside it.

    The line names the material, its ``rms_height`` and ``correlation_length`` [m], the bounds it
    exceeds with ``k s`` and ``k l``, the range, what the render does (geometric optics beyond
    ``k s = 3``, else the I2EM beyond its range) with the monostatic sigma nought that gives at
    ``incidence_deg`` (HH, VV and, for ``cross``, HV, in dB), and the surfaces inside the range at
    this frequency. ``eta`` None: a conductor's limit. ``cross``: HV is traced.
    """
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    exceeded = outside_range(surface, k, cross)
    if not exceeded:
        return None
    eta = CONDUCTOR_PERMITTIVITY if eta is None else complex(eta)
    ks, kl = k * surface.rms_height, k * surface.correlation_length
    sigma = sigma0_backscatter(surface, eta, k, math.cos(math.radians(incidence_deg)), cross=cross)
    db = {p: 10.0 * math.log10(max(float(sigma[p]), 1e-300)) for p in ("HH", "VV", "HV")}
    level = ", ".join(f"{p} {db[p]:.1f} dB" for p in (("HH", "VV", "HV") if cross and ks <= KS_LIMIT else ("HH", "VV")))
    does = ("renders by geometric optics (no HV)" if ks > KS_LIMIT else "renders by the I2EM beyond that range"
            if surface.rms_height > SLOPE_LIMIT * surface.correlation_length else
            "renders its HV by the I2EM's cross-polarised term (RS1x) beyond that range")
    quiet = (f", far below any radar's noise floor: its clutter is on but adds nothing"
             if max(db["HH"], db["VV"]) < INVISIBLE_DB else "")
    hv = f", and k s <= {CROSS_KS_LIMIT:g} for HV" if cross else ""
    return (f"rough material {name!r} (rms_height {surface.rms_height:g} m, correlation_length "
            f"{surface.correlation_length:g} m, {surface.correlation}) is outside the I2EM's validated range at "
            f"{frequency / 1e9:g} GHz: {', '.join(exceeded)} (k l = {kl:.3g}); the range is k s <= {KS_LIMIT:g} and "
            f"s / l <= {SLOPE_LIMIT:g}{hv} (docs/physics.md (RS5)), here rms_height <= "
            f"{(CROSS_KS_LIMIT if cross else KS_LIMIT) / k * 1e3:.3g} mm and correlation_length >= "
            f"{1.0 / SLOPE_LIMIT:g} rms_height; it {does}: sigma0 {level} at {incidence_deg:g} deg{quiet}")
