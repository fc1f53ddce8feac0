"""A city as radar sees it: surfaces by role (docs/physics.md (RS8)), facades with windows (FA1).

Truths: the roles of faces built for them (a flat roof, a pitched roof, a wall, ground at two
heights, a surface facing down, at more than one slope); the preset's every class in every role;
a window's recess against the closed form of the dihedral its sill and pane make (Knott, Shaeffer
and Tuley, *Radar Cross Section*, table 6.1, with the effective aperture of the recess); the
window grid's period in the image's azimuth spectrum.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trimesh

import sarmitsuba as sm
from sarmitsuba.analysis import point_target as analysis
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.facades import FacadeError, FacadeLayout, add_windows, wall_with_windows
from sarmitsuba.scene.loader import load_scene, material_table
from sarmitsuba.scene.materials import itu_material_names
from sarmitsuba.scene.roles import ROLES, face_roles, shape_roles
from sarmitsuba.scene.rough_presets import CITY, CITY_ROLES, CITY_RULES, PRESETS, preset_row

WAVELENGTH = 299_792_458.0 / 9.6e9


def _quad(corners, normal):
    v = np.asarray(corners, float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    if np.cross(v[1] - v[0], v[2] - v[0]) @ np.asarray(normal, float) < 0:
        f = f[:, ::-1]
    return trimesh.Trimesh(v, f, process=False)


def _box(x0, y0, x1, y1, z0, z1):
    return trimesh.creation.box(bounds=[[x0, y0, z0], [x1, y1, z1]])


# ============================================================================ roles
@pytest.mark.parametrize("pitch", [30.0, 55.0])
def test_face_roles_of_a_house_on_two_levels_of_ground(pitch):
    """A gabled house (walls, two roof slopes of ``pitch``) on ground at z = 0, a terrace of
    ground at z = 4 m, a balcony slab's soffit. Each face's role follows from its normal and the
    height of what lies below. Bugs: a threshold on the wrong component of the normal (walls as
    roofs), the height measured above the world's z = 0 instead of the geometry below (the terrace
    as a roof), a soffit counted as ground."""
    rise = 3.0 * math.tan(math.radians(pitch))
    roof_a = _quad([[0, 0, 6], [10, 0, 6], [10, 3, 6 + rise], [0, 3, 6 + rise]], [0, -1, 1])
    roof_b = _quad([[0, 3, 6 + rise], [10, 3, 6 + rise], [10, 6, 6], [0, 6, 6]], [0, 1, 1])
    wall = _quad([[0, 0, 0], [10, 0, 0], [10, 0, 6], [0, 0, 6]], [0, -1, 0])
    ground = _quad([[-20, -20, 0], [30, -20, 0], [30, -10, 0], [-20, -10, 0]], [0, 0, 1])
    terrace = _quad([[-20, 20, 4], [30, 20, 4], [30, 30, 4], [-20, 30, 4]], [0, 0, 1])
    soffit = _quad([[0, -2, 3], [10, -2, 3], [10, 0, 3], [0, 0, 3]], [0, 0, -1])
    below = {  # heights of the geometry under each up-facing centre: the house's floor at z = 0
        "roof": lambda p: p[:, 2] - 0.0, "none": lambda p: np.full(len(p), np.inf)}
    cases = [(roof_a, below["roof"], "roof"), (roof_b, below["roof"], "roof"), (wall, below["none"], "facade"),
             (ground, below["none"], "ground"), (terrace, below["none"], "ground"),
             (soffit, below["roof"], "underside")]
    for mesh, height, expected in cases:
        roles = face_roles(mesh.vertices, mesh.faces, height)
        assert [ROLES[r] for r in roles] == [expected] * 2, (expected, pitch)
    # a low shelter (1.5 m above the ground) is ground to a radar, a storey (2.5 m) a roof
    low = _quad([[0, 0, 1.5], [2, 0, 1.5], [2, 2, 1.5], [0, 2, 1.5]], [0, 0, 1])
    assert [ROLES[r] for r in face_roles(low.vertices, low.faces, below["roof"])] == ["ground"] * 2
    high = low.copy()
    high.vertices[:, 2] = 2.5
    assert [ROLES[r] for r in face_roles(high.vertices, high.faces, below["roof"])] == ["roof"] * 2


def test_shape_roles_cast_down_in_a_loaded_scene():
    """In a Mitsuba scene: a box building (walls and roof separate shapes) on a ground plate, a
    second plate of ground 4 m higher with nothing under it, and an overhang. The roof has the
    ground 12 m below it; the raised ground has nothing. Bug: the downward ray starting on the face
    itself (every face its own geometry below: distance 0)."""
    b = _box(0, 0, 10, 8, 0, 12)
    up = b.face_normals[:, 2] > 0.5
    roof = trimesh.Trimesh(b.vertices, b.faces[up], process=False)
    walls = trimesh.Trimesh(b.vertices, b.faces[np.abs(b.face_normals[:, 2]) < 0.5], process=False)
    ground = _quad([[-30, -30, 0], [40, -30, 0], [40, 40, 0], [-30, 40, 0]], [0, 0, 1])
    raised = _quad([[60, 0, 4], [80, 0, 4], [80, 20, 4], [60, 20, 4]], [0, 0, 1])
    overhang = _quad([[0, -2, 6], [10, -2, 6], [10, 0, 6], [0, 0, 6]], [0, 0, -1])
    scene = sm.Scene([(roof, "concrete", "roof"), (walls, "concrete", "walls"), (ground, "concrete", "ground"),
                      (raised, "concrete", "raised"), (overhang, "concrete", "overhang")], name="roles")
    roles = shape_roles(scene.to_mitsuba())
    assert roles.role == ("roof", "facade", "ground", "ground", "underside")
    assert roles.mixed().size == 0
    # one shape holding roof and walls takes the larger (the walls: 36 m x 12 m against 80 m^2 each)
    whole = shape_roles(sm.Scene([(b, "concrete", "house"), (ground, "concrete", "ground")], name="r").to_mitsuba())
    assert whole.role[0] == "facade" and whole.mixed().tolist() == [0]
    assert whole.share[0] == pytest.approx(432.0 / (432.0 + 80.0 + 80.0), rel=1e-6)   # walls / (walls, roof, floor)


def test_every_class_in_every_role_has_a_row_that_names_its_source():
    """Every ITU class the preset names resolves in every role to a row whose source is a
    reference or says it is an assumption; the rules send exactly the listed pairs to the role's
    row, with the role's permittivity. Bug: a rule applied to every class (a glass roof turned to
    gravel), or a row without a source."""
    assert set(CITY) == set(itu_material_names()), set(itu_material_names()) ^ set(CITY)
    for name in CITY:
        for role in ROLES:
            row = preset_row("city", name, role)
            assert row is not None and len(row.source) > 20
            assert "assumption" in row.source or "ISO" in row.source or "IEEE" in row.source, (name, role)
            if (name, role) in CITY_RULES:
                assert row.surface == CITY_ROLES[role].surface and row.material == CITY_ROLES[role].material
            else:
                assert row is CITY[name]
    assert preset_row("city", "glass", "roof").surface is None           # a skylight stays smooth
    assert preset_row("city", "metal", "facade").surface is None         # metal cladding stays smooth
    assert preset_row("city", "metal", "roof").material == "concrete"
    assert preset_row("none", "metal", "roof") is None and PRESETS["none"] == {}


def test_metal_roofs_take_the_roof_surface_and_metal_walls_stay_smooth():
    """Sionna's labelling: one ``itu_metal`` BSDF on a roof and on a wall. With the preset the
    roof's row is rough (the roof's surface, concrete's permittivity: a reflection coefficient far
    from a conductor's) and the wall's stays smooth metal; without it both share one row. Bug: the
    table keyed by material alone (both shapes on one row)."""
    b = _box(0, 0, 10, 8, 0, 12)
    roof = trimesh.Trimesh(b.vertices, b.faces[b.face_normals[:, 2] > 0.5], process=False)
    walls = trimesh.Trimesh(b.vertices, b.faces[np.abs(b.face_normals[:, 2]) < 0.5], process=False)
    ground = _quad([[-30, -30, 0], [40, -30, 0], [40, 40, 0], [-30, 40, 0]], [0, 0, 1])
    metal = {"plugin": "itu-radio-material", "type": "metal", "id": "metal"}
    scene = sm.Scene([(roof, metal, "roof"), (walls, metal, "walls"), (ground, "concrete", "ground")], name="m",
                     sensor={"scene_center": (5.0, 4.0, 0.0)})
    plain = load_scene(scene)
    table = material_table(plain.scene, plain.params.frequency, "VV")
    assert table.names.count("metal") == 1 and len(table.names) == 2
    loaded = load_scene(scene, material_overrides={"roughness": "city"})
    table = material_table(loaded.scene, loaded.params.frequency, "VV")
    assert sorted(table.names) == ["concrete", "metal", "metal (roof)"]
    roof_row, wall_row = table.names.index("metal (roof)"), table.names.index("metal")
    assert table.clutter[roof_row, 0] == 3 and table.clutter[wall_row, 0] == 0
    assert abs(table.table_tm[wall_row, -1]) == pytest.approx(1.0, abs=1e-3)      # a conductor at normal incidence
    assert abs(table.table_tm[roof_row, -1]) < 0.6                               # concrete tiles, and rough


# ============================================================================ facades
def test_facade_layout_refuses_what_cannot_be_built_and_repeats_its_balconies():
    with pytest.raises(FacadeError, match="window_width"):
        FacadeLayout(window_width=2.5, window_spacing=3.0)
    with pytest.raises(FacadeError, match="floor_height"):
        FacadeLayout(floor_height=1.0)
    with pytest.raises(FacadeError, match="unknown facade setting 'floor'"):
        FacadeLayout.from_mapping({"floor": "3"})
    with pytest.raises(FacadeError, match="recess_depth"):
        FacadeLayout(recess_depth=float("nan"))
    layout = FacadeLayout(balcony_share=0.5, seed=3)
    # a 20 m wall, ground 0 to eaves 15 m: bays (20 - 0.6 - 1.2) // 3 + 1 = 7, storeys 15 // 3 = 5
    v, f, pv, pf = wall_with_windows((0, 0), (20, 0), -1.0, 15.0, 15.0, 0.0, 15.0, layout, "b/0/0")
    assert len(pf) == 2 * 7 * 5
    again = wall_with_windows((0, 0), (20, 0), -1.0, 15.0, 15.0, 0.0, 15.0, layout, "b/0/0")
    assert np.array_equal(again[0], v) and np.array_equal(again[1], f)
    other = wall_with_windows((0, 0), (20, 0), -1.0, 15.0, 15.0, 0.0, 15.0, dataclasses.replace(layout, seed=4), "b/0/0")
    assert not (len(other[1]) == len(f) and np.array_equal(other[0], v))
    # the panes lie recess_depth behind the wall and face out (+y for an edge running east... -y here)
    assert np.allclose(pv[:, 1], layout.recess_depth)
    normals = trimesh.Trimesh(pv, pf, process=False).face_normals
    assert np.allclose(normals, [0, -1, 0])


def _window_wall(layout, windows: bool):
    """A 12 m PEC wall facing the default sensor (+y), 6 m high, one window (or none)."""
    if windows:
        v, f, pv, pf = wall_with_windows((6, 0), (-6, 0), 0.0, 6.0, 6.0, 0.0, 6.0, layout)
        return [(trimesh.Trimesh(v, f, process=False), "pec", "wall"), (trimesh.Trimesh(pv, pf, process=False), "pec", "pane")]
    return [(_quad([[6, 0, 0], [-6, 0, 0], [-6, 0, 6], [6, 0, 6]], [0, 1, 0]), "pec", "wall")]


@pytest.mark.parametrize("incidence", [35.0, 50.0])
def test_a_window_returns_the_dihedral_of_its_sill_and_pane(incidence):
    """A window 1.2 m wide, recessed 0.15 m, in a 12 m PEC wall seen broadside. Across the wall the
    sill and the pane make a dihedral: rays entering the recess below ``2 d cot(theta)`` of its
    height return, an aperture ``w 2 d cos(theta)`` wide (docs/physics.md (FA1)); its RCS
    ``4 pi (w 2 d cos theta)^2 / lambda^2`` falls across the 0.5 deg aperture as the
    ``sinc^2(k w sin phi)`` of the window's width. The window's return (the image less the plain
    wall's) within 1.5 dB of the aperture's mean (measured +0.10 dB at 35 deg, +0.33 dB at 50). Bugs:
    the recess built twice as deep as asked (+6.2 dB), two windows in the bay (+3.1 dB)."""
    layout = FacadeLayout(floor_height=6.0, window_width=1.2, window_height=1.5, window_spacing=12.0,
                          sill_height=3.0, recess_depth=0.15)
    sensor = {"bandwidth": 150e6, "azimuth_beamwidth": 0.5, "prf": 250, "scene_center": (0.0, 0.0, 0.0),
              "incidence_angle": incidence}
    images = [simulate(sm.Scene(_window_wall(layout, w), name="window", sensor=sensor,
                                integrator={"max_depth": 2})).image for w in (True, False)]
    window = dataclasses.replace(images[0], data=images[0].data - images[1].data)
    measured = analysis.integrated_rcs(window, center=np.array([0.0, 0.15, 3.0]))
    theta, k = math.radians(incidence), 2 * math.pi / WAVELENGTH
    peak = 4 * math.pi * (1.2 * 2 * 0.15 * math.cos(theta)) ** 2 / WAVELENGTH**2
    phi = np.linspace(-math.radians(0.25), math.radians(0.25), 401)
    expected = peak * float(np.mean(np.sinc(k * 1.2 * np.sin(phi) / np.pi) ** 2))
    assert abs(10 * math.log10(measured / expected)) < 1.5, (10 * math.log10(measured), 10 * math.log10(expected))


def test_the_window_grid_sets_the_azimuth_spectrum_of_the_facade():
    """A 30 m facade of 2.5 m bays (12 windows on one storey): the image's azimuth cut through the
    windows' row peaks at the spatial frequency 1 / 2.5 m. Bug: bays laid out at another spacing."""
    layout = FacadeLayout(floor_height=5.0, window_width=1.0, window_height=1.5, window_spacing=2.5,
                          sill_height=2.0, recess_depth=0.15)
    v, f, pv, pf = wall_with_windows((15, 0), (-15, 0), 0.0, 5.0, 5.0, 0.0, 5.0, layout)
    shapes = [(trimesh.Trimesh(v, f, process=False), "pec", "wall"), (trimesh.Trimesh(pv, pf, process=False), "pec", "pane")]
    sim = simulate(sm.Scene(shapes, name="grid", sensor={"bandwidth": 150e6, "azimuth_beamwidth": 1.5, "prf": 300,
                                                            "scene_center": (0.0, 0.0, 0.0)},
                            integrator={"max_depth": 2}))
    image = sim.image
    power = np.abs(image.data) ** 2
    row = np.argmax(power.sum(axis=0))                        # the range column of the window row
    cut = power[:, row] * (np.abs(image.azimuth) < 14.0)
    spectrum = np.abs(np.fft.rfft(cut - cut.mean(), n=8 * len(cut)))
    freq = np.fft.rfftfreq(8 * len(cut), d=float(image.azimuth[1] - image.azimuth[0]))
    band = freq > 0.2
    peak = freq[band][np.argmax(spectrum[band])]
    assert peak == pytest.approx(1 / 2.5, rel=0.05), peak


def test_add_windows_cuts_the_plain_walls_of_a_closed_building():
    """A 20 m x 11 m box building, 9 m tall: its four walls are upright rectangles of two
    triangles each. With the default layout (3 m storeys and bays, 1.2 m x 1.5 m windows 0.15 m
    deep, 0.3 m of wall around each) the long walls hold 1 + (20 - 0.6 - 1.2) // 3 = 7 bays and the
    short ones 1 + (11 - 1.8) // 3 = 4, on 3 storeys: 66 windows; the body stays closed, its volume
    less each recess, ``66 x 1.2 x 1.5 x 0.15`` m^3, and the panes face out.
    A gable wall (a triangle) is left as it is. Bugs: bays counted from the wall's end instead of
    centred (a window cut by the corner), walls taken to face inward (recesses standing out of
    the body: the volume grows)."""
    box = trimesh.creation.box(bounds=[[0, 0, 0], [20, 11, 9]])
    layout = FacadeLayout()
    v, f, pv, pf, count = add_windows(box.vertices, box.faces, layout, "box")
    assert count == 2 * 3 * 7 + 2 * 3 * 4 == 66
    body = trimesh.Trimesh(np.vstack([v, pv]), np.vstack([f, pf + len(v)]), process=False)
    assert body.volume == pytest.approx(20 * 11 * 9 - 66 * 1.2 * 1.5 * 0.15, rel=1e-9)
    centre = np.array([10.0, 5.5, 4.5])
    panes = trimesh.Trimesh(pv, pf, process=False)
    outward = np.einsum("ij,ij->i", panes.face_normals, panes.triangles_center - centre)
    assert np.all(outward > 0)
    gable = trimesh.Trimesh([[0, 0, 0], [10, 0, 0], [5, 0, 6]], [[0, 2, 1]], process=False)
    v2, f2, _, pf2, n2 = add_windows(gable.vertices, gable.faces, layout)
    assert n2 == 0 and len(pf2) == 0 and np.array_equal(f2, gable.faces)


def test_add_windows_writes_a_scene_that_loads(tmp_path):
    """``scene add-windows`` on a scene file: the walls get windows, the panes a glass shape, and
    the copy loads with every shape; the original is untouched."""
    from sarmitsuba.scene.windowed import GLASS_ID, write_windowed
    box = trimesh.creation.box(bounds=[[-10, -5, 0], [10, 5, 9]])
    walls = trimesh.Trimesh(box.vertices, box.faces[np.abs(box.face_normals[:, 2]) < 0.5], process=False)
    walls.export(tmp_path / "walls.ply")
    (tmp_path / "city.xml").write_text(
        '<scene version="3.0.0"><sensor type="sar"><string name="scene_center" value="0, 0, 0"/></sensor>'
        '<bsdf type="itu-radio-material" id="marble"><string name="type" value="marble"/></bsdf>'
        '<shape type="ply" id="mesh-walls"><string name="filename" value="walls.ply"/><ref id="marble" name="bsdf"/></shape>'
        '<shape type="rectangle" id="ground"><transform name="to_world"><scale x="40" y="40"/></transform>'
        '<ref id="marble" name="bsdf"/></shape></scene>')
    written = write_windowed(tmp_path / "city.xml", tmp_path / "out", FacadeLayout())
    assert written.windows == 2 * 3 * 7 + 2 * 3 * 3 and written.facades == 1      # 20 m: 7 bays, 10 m: 3
    loaded = load_scene(str(written.path))
    ids = [s.id() for s in loaded.scene.shapes()]
    assert sorted(ids) == ["ground", "mesh-walls", "mesh-walls-windows"]
    pane = next(s for s in loaded.scene.shapes() if s.id() == "mesh-walls-windows")
    assert pane.bsdf().itu_name == "glass" and pane.bsdf().name == GLASS_ID
    assert len(trimesh.load(tmp_path / "walls.ply", process=False).faces) == 8


def test_info_counts_the_windows_of_a_footprint_city(tmp_path):
    """``scene from-footprints --windows`` then ``info``: the windows info counts are those the
    scene was built with (two pane triangles each). Bug: panes counted per triangle."""
    from sarmitsuba.info import scene_info
    from sarmitsuba.scene.city import build_city, write_city
    from pathlib import Path
    city = build_city(Path(__file__).resolve().parent.parent / "scenes" / "footprints.geojson", facade=FacadeLayout())
    path = write_city(city, tmp_path / "city")
    assert city.window_count() > 500
    assert scene_info(str(path)).scene.windows == city.window_count()
