"""Moving shapes that Mitsuba builds from their ``to_world`` (``rectangle``), and the refusal of a
moving shape that leaves the still shapes around it (docs/physics.md (V1)-(V3),
:mod:`sarmitsuba.scene.motion`, :func:`sarmitsuba.tracing.mesh.facets.set_vertices`).

Truth: a second representation of the same shape. A tilted PEC roof (a ``rectangle``) 3 m above a
rough floor, whose shadow and whose double bounce with the floor follow it, written once as the
rectangle and once as a PLY mesh of the rectangle's own vertex and face buffers (the same
triangles, the same vertex order): still, the two scenes render the same bits, so with the roof
moving (a velocity, or a turn about its centre) they must render the same bits too. For the
refusal: the closed form of the largest speed that keeps a box on its ground along a given
direction, ``min_a 2 room_a / (T |u_a|)`` over the horizontal axes (``room_a`` the margin to the
ground's edge, ``T`` the aperture's duration, ``u`` the unit direction: the box moves
``+- v T / 2`` about where it stands).

Deliberate bugs these tests were run against (each fails the test named):
  * a moving rectangle's ``to_world`` left as it was (its lanes moving, its rays meeting it where
    it stood: -13 dB): ``test_a_moving_rectangle_renders_as_the_same_moving_mesh``, both motions;
  * its rotation left out of the motion (the translation alone): the turning roof;
  * the speed named as ``|v| - 2 (excess) / T`` (right only for a velocity along an axis; the
    speed it names still takes the box off its ground): ``test_the_speed_named_for_an_oblique_velocity_stays``;
  * the speed rounded to the nearest, not down: the 30 deg case (1.0997 m/s named 1.10, which leaves);
  * the rectangle's ``to_world`` path removed from ``set_vertices`` (a rectangle not moved at all):
    the dihedral's moving floor, ``test_a_wall_flush_with_its_floor_is_refused_naming_the_axis``;
  * a moving sphere let through to the tracer: ``test_a_moving_sphere_is_refused_in_one_line``.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.core.valid_ranges import ParameterError
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.tracing.mesh.facets import scene_meshes

from test_moving_shapes import _two_boxes

REPO = Path(__file__).resolve().parents[1]
#: A 20 m rough floor and a 4 m PEC roof tilted 20 deg about x, 3 m up; ``ROOF`` stands for the
#: roof's ``<shape>``, ``MOTION`` for its motion.
SCENE = """<scene version="3.0.0">
    <sensor type="sar">
        <float name="bandwidth" value="150e6"/> <float name="sampling_rate" value="180e6"/>
        <float name="prf" value="250"/> <float name="altitude" value="1000"/>
        <float name="incidence_angle" value="40"/> <string name="scene_center" value="0, 0, 0"/>
        <float name="azimuth_beamwidth" value="1.2"/> <integer name="n_pulses" value="32"/>
    </sensor>
    <integrator type="sbr"><integer name="max_depth" value="2"/></integrator>
    <bsdf type="radar" id="rough"><string name="material" value="concrete"/><float name="gamma_db" value="-10"/></bsdf>
    <bsdf type="radar" id="metal"><string name="model" value="pec"/></bsdf>
    <shape type="rectangle" id="floor"><transform name="to_world"><scale x="10" y="10"/></transform><ref id="rough"/></shape>
    ROOF
</scene>"""
RECTANGLE = ('<shape type="rectangle" id="roof">MOTION<transform name="to_world"><scale x="2" y="2"/>'
             '<rotate x="1" angle="20"/><translate z="3"/></transform><ref id="metal"/></shape>')
PLY = '<shape type="ply" id="roof">MOTION<string name="filename" value="roof.ply"/><ref id="metal"/></shape>'


def _write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """An ASCII PLY of the triangles (Mitsuba keeps its vertex order)."""
    head = (f"ply\nformat ascii 1.0\nelement vertex {len(vertices)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    path.write_text(head + "".join(f"{float(a)!r} {float(b)!r} {float(c)!r}\n" for a, b, c in vertices)
                    + "".join(f"3 {a} {b} {c}\n" for a, b, c in faces))


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """``write(kind, motion) -> path``: the scene with its roof as the ``rectangle`` or as the PLY of
    the rectangle's own buffers, moving by ``motion`` (``<vector .../>`` elements, or "")."""
    folder = tmp_path_factory.mktemp("roof")
    still = folder / "still.xml"
    still.write_text(SCENE.replace("ROOF", RECTANGLE.replace("MOTION", "")))
    _write_ply(folder / "roof.ply", *scene_meshes(load_scene(str(still)).scene)[1])

    def write(kind: str, motion: str) -> str:
        path = folder / f"{kind}.xml"
        path.write_text(SCENE.replace("ROOF", (RECTANGLE if kind == "rectangle" else PLY).replace("MOTION", motion)))
        return str(path)
    return write


def test_the_still_roof_as_a_mesh_is_the_rectangle(scenes):
    """The premise of the next test: the rectangle given as its own triangles renders the same bits."""
    assert np.array_equal(simulate(scenes("rectangle", "")).raw.data, simulate(scenes("mesh", "")).raw.data)


