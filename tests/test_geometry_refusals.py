"""Impossible or wasteful geometry is refused before tracing, naming the cause (issue 28).

- a track that passes over the scene (geometry at or beyond the nadir, on the side the radar
  does not look): mirrored ghosts (docs/physics.md (G4));
- a scene below the radar horizon (grazing incidence_angle, 89.99 deg);
- a mesh that cannot scatter (every triangle of zero area);
- an automatic track mostly empty because shapes lie kilometres along track from scene_center.

Each is refused by ``info`` (no tracing) and the loader with one line, exit 2 at the command
line, before the memory check could blame the pulses.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.cli import main
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.scene import canonical as C
from sarmitsuba.scene.loader import SceneError, load_scene
from sarmitsuba.scene.meshcheck import MeshDefectWarning

TRIHEDRAL_OBJ = Path(__file__).resolve().parents[1] / "scenes" / "meshes" / "trihedral.obj"
#: Effective earth radius of the radar horizon, 4/3 of 6371 km (docs/physics.md (G4)).
EARTH = 4.0 / 3.0 * 6.371e6


def _refused(capsys, argv: list[str]) -> str:
    """Run the CLI; it must exit 2 with exactly one ``error:`` line on stderr and no traceback."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err and "memory" not in err
    return lines[0]


def _plate(y0: float, y1: float, x0: float = -0.5, x1: float = 0.5) -> trimesh.Trimesh:
    """A horizontal plate on z = 0 over ``[x0, x1] x [y0, y1]``, facing up."""
    vertices = [[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]]
    return trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], process=False)


# ============================================================================ the nadir
@pytest.mark.parametrize("incidence, look_side, altitude", [(30.0, "right", 20.0), (60.0, "left", 20.0),
                                                            (45.0, "right", 300.0)])
def test_geometry_beyond_the_nadir_is_refused_just_inside_it_accepted(incidence, look_side, altitude):
    """Heading 0, scene_center at the origin: the nadir track lies ``G = h tan(theta)`` from it on
    the sensor's side (+y looking right, -y looking left). A plate centred 1 m beyond the nadir
    (ground range -1.5 .. -0.5 m) is refused naming it, the altitude and the incidence angle;
    the same plate on the other side of the nadir (ground range 0.5 .. 1.5 m) loads."""
    ground = altitude * math.tan(math.radians(incidence))
    side = 1.0 if look_side == "right" else -1.0            # sign of y on the sensor's side
    sensor = {"altitude": altitude, "incidence_angle": incidence, "look_side": look_side,
              "scene_center": (0.0, 0.0, 0.0), "n_pulses": 16, "bandwidth": 150e6, "prf": 250}

    def scene(y: float) -> sarmitsuba.Scene:
        edge = sorted((side * (y - 0.5), side * (y + 0.5)))
        return sarmitsuba.Scene([(_plate(-0.5, 0.5), "pec", "centre"), (_plate(*edge), "pec", "edge")],
                                sensor=sensor)

    with pytest.raises(ParameterError) as refused:
        load_scene(scene(ground + 1.0))
    message = str(refused.value)
    assert "'edge'" in message and "altitude" in message and "incidence_angle" in message
    assert f"{altitude:g} m" in message and f"{incidence:g} deg" in message
    assert "look_side" in message and "track_offset" in message
    # the fix it names works: the altitude it asks for puts the plate on the valid side
    needed = (ground + 1.5) / math.tan(math.radians(incidence))
    assert f"{needed:.1f} m" in message
    loaded = load_scene(scene(ground - 1.0))                  # ground range 0.5 .. 1.5 m: accepted
    assert loaded.n_shapes == 2
    assert load_scene(scene(ground + 1.0), sensor_overrides={"altitude": needed + 0.1}).n_shapes == 2


@pytest.mark.parametrize("argv", [["--set", "altitude=60", "--set", "incidence_angle=30"],
                                  ["--set", "altitude=60", "--set", "incidence_angle=30", "--set", "look_side=left"],
                                  ["--set", "altitude=100", "--set", "incidence_angle=45", "--set", "heading=90"]])
def test_info_refuses_a_track_over_the_urban_scene(capsys, argv):
    """urban is 240 m wide: from 60 m at 30 deg its nadir (34.6 m from the centre) lies inside
    it. Today info says "Warnings: none" and render makes mirrored ghosts."""
    err = _refused(capsys, ["info", "urban", *argv])
    assert "altitude" in err and "incidence_angle" in err and "nadir" in err


def test_render_refuses_a_track_over_the_scene_before_tracing(tmp_path, capsys):
    out = tmp_path / "out"
    err = _refused(capsys, ["render", "urban", "--set", "altitude=60", "--set", "incidence_angle=30",
                            "--out", str(out), "--no-progress"])
    assert "nadir" in err
    assert not out.exists() or not any(out.iterdir())


# ============================================================================ the horizon
@pytest.mark.parametrize("altitude", [1000.0, 10000.0])
def test_incidence_beyond_the_radar_horizon_is_refused(capsys, altitude):
    """The trihedral (apex at the scene centre, 1.5 m high: `hi_z`) is in view while the slant
    range ``h / cos(theta)`` is below the horizon's ``sqrt(2 k R h + h^2) + sqrt(2 k R z + z^2)``
    (k R = 4/3 earth radius). 0.05 deg below that incidence loads; 0.05 deg above is refused
    naming incidence_angle and the largest valid value."""
    top = load_scene("trihedral").bbox_hi[2]
    horizon = math.sqrt(2 * EARTH * altitude + altitude ** 2) + math.sqrt(2 * EARTH * top + top ** 2)
    limit = math.degrees(math.acos(altitude / horizon))
    ok = load_scene("trihedral", {"altitude": altitude, "incidence_angle": limit - 0.05, "n_pulses": 8})
    assert ok.params.incidence_angle == pytest.approx(limit - 0.05)
    err = _refused(capsys, ["info", "trihedral", "--set", f"altitude={altitude:g}",
                            "--set", f"incidence_angle={limit + 0.05!r}"])
    assert "incidence_angle" in err and "horizon" in err and f"{limit:.2f} deg" in err


