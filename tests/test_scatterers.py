"""The scatterer catalogue (docs/physics.md (SC1)-(SC4)): phase centres against the geometry that
makes them, RCS against closed forms and the image, and the options' refusals.

The truths are independent of the catalogue's code:

* ``tests/scenes/tower.xml``: a 30 m tower (x in [-4, 4], y in [-8, 0]) with a trihedral whose
  apex sits on its roof at (0, 0, 30). The apex is where the triple bounce focuses; the wall
  facing the sensor (y = 0) meets the ground on the line y = z = 0, where the wall-ground double
  bounce focuses; the roof's corners are (+-4, 0 or -8, 30). The apex images at the layover of
  a point 30 m up, ``sqrt(Y^2 - 2 H h + h^2) - Y`` in ground range (docs/physics.md (G2),
  ``Y = H tan(theta)``), whatever the catalogue computes;
* the built-in trihedral's RCS ``4 pi a^4 / (3 lambda^2)`` (Knott, Shaeffer and Tuley, *Radar
  Cross Section*, 2nd ed., table 6.1) and the image's integrated RCS (K);
* a moving trihedral: the image itself puts its peak ``-R v_r / V`` along track (the shift a
  radial velocity ``v_r`` gives a point at range ``R`` seen from speed ``V``), with ``v_r`` the
  velocity's projection on the line of sight from mid-aperture.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.cli import main
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.pipeline import simulate
from sarmitsuba.analysis.impulse_model import integrated_rcs
from sarmitsuba.analysis.scatterers import check_selection, explain
from sarmitsuba.products.scatterer_files import read_csv
from sarmitsuba.tracing.integration.catalogue import phase_centres

REPO = Path(__file__).resolve().parents[1]
TOWER = str(REPO / "tests" / "scenes" / "tower.xml")
APEX = np.array([0.0, 0.0, 30.0])
ROOF_CORNERS = np.array([[x, y, 30.0] for x in (-4.0, 4.0) for y in (-8.0, 0.0)])
#: The acceptance's tolerance on phase centres, m.
TOLERANCE = 0.05
PULSES = 96


def _tower(heading: float, incidence: float, **sensor):
    return simulate(TOWER, sensor_overrides={"n_pulses": PULSES, "heading": heading, "incidence_angle": incidence,
                                             **sensor}, scatterers=True, scatterers_db=-100.0)


@pytest.fixture(scope="module", params=[(0.0, 45.0), (20.0, 40.0)], ids=["heading0-inc45", "heading20-inc40"])
def tower(request):
    heading, incidence = request.param
    return heading, incidence, _tower(heading, incidence)


def _rows(sim, order: int, shapes: str | None = None) -> np.ndarray:
    col = sim.scatterers.columns
    keep = col["order"] == order
    if shapes is not None:
        keep &= np.array([s == shapes for s in col["shapes"]])
    return np.flatnonzero(keep)


def _xyz(sim, rows) -> np.ndarray:
    col = sim.scatterers.columns
    return np.stack([col["x_m"][rows], col["y_m"][rows], col["z_m"][rows]], axis=1)


def test_the_triple_bounce_sits_on_the_apex_and_images_at_its_layover(tower):
    heading, incidence, sim = tower
    rows = _rows(sim, 3, "roof_reflector>roof_reflector>roof_reflector")
    assert len(rows) == 3                      # three bounce sequences, each with its reverse (SC4)
    assert np.max(np.linalg.norm(_xyz(sim, rows) - APEX, axis=1)) < TOLERANCE
    p = sim.loaded.params
    h, big_h = 30.0, p.altitude
    y = big_h * math.tan(math.radians(incidence))
    layover = math.sqrt(y * y - 2.0 * big_h * h + h * h) - y            # (G2), on the flat ground image
    col = sim.scatterers.columns
    assert np.max(np.abs(col["range_m"][rows] - layover)) < TOLERANCE
    assert np.max(np.abs(col["azimuth_m"][rows])) < TOLERANCE
    # 30 m above the scene centre (the reference of every pulse's phase): its cell's coherent
    # RCS is the image's integrated RCS there, within 0.5 dB
    image = 10.0 * math.log10(integrated_rcs(sim.image, center=tuple(APEX)))
    assert abs(col["cell_rcs_dbsm"][rows[0]] - image) < 0.5


def _off_the_feet(xyz: np.ndarray) -> np.ndarray:
    """Distance [m] of points from the tower's wall feet: y = 0 (its front, |x| <= 4) and x = +-4
    (its sides, -8 <= y <= 0), all at z = 0."""
    front = np.hypot(np.hypot(xyz[:, 1], xyz[:, 2]), np.maximum(np.abs(xyz[:, 0]) - 4.0, 0.0))
    side = np.hypot(np.hypot(np.abs(xyz[:, 0]) - 4.0, xyz[:, 2]), np.maximum(np.abs(xyz[:, 1] + 4.0) - 4.0, 0.0))
    return np.minimum(front, side)


def test_the_wall_ground_double_bounce_sits_on_the_walls_foot(tower):
    """The strong double bounces (within 10 dB of the strongest) lie on a wall's foot; looking
    obliquely, the tower's side wall has one too."""
    _, _, sim = tower
    rows = _rows(sim, 2, "ground>tower")
    strong = rows[sim.scatterers.columns["rcs_dbsm"][rows] > sim.scatterers.columns["rcs_dbsm"][rows].max() - 10.0]
    assert len(strong) >= 3
    assert np.max(_off_the_feet(_xyz(sim, strong))) < TOLERANCE