@pytest.mark.parametrize("name, value", [("velocity", (8.0, 3.0, 0.0)), ("angular_velocity", (0.0, 30.0, 10.0))])
def test_a_moving_rectangle_renders_as_the_same_moving_mesh(scenes, name, value):
    """The roof (a ``rectangle``) driving at 8.5 m/s, or turning at 32 deg/s about its centre, over
    the still floor: the scene renders (it crashed with StopIteration: Mitsuba gives a rectangle no
    vertex buffer to move) and its raw data are those of the same roof given as a triangle mesh
    with the same motion, bit for bit; the motion changes them (against the still scene, by more
    than -30 dB)."""
    motion = f'<vector name="{name}" value="{", ".join(map(repr, value))}"/>'
    moving_rectangle = simulate(scenes("rectangle", motion))
    moving_mesh = simulate(scenes("mesh", motion))
    assert moving_rectangle.loaded.motion is not None
    assert np.array_equal(moving_rectangle.raw.data, moving_mesh.raw.data)
    still = simulate(scenes("rectangle", "")).raw.data
    if still.shape == moving_mesh.raw.data.shape:          # (a turn may widen the fast-time window)
        change = np.sum(np.abs(moving_mesh.raw.data - still.astype(complex)) ** 2) / np.sum(np.abs(still) ** 2.0)
        assert 10 * np.log10(change) > -30.0


def _dihedral_moving(tmp_path: Path, shape: str, velocity) -> str:
    """scenes/dihedral.xml with a ``velocity`` on its shape ``shape``."""
    text = (REPO / "scenes" / "dihedral.xml").read_text()
    tag = f'<shape type="rectangle" id="{shape}">'
    assert tag in text
    path = tmp_path / "dihedral.xml"
    path.write_text(text.replace(tag, tag + f'<vector name="velocity" value="{", ".join(map(repr, velocity))}"/>'))
    return str(path)


@pytest.mark.parametrize("velocity, axis", [((1.0, 0.0, 0.0), "x"), ((0.0, 0.5, 0.0), "y")])
def test_a_wall_flush_with_its_floor_is_refused_naming_the_axis(tmp_path, velocity, axis):
    """The built-in dihedral's wall spans its floor along x and stands on its near edge in y: moving
    along either it leaves the floor at any speed. The refusal says so, naming the axis, instead of
    a speed "below about 0 m/s" (it said 2.13e-14 m/s); its floor, which stands beyond the still
    wall, moves (it crashed with StopIteration)."""
    with pytest.raises(ParameterError, match=rf"shape 'wall': velocity .* beyond the still shapes .* edge along {axis}"
                                             rf" already: give it a velocity without an {axis} part") as caught:
        load_scene(_dihedral_moving(tmp_path, "wall", velocity), {"n_pulses": 16})
    assert "below about" not in str(caught.value)
    sim = simulate(_dihedral_moving(tmp_path, "floor", velocity), sensor_overrides={"n_pulses": 16})
    assert sim.loaded.motion is not None and np.sum(np.abs(sim.raw.data) ** 2) > 0


@pytest.mark.parametrize("angle_deg", [30.0, 60.0])
def test_the_speed_named_for_an_oblique_velocity_stays(angle_deg):
    """A 1 m box at x = 29.3 m on a 60 m ground (0.2 m from its edge along x, 29.5 m along y),
    driving at 3 m/s 30 or 60 deg off +x, over 63 / 150 = 0.42 s: refused, naming the largest speed
    along that direction that stays, ``2 x 0.2 / (0.42 cos(angle))`` (1.0997 and 1.9048 m/s; the
    y margin limits nothing) rounded down to three digits; at the speed named it loads, 1 % faster
    it is refused."""
    direction = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg)), 0.0])
    with pytest.raises(ParameterError, match="below about") as caught:
        load_scene(_two_boxes({"velocity": tuple(3.0 * direction)}, ground=True, at=29.3))
    named = float(re.search(r"below about ([0-9.eE+-]+) m/s", str(caught.value)).group(1))
    closed = 2.0 * 0.2 / (0.42 * np.cos(np.radians(angle_deg)))
    assert closed - 0.01 < named <= closed
    loaded = load_scene(_two_boxes({"velocity": tuple(named * direction)}, ground=True, at=29.3))
    assert loaded.motion is not None
    with pytest.raises(ParameterError, match="below about"):
        load_scene(_two_boxes({"velocity": tuple(1.01 * closed * direction)}, ground=True, at=29.3))


def test_a_moving_sphere_is_refused_in_one_line(tmp_path, capsys):
    """A sphere is no triangle mesh: nothing for the tracer to move (it raised from inside the
    trace). ``info`` refuses it before tracing: exit code 2, one line naming the shape and the fix."""
    from sarmitsuba.cli import main
    ball = ('<shape type="sphere" id="ball"><vector name="velocity" value="1, 0, 0"/>'
            '<point name="center" x="0" y="0" z="3"/><float name="radius" value="1"/><ref id="metal"/></shape>')
    path = tmp_path / "ball.xml"
    path.write_text(SCENE.replace("ROOF", ball))
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "shape 'ball': a moving shape must be a triangle mesh" in err[0], err