def test_grazing_incidence_names_the_incidence_not_the_memory(capsys):
    """89.99 deg: the slant range is 5,730 km; today the memory check blames the pulses."""
    err = _refused(capsys, ["info", "trihedral", "--set", "incidence_angle=89.99"])
    assert "incidence_angle = 89.99 deg" in err and "horizon" in err and "altitude" in err


# ============================================================================ meshes that cannot scatter
COLLINEAR = trimesh.Trimesh([[0.0, 0.0, 0.0], [1.0, 1.0, 0.5], [2.0, 2.0, 1.0]], [[0, 1, 2]], process=False)
FLAT = trimesh.Trimesh([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]],
                       [[0, 1, 2], [1, 2, 3]], process=False)      # every vertex on the x axis


@pytest.mark.parametrize("mesh", [FLAT, trimesh.Trimesh(np.zeros((3, 3)), [[0, 1, 2]], process=False)],
                         ids=["collinear", "one point"])
def test_a_scene_whose_every_triangle_has_zero_area_is_refused(tmp_path, capsys, mesh):
    """A PLY whose triangles all have zero area wrote all-zero products with exit 0: it is refused,
    naming the shape by its file (the XML gives it no id)."""
    xml = C.scene_xml(tmp_path, mesh, C.PEC, 3, name="flat")
    err = _refused(capsys, ["info", str(xml)])
    assert "flat.ply" in err and "zero area" in err and "cannot scatter" in err


def test_a_python_scene_of_degenerate_meshes_is_refused_naming_them():
    scene = sarmitsuba.Scene([(FLAT, "pec", "wire"), (COLLINEAR.copy(), "pec", "kink")],
                             sensor={"n_pulses": 8, "scene_center": (0, 0, 0)})
    with pytest.raises(SceneError, match=r"'wire'.*'kink'|'kink'.*'wire'"):
        load_scene(scene)


def test_one_degenerate_shape_among_good_ones_warns_naming_it():
    """The rest of the scene is a valid simulation (a zero-area shape neither scatters nor
    shadows): it loads, with a warning that names the shape that is missing from the image."""
    scene = sarmitsuba.Scene([(_plate(-1.0, 1.0), "pec", "plate"), (FLAT, "pec", "wire")],
                             sensor={"n_pulses": 8, "scene_center": (0, 0, 0)})
    with pytest.warns(MeshDefectWarning, match=r"wire: all 2 triangles have zero area.*cannot scatter"):
        loaded = load_scene(scene)
    assert loaded.n_shapes == 2


# ============================================================================ along the track
def test_scene_center_50_km_along_track_names_the_distance_not_the_memory(capsys):
    """The trihedral lies 50 km along track from scene_center: the automatic track (100 km,
    250,000 pulses) is refused naming scene_center and the shape, not the memory."""
    err = _refused(capsys, ["info", "trihedral", "--set", "scene_center=50000,0,0"])
    assert "scene_center" in err and "'trihedral'" in err and "50.0 km along track" in err
    assert "n_pulses" in err


def _two_shapes(tmp_path: Path, heading: float, far: tuple[float, float]) -> Path:
    """The trihedral at the origin (scene_center) and a second one at ``far`` = (x, y) [m]."""
    xml = tmp_path / "far.xml"
    xml.write_text(f"""<scene version="3.0.0">
    <sensor type="sar"><float name="bandwidth" value="150e6"/><float name="prf" value="250"/>
        <float name="azimuth_beamwidth" value="1.2"/><float name="heading" value="{heading}"/>
        <string name="scene_center" value="0, 0, 0"/></sensor>
    <integrator type="sbr"><integer name="max_depth" value="1"/></integrator>
    <bsdf type="radar" id="metal"><string name="model" value="pec"/></bsdf>
    <shape type="obj" id="near"><string name="filename" value="{TRIHEDRAL_OBJ}"/><ref id="metal"/></shape>
    <shape type="obj" id="outlier"><string name="filename" value="{TRIHEDRAL_OBJ}"/>
        <transform name="to_world"><translate x="{far[0]}" y="{far[1]}"/></transform><ref id="metal"/></shape>
</scene>""")
    return xml


@pytest.mark.parametrize("heading, far", [(0.0, (3000.0, 0.0)), (90.0, (0.0, 3000.0)), (180.0, (-4000.0, 0.0))])
def test_a_shape_kilometres_along_track_from_scene_center_is_refused(tmp_path, capsys, heading, far):
    """Today: 15,000 pulses (723 MB) and no warning, 97 % of them seeing nothing. With n_pulses
    given the track is the user's own and loads; the same outlier 300 m across track (beyond the
    scene from the sensor) leaves the automatic track short and loads."""
    xml = _two_shapes(tmp_path, heading, far)
    distance = math.hypot(*far)
    err = _refused(capsys, ["info", str(xml)])
    assert "'outlier'" in err and f"{distance / 1000:.1f} km along track" in err and "scene_center" in err
    assert "n_pulses" in err
    assert main(["info", str(xml), "--pulses", "64"]) == 0
    capsys.readouterr()
    across = _two_shapes(tmp_path, heading, (300.0 * math.sin(math.radians(heading)),
                                             -300.0 * math.cos(math.radians(heading))))
    assert load_scene(str(across)).params.n_pulses < 1000      # 300 m across track: a short track, loads