@pytest.mark.parametrize("heading, incidence", [(20.0, 40.0), (-25.0, 45.0)])
def test_a_roof_corners_single_bounce_sits_on_the_corner(heading, incidence):
    """An oblique look (the roof's edges not along the track): the roof's strongest single bounce
    is a corner's, on the corner; every roof row is on the roof's rim."""
    sim = _tower(heading, incidence)
    rows = _rows(sim, 1, "tower")
    roof = rows[np.abs(_xyz(sim, rows)[:, 2] - 30.0) < TOLERANCE]
    assert len(roof) >= 2
    strongest = roof[np.argmax(sim.scatterers.columns["rcs_dbsm"][roof])]
    corner = np.min(np.linalg.norm(ROOF_CORNERS - _xyz(sim, [strongest])[0], axis=1))
    assert corner < TOLERANCE
    xy = _xyz(sim, roof)[:, :2]
    rim = np.minimum(np.minimum(np.abs(np.abs(xy[:, 0]) - 4.0), np.abs(xy[:, 1])), np.abs(xy[:, 1] + 8.0))
    assert np.max(rim) < TOLERANCE


def test_phase_centres_of_chains_built_by_hand():
    """(SC1) on chains whose centres are known without the tracer: one bounce (the point itself),
    a trihedral (image theory puts a last point ``B`` at ``2 apex - B``: the centre is the apex)
    and a dihedral (``B`` on the wall mirrored in the floor: the centre is on the fold, at ``B``'s
    x). A far transmitter at 45 and 30 deg from the vertical (not symmetric in sin and cos) and
    30 deg off broadside: the dihedral's fold is oblique to the look."""
    rng = np.random.default_rng(3)
    for look in (45.0, 30.0):
        d = np.array([math.sin(math.radians(30.0)), math.cos(math.radians(30.0)), 0.0]) * math.sin(math.radians(look))
        t = 2000.0 * (d + np.array([0.0, 0.0, math.cos(math.radians(look))]))
        ts = np.broadcast_to(t, (6, 3))
        apex = np.array([1.0, -2.0, 3.0])
        b = apex + rng.uniform(-0.5, 0.5, (6, 3))
        u = 2.0 * apex - b
        length = np.linalg.norm(u - t, axis=1) + np.linalg.norm(b - t, axis=1)
        assert np.max(np.linalg.norm(phase_centres(ts, ts, u, b, length) - apex, axis=1)) < 1e-3
        b2 = np.column_stack([rng.uniform(-3, 3, 6), np.zeros(6), rng.uniform(0.1, 2, 6)])   # on the wall y = 0
        u2 = b2 * np.array([1.0, 1.0, -1.0])                                                  # the floor's mirror z = 0
        length2 = np.linalg.norm(u2 - t, axis=1) + np.linalg.norm(b2 - t, axis=1)
        p = phase_centres(ts, ts, u2, b2, length2)
        assert np.max(np.hypot(p[:, 1], p[:, 2])) < 5e-3 and np.allclose(p[:, 0], b2[:, 0], atol=5e-3)
        single = rng.uniform(-5, 5, (6, 3))
        one = np.linalg.norm(single - t[None], axis=1) * 2.0
        assert np.allclose(phase_centres(ts, ts, single, single, one), single, atol=1e-9)
    # the defining property, where the middle point alone is far from it: a transmitter 30 m away
    # (a drone) and a bistatic receiver, the dihedral's two-way length kept exactly
    t, r = np.array([0.0, 20.0, 22.0]), np.array([5.0, 25.0, 15.0])
    b2 = np.column_stack([rng.uniform(-3, 3, 6), np.zeros(6), rng.uniform(0.5, 3, 6)])
    u2 = b2 * np.array([1.0, 1.0, -1.0])
    length = np.linalg.norm(u2 - t, axis=1) + np.linalg.norm(b2 - r, axis=1)
    p = phase_centres(np.broadcast_to(t, b2.shape), np.broadcast_to(r, b2.shape), u2, b2, length)
    assert np.allclose(np.linalg.norm(p - t, axis=1) + np.linalg.norm(p - r, axis=1), length, rtol=0, atol=1e-9)
    assert np.max(np.linalg.norm(p - 0.5 * (u2 + b2), axis=1)) > 1e-3        # the steps did move it


