"""The ``city`` roughness preset (docs/physics.md (RS7)): every ITU-R P.2040 class against its
surface as its sources give it, typed here from them (the preset's rows, docs/guide/scenes.md),
not read from the preset: the preset's table itself and the surfaces a scene's materials take
when it is loaded with ``--material-set roughness=city``.

Planted bug: wood given a rough surface of ``s = 2 mm`` (marble's and wood's 1 mm doubled); or a
class dropped from the preset (then it loads smooth). Either fails both tests."""
from __future__ import annotations

import trimesh

import sarmitsuba as sm
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.scene.materials import itu_material_names
from sarmitsuba.scene.rough_presets import CITY, preset_surface
from sarmitsuba.scene.roughness import RoughSurface

#: rms height and correlation length [mm] of each class (exponential correlation), None smooth.
SOURCES = {
    # road macrotexture: mean profile depth about 1 mm for dense asphalt (ISO 13473-1); s = MPD / 2
    # and l = 5 mm, about half an 11 mm maximum aggregate, are assumptions
    "asphalt_concrete": (1.0 / 2, 5.0),
    "concrete": (1.0 / 2, 5.0),                     # as asphalt: a brushed pavement, MPD about 1 mm
    # within Oh, Sarabandi and Ulaby's bare-soil fields (IEEE TGRS 30(2), 1992: s 3.2 to 30 mm);
    # a lawn as its soil, s = 6 mm, l = 60 mm, is an assumption
    "medium_dry_ground": (6.0, 60.0),
    "very_dry_ground": (6.0, 60.0),
    "wet_ground": (6.0, 60.0),
    "brick": (2.0, 20.0),                           # assumption: recessed mortar joints
    "marble": (1.0, 10.0),                          # assumption: dressed stone or rendered facades
    "wood": (1.0, 10.0),                            # assumption: weathered sawn boards
    # smooth (physical optics only): rolled metal, float glass, cast acrylic (micrometre to
    # nanometre roughness), indoor finishes, and vacuum (not a surface)
    **{name: None for name in ("metal", "glass", "clear_acrylic", "plasterboard", "ceiling_board", "chipboard",
                               "floorboard", "plywood", "carpet_tile", "vinyl_tile", "vacuum")},
}


def _expected(name: str) -> RoughSurface | None:
    row = SOURCES[name]
    return None if row is None else RoughSurface(row[0] * 1e-3, row[1] * 1e-3, "exponential")


def test_every_class_has_the_surface_its_sources_give():
    """All 19 ITU classes (no more, no fewer) and each one's surface, or smooth."""
    assert set(SOURCES) == set(itu_material_names()) == set(CITY)
    for name in SOURCES:
        assert preset_surface("city", name) == _expected(name), name
    assert 3.2 <= SOURCES["medium_dry_ground"][0] <= 30.0         # inside the measured soils' range


def test_a_scene_loaded_with_the_preset_gives_every_class_its_surface():
    """One box per ITU class (Sionna's ``itu-radio-material``), loaded with ``roughness=city``:
    each material takes its class's surface (clutter kind 3), the smooth classes none (kind 0)."""
    rows = []
    for i, name in enumerate(sorted(SOURCES)):
        box = trimesh.creation.box((3.0, 3.0, 3.0))
        box.apply_translation((6.0 * (i % 5) - 12.0, 6.0 * (i // 5) - 12.0, 1.5))
        rows.append((box, {"plugin": "itu-radio-material", "type": name}, name))
    loaded = load_scene(sm.Scene(rows, sensor={"incidence_angle": 35.0}, name="itu_every_class"),
                        material_overrides={"roughness": "city"})
    got = {s.bsdf().name: (s.bsdf().surface, s.bsdf().clutter[0]) for s in loaded.scene.shapes()}
    assert set(got) == set(SOURCES)
    for name, (surface, kind) in got.items():
        expected = _expected(name)
        assert (surface, kind) == (expected, 0 if expected is None else 3), name