def test_the_trihedrals_rcs_is_the_closed_form_and_the_images():
    """The catalogue's coherent sum in the apex's cell against 4 pi a^4 / (3 lambda^2) and against
    the image's integrated RCS (K), within 0.5 dB, at two incidences."""
    for incidence in (45.0, 38.0):
        sim = simulate("trihedral", sensor_overrides={"incidence_angle": incidence}, scatterers=True,
                       scatterers_db=-190.0)
        col = sim.scatterers.columns
        rows = np.flatnonzero(col["order"] == 3)
        assert len(rows) == 3
        cell = col["cell_rcs_dbsm"][rows[0]]
        lam, a = sim.loaded.params.wavelength, 1.5
        image = 10.0 * math.log10(integrated_rcs(sim.image, center=(0.0, 0.0, 0.0)))
        assert abs(cell - image) < 0.5, (incidence, cell, image)
        if incidence == 45.0:                  # on boresight: the closed form
            assert abs(cell - 10.0 * math.log10(4 * math.pi * a ** 4 / (3 * lam ** 2))) < 0.5
        # the shares of the apex's cell (every scatterer listed here) add up to its coherent power
        same = (col["row"] == col["row"][rows[0]]) & (col["column"] == col["column"][rows[0]])
        same = np.flatnonzero(np.isclose(col["cell_rcs_dbsm"], cell, rtol=0, atol=1e-9) & same)
        assert sum(col["share"][same]) * sim.scatterers.image_rcs == pytest.approx(10 ** (cell / 10), rel=1e-6)


def test_a_bistatic_receiver_sees_the_apex_and_the_walls_foot():
    """A receiver on its own track 1 deg steeper (the trihedral still returns to it): the triple
    bounce's centre on the apex and the double bounce's on the wall's foot, within 5 cm."""
    sim = _tower(0.0, 45.0, receiver_altitude=1000.0, receiver_incidence_angle=46.0, receiver_heading=0.0,
                 receiver_velocity=100.0)
    rows = _rows(sim, 3, "roof_reflector>roof_reflector>roof_reflector")
    assert len(rows) >= 1
    assert np.max(np.linalg.norm(_xyz(sim, rows) - APEX, axis=1)) < TOLERANCE
    foot = _rows(sim, 2)
    col = sim.scatterers.columns
    foot = foot[col["rcs_dbsm"][foot] > col["rcs_dbsm"][foot].max() - 10.0]
    assert len(foot) >= 3 and np.max(_off_the_feet(_xyz(sim, foot))) < TOLERANCE


def _moving_trihedral(tmp_path: Path, velocity) -> str:
    text = (REPO / "scenes" / "trihedral.xml").read_text()
    tag = '<shape type="obj" id="trihedral">'
    path = tmp_path / "trihedral.xml"
    path.write_text(text.replace(tag, tag + f'<vector name="velocity" value="{", ".join(map(repr, velocity))}"/>')
                    .replace('value="meshes/trihedral.obj"', f'value="{REPO / "scenes" / "meshes" / "trihedral.obj"}"'))
    return str(path)


def test_a_moving_trihedral_images_shifted_by_its_radial_velocity(tmp_path):
    """Moving at 0.6 m/s toward the sensor's side (+y): v_r = w . u (u from the mid-aperture
    antenna to the apex) and the shift -R v_r / V. The image's own peak moves there; the
    catalogue's row says so, and keeps its 3-D phase centre on the apex at mid-aperture."""
    sim = simulate(_moving_trihedral(tmp_path, (0.0, 0.6, 0.0)), scatterers=True)
    p = sim.loaded.params
    mid = sim.raw.tx_position[sim.raw.n_pulses // 2]
    u = -mid / np.linalg.norm(mid)
    v_r = float(np.array([0.0, 0.6, 0.0]) @ u)
    shift = -np.linalg.norm(mid) * v_r / p.velocity
    assert abs(shift) > 3.0                                           # several resolution cells
    i, j = np.unravel_index(np.argmax(np.abs(sim.image.data)), sim.image.data.shape)
    assert abs(sim.image.azimuth[i] - shift) < 0.6                    # the image itself: a cell
    col = sim.scatterers.columns
    rows = np.flatnonzero(col["order"] == 3)
    assert len(rows) >= 1
    assert np.allclose(col["radial_velocity_mps"][rows], v_r, rtol=0.02)
    assert np.allclose(col["azimuth_shift_m"][rows], shift, rtol=0.02)
    assert np.all(np.abs(col["azimuth_m"][rows] - shift) < TOLERANCE + 0.02 * abs(shift))
    assert np.max(np.linalg.norm(_xyz(sim, rows), axis=1)) < TOLERANCE
    # so does every sub-aperture's: the trace's rows, before the catalogue merges them (the shape
    # moves 0.5 m over the aperture; each sub-aperture's lanes are carried back to mid-aperture)
    trace = sim.trace.catalogue
    third = trace.order == 3
    centres = trace.centre[third] / trace.weight[third, None]
    assert np.max(np.linalg.norm(centres, axis=1)) < TOLERANCE


def test_render_writes_the_catalogue_and_explain_reads_it(tmp_path, capsys):
    out = tmp_path / "tri"
    assert main(["render", "trihedral", "--scatterers", "--out", str(out), "--no-progress"]) == 0
    for name in ("scatterers.csv", "scatterers.geojson", "fig_scatterers.png"):
        assert (out / name).is_file()
    columns = read_csv(out / "scatterers.csv")
    assert set(columns["shapes"]) >= {"trihedral>trihedral>trihedral"}
    capsys.readouterr()
    assert main(["analyze", str(out / "image.npz"), "--explain", "0,0"]) == 0
    import json
    report = json.loads(capsys.readouterr().out)
    assert report["rows"][0]["order"] == 3 and report["explained"] == pytest.approx(1.0, abs=0.1)
    # off the peak, in both axes: the resynthesis through the image's response (SC4) still gives
    # the pixel's value (a carrier phase or response off by a pixel turns it)
    for az, rg in ((0.0, 0.3), (0.3, 0.0), (-0.4, 0.3), (0.0, 1.0)):
        capsys.readouterr()
        assert main(["analyze", str(out / "image.npz"), f"--explain={az},{rg}"]) == 0
        report = json.loads(capsys.readouterr().out)
        assert report["explained"] == pytest.approx(1.0, abs=0.05) and report["residual"] < 0.01, (az, rg, report)
    from sarmitsuba.core.image import SarImage
    image = SarImage.load(out / "image.npz")
    with pytest.raises(ParameterError, match="outside the image"):
        explain(image, columns, float(image.azimuth.max()) + 1.0, 0.0)


@pytest.mark.parametrize("flag, value", [("--scatterers-db", "3"), ("--scatterers-db", "nan"),
                                         ("--scatterers-db", "-250"), ("--scatterers-share", "0"),
                                         ("--scatterers-share", "1.5")])
def test_bad_catalogue_options_are_refused_before_tracing(flag, value, tmp_path, capsys):
    code = main(["render", "trihedral", "--scatterers", flag, value, "--out", str(tmp_path / "x"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and flag in err
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())


def test_explain_outside_the_image_exits_2(tmp_path, capsys):
    out = tmp_path / "tri"
    assert main(["render", "trihedral", "--scatterers", "--out", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["analyze", str(out / "image.npz"), "--explain=-900,0"]) == 2
    err = capsys.readouterr().err
    assert "outside the image" in err and err.count("\n") == 1


def test_check_selection_bounds():
    assert check_selection(0.9, None) == (0.9, None)
    assert check_selection(1.0, 0.0) == (1.0, 0.0)
    for share, floor in ((0.9, 0.1), (0.9, -200.0), (0.9, float("nan")), (-0.1, None), (0.9, "x")):
        with pytest.raises(ParameterError):
            check_selection(share, floor)


def test_single_bounces_lie_on_the_stacks_elevation_truth(tower):
    """The heights where each pixel's iso-range circle meets the visible geometry (the stack's
    ``truth.npz``, :func:`iso_range_heights`, a ray fan independent of the tracer): the 8 strongest
    single bounces of the tower and the ground each find their phase centre's height there, at
    their pixel or a neighbour (the fan's plane through a row passes a corner by up to half a
    pixel, and an edge's truth is good to a hit spacing), within a pixel spacing over tan(theta)
    (the fan's resolution on a facade)."""
    from sarmitsuba.products.elevation_truth import iso_range_heights
    _, incidence, sim = tower
    col = sim.scatterers.columns
    # the tower's and the ground's (the fan's rays, a pixel spacing over oversample apart, can miss
    # the 1.5 m reflector's edges whole)
    rows = np.flatnonzero((col["order"] == 1) & np.isin(col["shapes"], ["tower", "ground"]))
    rows = rows[np.argsort(-col["rcs_dbsm"][rows])[:8]]                 # the 8 strongest single bounces
    assert len(rows) >= 3
    spacing = abs(float(sim.image.range[1] - sim.image.range[0]))
    tolerance = max(spacing / math.tan(math.radians(incidence)), spacing)
    for i in rows:
        r, c = col["row"][i], col["column"][i]
        heights = iso_range_heights(sim.loaded, sim.image, np.arange(max(r - 1, 0), r + 2))[:, max(c - 1, 0):c + 2]
        assert np.nanmin(np.abs(heights - col["z_m"][i])) < tolerance, (col["shapes"][i], col["z_m"][i], heights)


def test_clutter_is_summarised_per_surface_as_its_sigma_nought():
    """A homogeneous rough ground of gamma = -10 dB (``tests/scenes/rough_ground.xml``): no speck
    of it is listed as a scatterer; its summary covers the pixels of its 80 m x 80 m at the
    image's spacing (within the image) and reads sigma0 = gamma cos(theta) (-11.5 dB at 45 deg),
    within 1 dB (speckle over some thousand cells)."""
    sim = simulate(str(REPO / "tests" / "scenes" / "rough_ground.xml"), scatterers=True)
    summary = {c["surface"]: c for c in sim.scatterers.clutter}
    assert set(summary) == {"ground"}
    theta = math.radians(sim.loaded.params.incidence_angle)
    assert abs(summary["ground"]["sigma0_db"] - (-10.0 + 10.0 * math.log10(math.cos(theta)))) < 1.0
    spacing = abs(float(sim.image.azimuth[1] - sim.image.azimuth[0])) * abs(float(sim.image.range[1] - sim.image.range[0]))
    inside = min(80.0, float(np.ptp(sim.image.azimuth))) * min(80.0, float(np.ptp(sim.image.range)))
    assert summary["ground"]["pixels"] == pytest.approx(inside / spacing, rel=0.1)
