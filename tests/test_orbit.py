"""ECEF orbits (issue 55, item 2; docs/physics.md (J5), (J6)): a Sentinel-1 orbit file flies the
scene's sensor, carried into the scene's ENU frame at ``geo_origin`` with no flat-earth step.

The test data, tests/data/orbit/synthetic_s1_poeorb.EOF, is a Sentinel-1-like precise orbit file
in the Earth Explorer layout (two-body + J2, 10 s OSVs; written by tests/data/orbit/make_orbit.py),
and SCENE the point it sees at 35 deg incidence, right-looking, at the middle OSV.

Acceptance:
- the orbit images a trihedral at ``geo_origin`` within 0.1 resolution cell (backprojection);
- the orbit as rendered (CPHD ``TxPos``/``TxVel`` read with sarkit, at ``CollectionStart +
  TxTime``) is within 1 mm (1 mm/s) of the file's Hermite interpolation at every pulse, in ECEF.
  The oracle is computed here from the XML alone (xml.etree): on each 10 s interval, the degree-7
  polynomial through the positions and velocities of the 4 OSVs around it, by solving its
  confluent Vandermonde system with numpy (not scipy's Krogh form that sarmitsuba uses).
"""
from __future__ import annotations

import datetime
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh
from pyproj import Transformer

from sarmitsuba.core.trajectory import TrajectoryError, read_state_vectors

sarkit_cphd = pytest.importorskip("sarkit.cphd")

EOF_FILE = Path(__file__).parent / "data" / "orbit" / "synthetic_s1_poeorb.EOF"
SCENE = (49.165796, 12.278661, 0.0)          # printed by make_orbit.py: 35.0002 deg incidence
OTHER = (47.2, 14.9, 300.0)                  # a second origin: another latitude, longitude and incidence
RADAR = {"prf": 4000.0, "azimuth_beamwidth": 0.3, "n_pulses": 1501}


def eof_oracle() -> tuple[datetime.datetime, np.ndarray, np.ndarray, np.ndarray]:
    """(UTC of the first OSV, times [s] from it, ECEF positions [m], velocities [m/s]) from the XML."""
    osvs = ET.parse(EOF_FILE).getroot().find("Data_Block/List_of_OSVs").findall("OSV")
    stamps = [datetime.datetime.fromisoformat(o.findtext("UTC")[4:]).replace(tzinfo=datetime.timezone.utc)
              for o in osvs]
    t = np.array([(s - stamps[0]).total_seconds() for s in stamps])
    pos = np.array([[float(o.findtext(k)) for k in ("X", "Y", "Z")] for o in osvs])
    vel = np.array([[float(o.findtext(k)) for k in ("VX", "VY", "VZ")] for o in osvs])
    return stamps[0], t, pos, vel


def hermite_oracle(t_query: np.ndarray, t: np.ndarray, pos: np.ndarray, vel: np.ndarray, m: int = 4):
    """(position, velocity) of the degree-(2m-1) Hermite polynomial through the m OSVs around each
    query's interval (two on each side, moved inwards at the ends), by a confluent Vandermonde solve."""
    out_p, out_v = np.empty((t_query.size, 3)), np.empty((t_query.size, 3))
    for q, tq in enumerate(t_query):
        i = min(max(int(np.searchsorted(t, tq, side="right")) - 1, 0), t.size - 2)
        s = min(max(i - (m // 2 - 1), 0), t.size - m)
        x = (t[s:s + m] - tq) / 10.0                      # the query at 0, scaled for conditioning
        powers = np.arange(2 * m)
        rows = np.vstack([x[:, None] ** powers, powers * np.where(powers > 0, x[:, None], 1.0) ** (powers - 1)])
        rhs = np.vstack([pos[s:s + m] - pos[s], vel[s:s + m] * 10.0])
        coef = np.linalg.solve(rows, rhs)
        out_p[q], out_v[q] = coef[0] + pos[s], coef[1] / 10.0
    return out_p, out_v


def trihedral_facing_the_orbit(origin) -> "object":
    """The built-in trihedral (boresight 45 deg up toward +y) turned about z toward the satellite at
    the middle OSV, as seen in the ENU frame at ``origin`` (PROJ's topocentric, here)."""
    import sarmitsuba
    from sarmitsuba.scene.canonical import trihedral
    _, _, pos, _ = eof_oracle()
    lat, lon, h = origin
    pipe = Transformer.from_pipeline(f"+proj=pipeline +step +proj=topocentric +ellps=WGS84 +lat_0={lat} "
                                     f"+lon_0={lon} +h_0={h}")
    e, n, _ = pipe.transform(*pos[pos.shape[0] // 2])
    mesh = trihedral(1.0)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.atan2(n, e) - math.pi / 2, [0, 0, 1]))
    return sarmitsuba.Scene([(mesh, "pec", "trihedral")])


@pytest.fixture(scope="module")
def orbit_run(tmp_path_factory):
    """(SimulationResult, CPHD path) of the trihedral seen by the orbit file."""
    from sarmitsuba.formats.cphd import write_cphd
    from sarmitsuba.pipeline import simulate
    sim = simulate(trihedral_facing_the_orbit(SCENE), focuser="bp", image_size=(112, 48),
                   sensor_overrides={"trajectory": str(EOF_FILE), "geo_origin": ", ".join(map(str, SCENE)), **RADAR})
    return sim, write_cphd(sim.raw, tmp_path_factory.mktemp("orbit") / "raw.cphd")


def test_the_orbit_images_a_trihedral_at_geo_origin(orbit_run):
    """Catches ECEF/ENU axes swapped or velocities left unrotated (the track would pass elsewhere,
    or curve, and the trihedral would smear or shift) and a pass picked away from closest
    approach (a squinted aperture: the beam would miss it): within 0.1 cell in both axes."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    sim, _ = orbit_run
    report = analyze_point_target(sim.image, (0.0, 0.0, 0.0), chip=32)
    assert abs(report.azimuth_error_cells) < 0.1 and abs(report.range_error_cells) < 0.1, report


def test_the_cphd_orbit_is_the_files_hermite_interpolation_in_ecef(orbit_run):
    """Catches a time offset between the file's clock and the CPHD's (1 us is 7.6 mm here), velocities
    not rotated into the ENU frame (the Hermite interpolant between OSVs bends), ECEF/ENU axes
    swapped: every pulse's TxPos within 1 mm, TxVel within 1 mm/s (the acceptance). The pulses lie
    within 0.2 s of an OSV, where every interpolant agrees: the next test checks the interpolant."""
    _, path = orbit_run
    with open(path, "rb") as f, sarkit_cphd.Reader(f) as reader:
        _, pvp = reader.read_channel("1")
        start = reader.metadata.xmltree.findtext("{*}Global/{*}Timeline/{*}CollectionStart")
    first, t, pos, vel = eof_oracle()
    start = datetime.datetime.fromisoformat(start.replace("Z", "+00:00"))
    start = start if start.tzinfo else start.replace(tzinfo=datetime.timezone.utc)
    times = (start - first).total_seconds() + pvp["TxTime"]
    want_p, want_v = hermite_oracle(times, t, pos, vel)
    assert np.max(np.linalg.norm(pvp["TxPos"] - want_p, axis=1)) < 1e-3
    assert np.max(np.linalg.norm(pvp["TxVel"] - want_v, axis=1)) < 1e-3
    # the aperture is centred on the closest approach to the scene (zero Doppler at the middle OSV)
    assert abs(0.5 * (times[0] + times[-1]) - 150.0) < 1.0 / RADAR["prf"]


def test_the_interpolant_is_the_files_hermite_window_between_osvs():
    """Catches an interpolant other than the 4-point Hermite window, all across the file and
    midway between OSVs (scipy's piecewise cubic Hermite is 0.2 mm off it here, a spline through
    positions alone 2 mm): the ECEF track (carried through the scene frame and back with pyproj)
    within 10 um and 10 um/s of the oracle."""
    from sarmitsuba.core import georef, orbit
    from sarmitsuba.core.trajectory import from_state_vectors
    _, t, pos, vel = eof_oracle()
    query = np.linspace(0.3, 299.7, 1001)
    want_p, want_v = hermite_oracle(query, t, pos, vel)
    ref = georef.GeoReference(*OTHER)
    path = from_state_vectors(orbit.in_scene_frame(read_state_vectors(EOF_FILE), ref))
    got_p = georef.enu_to_ecef(path.position(query), ref)
    got_v = path.velocity(query) @ georef.enu_axes(ref)
    assert np.max(np.linalg.norm(got_p - want_p, axis=1)) < 1e-5
    assert np.max(np.linalg.norm(got_v - want_v, axis=1)) < 1e-5


@pytest.mark.parametrize("origin, incidence", [(SCENE, 35.0002), (OTHER, None)])
def test_pass_geometry_matches_the_ellipsoid_normals_in_ecef(origin, incidence):
    """Catches east and north swapped, or up taken as the geocentric direction, in the carriage of
    the orbit into the scene frame: at two origins (different latitude and longitude) the look and
    incidence angles, slant range and squint at closest approach equal those computed here in ECEF
    from the oracle orbit and the closed-form ellipsoid normal (cos(lat) cos(lon), cos(lat) sin(lon),
    sin(lat)); at SCENE the incidence is make_orbit.py's 35.0002 deg. Also catches pulses centred on
    the middle of the file rather than on the closest approach."""
    from sarmitsuba.core import georef, orbit
    _, t, pos, vel = eof_oracle()
    lat, lon, h = origin
    scene = np.array(Transformer.from_crs("EPSG:4979", "EPSG:4978").transform(lat, lon, h))
    fine = np.linspace(t[0], t[-1], 300001)
    p_all, _ = hermite_oracle(fine[::100], t, pos, vel)
    k = int(np.argmin(np.linalg.norm(p_all - scene, axis=1))) * 100
    near = fine[max(k - 100, 0):k + 101]
    p_near, v_near = hermite_oracle(near, t, pos, vel)
    j = int(np.argmin(np.linalg.norm(p_near - scene, axis=1)))
    p, v = p_near[j], v_near[j]

    def normal(la, lo):
        la, lo = math.radians(la), math.radians(lo)
        return np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
    u = (scene - p) / np.linalg.norm(scene - p)
    sat_lat, sat_lon, _ = Transformer.from_crs("EPSG:4978", "EPSG:4979").transform(*p)
    want_incidence = math.degrees(math.acos(-u @ normal(lat, lon)))
    want_look = math.degrees(math.acos(-u @ normal(sat_lat, sat_lon)))
    got = orbit.pass_geometry(read_state_vectors(EOF_FILE), georef.GeoReference(*origin), np.zeros(3))
    assert abs(got.incidence - want_incidence) < 1e-3 and abs(got.look_angle - want_look) < 1e-3, (got, want_look)
    assert abs(got.slant_range - np.linalg.norm(scene - p)) < 0.05 and abs(got.squint) < 1e-4
    assert abs(got.speed - np.linalg.norm(v)) < 1e-3
    if incidence is not None:
        assert abs(got.incidence - incidence) < 1e-3
    # the pulses centre on that closest approach (OTHER's lies 1.6 min from the file's middle)
    from sarmitsuba.core.geometry import pulse_times, trajectory_of
    from sarmitsuba.core.radar import RadarParameters
    params = RadarParameters(trajectory=read_state_vectors(EOF_FILE), geo_origin=origin, scene_center=(0.0, 0.0, 0.0),
                             n_pulses=101, prf=100.0)
    assert abs(pulse_times(params, trajectory_of(params))[50] - near[j]) < 2e-3
    assert abs(got.time - near[j]) < 2e-3


@pytest.mark.parametrize("edit, words", [
    (("<X unit=\"m\">", "<X unit=\"km\">"), ["line 30", "<X>", "unit 'km'", "metres"]),
    (("<VZ unit=\"m/s\">-3948.590387</VZ>", ""), ["line 25", "<VZ>", "missing", "VX, VY, VZ"]),
    (("<UTC>UTC=2026-06-15T05:17:40", "<UTC>UTC=2026-06-15T25:17:40"), ["line 40", "<UTC>", "ISO 8601"]),
    (("EARTH_FIXED", "INERTIAL"), ["line 19", "Ref_Frame", "EARTH_FIXED"]),
    (("Earth_Explorer_File>", "Orbit_File>"), ["line 2", "<Earth_Explorer_File>"]),
    (("</Data_Block>", "</Data_Bloc>"), ["not readable as XML"]),
])
def test_a_malformed_orbit_file_names_the_line_and_the_fix(tmp_path, edit, words):
    """Catches a broken EOF read silently (kilometres as metres, a missing coordinate as 0, an
    inertial orbit as Earth-fixed): each is refused naming the file, the line and the element."""
    text = EOF_FILE.read_text()
    bad = tmp_path / "broken.EOF"
    bad.write_text(text.replace(*edit, 1) if "Earth_Explorer_File" not in edit[0] else text.replace(*edit))
    with pytest.raises(TrajectoryError) as info:
        read_state_vectors(bad)
    assert "broken.EOF" in str(info.value) and all(w in str(info.value) for w in words), str(info.value)


def test_an_ecef_csv_is_the_same_orbit_as_the_eof(tmp_path):
    """Catches an ECEF CSV (``# frame = ecef``) read as scene coordinates or interpolated otherwise
    than the orbit file: the same state vectors give the same track to a micrometre."""
    from sarmitsuba.core import georef, orbit
    from sarmitsuba.core.trajectory import from_state_vectors
    first, t, pos, vel = eof_oracle()
    rows = [f"{(first + datetime.timedelta(seconds=float(s))).isoformat().replace('+00:00', 'Z')},"
            + ",".join(f"{x:.6f}" for x in (*p, *v)) for s, p, v in zip(t, pos, vel)]
    csv = tmp_path / "orbit.csv"
    csv.write_text("# frame = ecef\nutc,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps\n" + "\n".join(rows) + "\n")
    ref = georef.GeoReference(*SCENE)
    a = from_state_vectors(orbit.in_scene_frame(read_state_vectors(csv), ref))
    b = from_state_vectors(orbit.in_scene_frame(read_state_vectors(EOF_FILE), ref))
    query = np.linspace(3.0, 297.0, 50)
    assert np.max(np.abs(a.position(query) - b.position(query))) < 1e-6


def test_info_reports_the_pass_and_render_refuses_a_broken_orbit_file(tmp_path, capsys):
    """Catches the orbit's geometry missing from ``info`` (only the flat-earth altitude and look
    angle, 677 km and 35 deg here, against 693 km and 31.16 deg on the ellipsoid), and a broken
    orbit file ending in a traceback rather than exit 2 with the file and line."""
    from sarmitsuba.cli import main
    args = ["info", "trihedral", "--set", f"trajectory={EOF_FILE}", "--set", "geo_origin=" + ", ".join(map(str, SCENE))]
    args += [a for k, v in RADAR.items() for a in ("--set", f"{k}={v}")]
    assert main(args) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "orbit at closest approach" in x)
    assert "2026-06-15T05:20:00" in line and "incidence 35.000 deg" in line and "look angle 31.16" in line, line
    assert "693.000 km above the ellipsoid" in line, line
    bad = tmp_path / "broken.EOF"
    bad.write_text(EOF_FILE.read_text().replace('<Y unit="m">', '<Y unit="mm">', 1))
    assert main(["info", "trihedral", "--set", f"trajectory={bad}"]) == 2
    err = capsys.readouterr().err
    assert "broken.EOF, line 31" in err and "Traceback" not in err, err


def test_an_orbit_file_far_from_geo_origin_is_refused_naming_geo_origin(capsys):
    """An orbit file with the placeholder geo_origin (0 N 0 E, 5000 km from this orbit's pass):
    exit 2 with a message that names geo_origin as the fix. Catches the refusal that told a
    user to check the scene frame or scene_center, which an ECEF orbit does not use."""
    from sarmitsuba.cli import main
    assert main(["info", "trihedral", "--set", f"trajectory={EOF_FILE}"]) == 2
    err = capsys.readouterr().err
    assert "set geo_origin" in err and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1, err


GM, OMEGA = 3.986004418e14, 7.292115e-5      # WGS84 (NIMA TR8350.2 table 3.1)


@pytest.mark.parametrize("origin, incidence, side, inclination, ascending", [
    ((48.1, 11.6, 500.0), 35.0, "right", 98.18, False),
    ((-33.9, 151.2, 20.0), 42.0, "left", 97.4, True),
    ((0.5, -60.0, 0.0), 25.0, "right", 51.6, True),
])
def test_the_builtin_orbit_passes_the_scene_as_asked(origin, incidence, side, inclination, ascending):
    """Catches the Earth's rotation added with the wrong sign (v_ecef = v + W x r), a look side or
    direction flipped, the altitude taken above a sphere or the scene's tangent plane, and the
    incidence taken against the geocentric radius: checked in ECEF from the state vectors alone
    (scipy's Hermite spline, the closed-form ellipsoid normal, pyproj's heights) at three origins,
    north and south, at three incidences: circular (|r| constant, inertial speed sqrt(GM / a)),
    the inclination from the inertial angular momentum, zero Doppler at the middle sample."""
    from scipy.interpolate import CubicHermiteSpline
    from sarmitsuba.core import georef, orbit
    states = orbit.builtin_orbit(georef.GeoReference(*origin), 693e3, incidence, side, inclination, ascending)
    assert states.frame == "ecef"
    r, v = states.position, states.velocity
    radius = np.linalg.norm(r, axis=1)
    inertial = v + np.cross([0.0, 0.0, OMEGA], r)
    assert np.ptp(radius) < 1e-6 and np.allclose(np.linalg.norm(inertial, axis=1), np.sqrt(GM / radius), rtol=1e-12)
    h = np.cross(r, inertial)
    assert np.allclose(np.degrees(np.arccos(h[:, 2] / np.linalg.norm(h, axis=1))), inclination, atol=1e-9)
    spline = CubicHermiteSpline(states.time, r, v)
    lat, lon, hgt = origin
    scene = np.array(Transformer.from_crs("EPSG:4979", "EPSG:4978").transform(lat, lon, hgt))
    fine = np.linspace(states.time[0], states.time[-1], 600001)
    k = int(np.argmin(np.linalg.norm(spline(fine) - scene, axis=1)))
    t_ca, p, vel = fine[k], spline(fine[k]), spline(fine[k], 1)
    assert abs(t_ca - 0.5 * (states.time[0] + states.time[-1])) < 2e-3
    la, lo = math.radians(lat), math.radians(lon)
    normal = np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
    u = (p - scene) / np.linalg.norm(p - scene)
    assert abs(math.degrees(math.acos(u @ normal)) - incidence) < 1e-4
    assert abs(Transformer.from_crs("EPSG:4978", "EPSG:4979").transform(*p)[2] - 693e3) < 0.01
    assert (inertial[states.time.size // 2, 2] > 0) == ascending
    right = np.cross(vel, p / np.linalg.norm(p)) @ (scene - p) > 0        # the scene right of the track
    assert right == (side == "right")


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_the_builtin_orbit_images_a_trihedral_at_geo_origin():
    """Catches the built-in orbit's ECEF states used as scene coordinates (not carried into the ENU
    frame at geo_origin), end to end: ``trajectory = orbit`` at 693 km, 30 deg, descending and
    right-looking, images the trihedral (turned toward it) within 0.1 cell."""
    import sarmitsuba
    from sarmitsuba.analysis.point_target import analyze_point_target
    from sarmitsuba.core import georef, orbit
    from sarmitsuba.pipeline import simulate
    from sarmitsuba.scene.canonical import trihedral
    origin = (45.5, 9.2, 120.0)
    states = orbit.builtin_orbit(georef.GeoReference(*origin), 693e3, 30.0, "right", 98.18, False)
    e, n, _ = georef.ecef_to_enu(states.position[states.time.size // 2], georef.GeoReference(*origin))
    mesh = trihedral(1.0)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.atan2(n, e) - math.pi / 2, [0, 0, 1]))
    sim = simulate(sarmitsuba.Scene([(mesh, "pec", "trihedral")]), focuser="bp", image_size=(112, 48),
                   sensor_overrides={"trajectory": "orbit", "altitude": 693e3, "incidence_angle": 30.0,
                                     "geo_origin": ", ".join(map(str, origin)), **RADAR})
    report = analyze_point_target(sim.image, (0.0, 0.0, 0.0), chip=32)
    assert abs(report.azimuth_error_cells) < 0.1 and abs(report.range_error_cells) < 0.1, report
    assert abs(sim.raw.metadata["radar"]["incidence_angle"] - 30.0) < 1e-3     # at the scene centre, 0.5 m off


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_orbit_products_pass_sarpy_and_sarkit(orbit_run, tmp_path, caplog):
    """Catches an orbit product that the standards' checkers refuse (TxVel left in the scene's ENU
    axes: sarkit's cphdcheck then fails; a SICD ARP polynomial or SCPCOA that cannot follow an ECEF
    orbit's curvature): sarkit's sicdcheck and cphdcheck, and sarpy's SICD validity and consistency and
    CPHD consistency checks, report no error and no "want" on the Sentinel-1-like orbit's files."""
    import logging

    from sarpy.consistency.cphd_consistency import CphdConsistency
    from sarpy.consistency.sicd_consistency import check_file
    from sarpy.io.complex.converter import open_complex
    from sarmitsuba.formats.cphd import check_cphd
    from sarmitsuba.formats.sicd import check_sicd, write_sicd
    sim, cphd = orbit_run
    sicd = write_sicd(sim.image, tmp_path / "image.nitf", sim.raw)
    assert check_sicd(sicd) == [] and check_cphd(cphd) == []
    con = CphdConsistency.from_file(str(cphd), check_signal_data=False)
    con.check()
    assert con.failures() == {}
    caplog.clear()
    with caplog.at_level(logging.INFO):
        open_complex(str(sicd)).sicd_meta.is_valid(recursive=True, stack=False)
        check_file(str(sicd))
    found = [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR or "want" in r.getMessage().lower()]
    assert found == []


def test_python_ecef_state_vectors_are_carried_like_the_files():
    """Catches ECEF ``StateVectors`` given from Python (``frame="ecef"``) used as scene coordinates:
    loaded, they are the orbit file's track in the scene frame, to a micrometre."""
    from sarmitsuba.core.trajectory import StateVectors
    from sarmitsuba.scene.loader import load_scene
    first, t, pos, vel = eof_oracle()
    python = StateVectors(t, pos, vel, "python", epoch=first.isoformat(), frame="ecef", window=4,
                          closest_approach=True)
    given = {"geo_origin": ", ".join(map(str, SCENE)), **RADAR}
    a = load_scene("trihedral", sensor_overrides={**given, "trajectory": python}).params.trajectory
    b = load_scene("trihedral", sensor_overrides={**given, "trajectory": str(EOF_FILE)}).params.trajectory
    assert a.frame == b.frame == "scene"
    assert np.max(np.abs(a.position - b.position)) < 1e-6 and np.max(np.abs(a.velocity - b.velocity)) < 1e-6


# -- the beam on an orbit (docs/physics.md (J7)): where it points, how fast it sweeps -------------------

MESH = Path(__file__).resolve().parents[1] / "scenes" / "meshes" / "trihedral.obj"
X_BAND = {"frequency": 9.6e9, "bandwidth": 150e6, "sampling_rate": 180e6, "azimuth_beamwidth": 0.15}
ORBITS = {
    "500 km, 40 deg, descending, right": {"trajectory": "orbit", "altitude": 500e3, "incidence_angle": 40.0,
                                           "prf": 2000.0, "geo_origin": "48.1, 11.5, 520"},
    "693 km, 30 deg, ascending, left": {"trajectory": "orbit", "altitude": 693e3, "incidence_angle": 30.0,
                                         "look_side": "left", "orbit_direction": "ascending", "prf": 2000.0,
                                         "geo_origin": "-33.9, 151.2, 20"},
    "Sentinel-1-like file, 35 deg": {"trajectory": str(EOF_FILE), "prf": 4000.0,
                                     "geo_origin": ", ".join(map(str, SCENE))},
}


def facing_trihedral(sensor: dict, incidence: float) -> trimesh.Trimesh:
    """The built-in trihedral, 1.5 m edges (its axis rises 35.26 deg), tilted up to ``incidence`` and
    turned about the vertical toward the mid-aperture antenna (orientation only)."""
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.core.radar import RadarParameters
    positions = acquisition_geometry(RadarParameters.from_mapping({**sensor, "scene_center": (0.0, 0.0, 0.0),
                                                                   "n_pulses": 3})).positions
    mesh = trimesh.load(MESH, force="mesh")
    mesh.apply_scale(1.5)
    tilt = 90.0 - incidence - math.degrees(math.atan(1.0 / math.sqrt(2.0)))
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.radians(tilt), [1, 0, 0]))
    east, north = positions[1][:2]
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.atan2(north, east) - math.pi / 2, [0, 0, 1]))
    return mesh


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("case", list(ORBITS))
def test_an_orbit_images_the_trihedral_rcs_of_the_closed_form(case, tmp_path):
    """The trihedral's RCS on the focused image (automatic aperture) against the closed form
    ``4 pi a^4 / (3 lambda^2)`` (43.37 dBsm at 9.6 GHz), within 0.3 dB as on a straight track.
    Catches the tracer's beam along the horizontal part of an orbit's ENU velocity, which dips
    0.19 deg (the beam sat 0.14 deg, most of a 0.15 deg beam, beside the processed one: 35.03 dBsm,
    8.3 dB low), and an impulse model that takes an orbit's azimuth support for a straight track's
    (the target sees the beam sweep 1.09 times as fast at 500 km: 0.36 dB low).

    The SICD written from it reads the same RCS in sarpy's RCS tool and in the analysis of the file
    read back, within 0.3 dB of the closed form. Catches the SICD's azimuth support (the uniform
    file's band, and the sines it stores) taken for a straight track's: sarpy read 0.1-0.5 dB and
    the read-back analysis 0.7-1.1 dB high, then, with the band right but the sines scaled twice,
    0.3-0.5 dB high."""
    from sarmitsuba import Scene, simulate
    from sarmitsuba.analysis.point_target import analyze_point_target
    from sarmitsuba.formats.sicd import read_sicd, write_sicd
    from test_sicd_calibration import sarpy_total_rcs_db
    sensor = {**X_BAND, **ORBITS[case]}
    incidence = sensor.get("incidence_angle", 35.0)
    sim = simulate(Scene(meshes=[(facing_trihedral(sensor, incidence), "pec", "tri")], sensor=sensor,
                         integrator={"max_depth": 3}), image_size=(96, 96), focuser="bp")
    wavelength = 299792458.0 / X_BAND["frequency"]
    closed_form = 10 * math.log10(4 * math.pi * 1.5 ** 4 / (3 * wavelength ** 2))
    report = analyze_point_target(sim.image, (0.0, 0.0, 0.0), chip=32)
    assert report.rcs_db == pytest.approx(closed_form, abs=0.3), (report.rcs_db, closed_form)
    path = write_sicd(sim.image, tmp_path / "image.nitf", raw=sim.raw)
    read_back = analyze_point_target(read_sicd(path), (0.0, 0.0, 0.0), chip=16).rcs_db
    sarpy_rcs = sarpy_total_rcs_db(path, fit=True)
    assert read_back == pytest.approx(closed_form, abs=0.3), (read_back, closed_form)
    assert sarpy_rcs == pytest.approx(closed_form, abs=0.3), (sarpy_rcs, closed_form)
    assert sarpy_rcs == pytest.approx(report.rcs_db, abs=0.2), (sarpy_rcs, report.rcs_db)


@pytest.mark.parametrize("case", list(ORBITS))
def test_the_automatic_orbit_aperture_sweeps_the_whole_beam_over_the_scene(case):
    """Every corner of the scene's box enters the traced beam (its first nulls) after the first pulse
    and leaves it before the last, by the tracer's own criterion (the along-track sine about each
    pulse's beam axis), as on a straight track. Catches the aperture counted at the satellite's speed:
    the footprint moves 7 to 11 % slower on the ground, and the beam swept only 92 % (500 km) of its
    width over the trihedral."""
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.loader import load_scene
    loaded = load_scene("trihedral", sensor_overrides={**X_BAND, **ORBITS[case]})
    params = loaded.params
    geometry = acquisition_geometry(params)
    half = params.traced_half_angle
    lo, hi = loaded.bbox_lo, loaded.bbox_hi
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    for corner in corners:
        e = corner - geometry.positions
        sines = np.einsum("pk,pk->p", e, geometry.beam_axes) / np.linalg.norm(e, axis=1)
        assert sines.max() >= math.sin(half) and sines.min() <= -math.sin(half), (case, corner, sines[[0, -1]])


def test_the_builtin_orbit_names_the_velocity_and_heading_it_does_not_use():
    """Catches ``velocity`` and ``heading`` given with ``trajectory = orbit`` dropped without a word,
    or a warning that does not say what sets them: the orbit's speed follows from its altitude, its
    heading from ``orbit_inclination`` and ``orbit_direction``."""
    from sarmitsuba.scene.loader import load_scene
    from sarmitsuba.scene.planning import AcquisitionWarning
    given = {**ORBITS["500 km, 40 deg, descending, right"], "velocity": 7000.0, "heading": 30.0}
    with pytest.warns(AcquisitionWarning) as caught:
        load_scene("trihedral", sensor_overrides=given)
    text = " ".join(str(w.message) for w in caught)
    assert "velocity 7000 -> 7697" in text and "heading 30 -> " in text and "not used" in text, text
    assert "orbit_inclination" in text and "orbit_direction" in text and "altitude" in text, text


def test_info_gives_an_orbit_no_flat_earth_look_angle(capsys):
    """Catches ``info`` printing the tangent plane's height and a flat-earth look angle (487 km, 40 deg)
    as the orbit's, above the orbit line that gives 500 km and 36.6 deg on the ellipsoid."""
    from sarmitsuba.cli import main
    sensor = {**X_BAND, **ORBITS["500 km, 40 deg, descending, right"]}
    assert main(["info", "trihedral"] + [a for k, v in sensor.items() for a in ("--set", f"{k}={v}")]) == 0
    out = capsys.readouterr().out
    assert "flat earth" not in out and "altitude 487" not in out, out
    assert "tangent plane" in out and "look angle 36.59" in out and "500.000 km above the ellipsoid" in out, out


def test_the_orbit_aperture_per_point_is_the_pulses_its_beam_holds_the_scene_centre():
    """``info``'s synthetic aperture per point (analysis.cost.synthetic_aperture, which also sizes the
    cost estimate) against the pulses whose traced beam holds the scene centre, counted with the
    tracer's criterion on 2000 pulses: within 1 %. Catches the footprint divided by the satellite's
    speed (977 pulses at 500 km, where the beam holds the centre for 1062)."""
    from sarmitsuba.analysis.cost import synthetic_aperture
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.loader import load_scene
    for case in ("500 km, 40 deg, descending, right", "693 km, 30 deg, ascending, left"):
        params = load_scene("trihedral", sensor_overrides={**X_BAND, **ORBITS[case], "n_pulses": 2000}).params
        geometry = acquisition_geometry(params)
        e = np.asarray(params.scene_center) - geometry.positions
        sines = np.einsum("pk,pk->p", e, geometry.beam_axes) / np.linalg.norm(e, axis=1)
        held = int(np.count_nonzero(np.abs(sines) <= math.sin(params.traced_half_angle)))
        assert 0 < held < 2000
        assert synthetic_aperture(params)[1] == pytest.approx(held, rel=0.01), case


def test_info_gives_an_orbit_the_azimuth_resolution_its_image_has():
    """``info``'s azimuth resolution of an orbit against a straight track's with the same beam, in the
    ratio of the two rendered trihedrals' measured impulse-response widths (within 2 %). Catches the
    orbit given the straight track's resolution (5.28 m at 500 km, where the image resolves 4.86 m:
    the footprint sweeps the ground at v_g, the Doppler bandwidth comes from |V|)."""
    from sarmitsuba import Scene, simulate
    from sarmitsuba.analysis.point_target import analyze_point_target
    from sarmitsuba.info import scene_info
    orbit = {**X_BAND, **ORBITS["500 km, 40 deg, descending, right"]}
    straight = {**X_BAND, "altitude": 500e3, "incidence_angle": 40.0, "prf": 2000.0, "velocity": 7600.0}
    resolution, irw = [], []
    for sensor in (orbit, straight):
        resolution.append(scene_info("trihedral", sensor_overrides=sensor).radar.azimuth_resolution_m)
        sim = simulate(Scene(meshes=[(facing_trihedral(sensor, 40.0), "pec", "tri")], sensor=sensor,
                             integrator={"max_depth": 3}), image_size=(96, 96), focuser="bp")
        irw.append(analyze_point_target(sim.image, (0.0, 0.0, 0.0), chip=32).irw_azimuth)
    assert resolution[0] / resolution[1] == pytest.approx(irw[0] / irw[1], rel=0.02), (resolution, irw)


# -- a day's orbit file: which pass is imaged (docs/physics.md (J6)) -----------------------------------

DAY_ORIGIN = (48.1, 11.6, 500.0)
DAY_EPOCH = datetime.datetime(2026, 6, 15, tzinfo=datetime.timezone.utc)


@pytest.fixture(scope="module")
def day_files(tmp_path_factory):
    """26 h (a Sentinel-1 POEORB's span, 16 orbits) of the built-in orbit, 693 km, descending,
    designed to see DAY_ORIGIN at its middle (t = 13 h) at 35 or 45 deg looking right, or at 30 deg
    looking left, written as ECEF CSVs with an epoch (every 10 s, millimetre digits)."""
    from sarmitsuba.core import georef, orbit
    files = {}
    for incidence, side in [(35.0, "right"), (45.0, "right"), (30.0, "left")]:
        sv = orbit.builtin_orbit(georef.GeoReference(*DAY_ORIGIN), 693e3, incidence, side, 98.18, False,
                                 duration=93600.0)
        path = tmp_path_factory.mktemp("day") / f"day_{incidence:g}_{side}.csv"
        rows = np.column_stack([sv.time, sv.position, sv.velocity])
        np.savetxt(path, rows, fmt=["%.1f"] + ["%.3f"] * 3 + ["%.6f"] * 3, delimiter=",",
                   header="# frame = ecef\n# epoch = 2026-06-15T00:00:00Z\ntime_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps",
                   comments="")
        files[(incidence, side)] = path
    return files


def day_passes(path) -> list[tuple[float, float, str]]:
    """The oracle: every closest approach of the CSV's samples to DAY_ORIGIN (interior local minima
    of range, to the 10 s sample), its incidence against the ellipsoid normal (closed form in
    latitude and longitude) and the side it looks to (sign of (V x LOS) . up), from numpy and
    pyproj alone."""
    rows = np.loadtxt(path, delimiter=",", skiprows=3)
    t, p, v = rows[:, 0], rows[:, 1:4], rows[:, 4:7]
    c = np.array(Transformer.from_crs(4979, 4978, always_xy=True).transform(DAY_ORIGIN[1], DAY_ORIGIN[0],
                                                                             DAY_ORIGIN[2]))
    lat, lon = np.radians(DAY_ORIGIN[:2])
    up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    d = np.linalg.norm(p - c, axis=1)
    out = []
    for k in np.flatnonzero((d[1:-1] < d[:-2]) & (d[1:-1] <= d[2:])) + 1:
        los = (c - p[k]) / d[k]
        side = "left" if np.cross(v[k], los) @ (p[k] / np.linalg.norm(p[k])) > 0 else "right"
        out.append((float(t[k]), math.degrees(math.acos(-los @ up)), side))
    return out


def imaged(path, **sensor):
    """(the oracle pass at whose closest approach the pulses are centred, the loaded parameters,
    the warnings naming passes)."""
    import warnings
    from sarmitsuba.core.geometry import pulse_times
    from sarmitsuba.core.trajectory import from_state_vectors
    from sarmitsuba.scene.loader import load_scene
    given = {"trajectory": str(path), "geo_origin": ", ".join(map(str, DAY_ORIGIN)), "prf": 2000.0, "n_pulses": 101,
             **sensor}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        params = load_scene("trihedral", sensor_overrides=given).params
    times = pulse_times(params, from_state_vectors(params.trajectory))
    middle = 0.5 * (times[0] + times[-1])
    nearest = min(day_passes(path), key=lambda x: abs(x[0] - middle))
    assert abs(nearest[0] - middle) <= 10.0, (middle, nearest)     # centred on a closest approach
    return nearest, params, [str(w.message) for w in caught if "passes geo_origin" in str(w.message)]


@pytest.mark.parametrize("incidence, n_qualifying", [(35.0, 1), (45.0, 3)])
def test_a_days_orbit_file_images_the_designed_pass(day_files, incidence, n_qualifying):
    """A 26 h orbit file designed to see the scene at 35 (or 45) deg right at 13:00 UTC also passes
    it 10 h later nearly overhead (3.9 or 18.5 deg, 694 km, looking left): the pass imaged is the
    designed one. Catches the nearest sample of the whole file taken as the closest approach (the
    near-nadir pass, today's code), and the warning naming the qualifying passes missing (45 deg:
    56.6 deg right, 45 deg right, 18.5 deg left qualify; right is the default look_side)."""
    (t, oracle_incidence, side), params, notes = imaged(day_files[(incidence, "right")])
    assert abs(t - 46800.0) <= 10.0 and side == "right" == params.look_side
    assert abs(params.incidence_angle - oracle_incidence) < 0.1 and abs(oracle_incidence - incidence) < 0.1
    assert len(notes) == (n_qualifying > 1), notes
    if n_qualifying > 1:
        assert f"{n_qualifying} times" in notes[0] and "2026-06-15T13:00:00Z" in notes[0], notes[0]


@pytest.mark.parametrize("design, sensor, hour, side", [
    ((30.0, "left"), {"look_side": "left"}, 13.0, "left"),           # the designed 30 deg left pass
    ((30.0, "left"), {"look_side": "right"}, 24.1, "right"),         # the 52 deg right pass at 00:05:52 next day
    ((45.0, "right"), {"orbit_pass_time": "2026-06-15T01:10:00Z"}, 1.13, "right"),   # 56.6 deg, not the 45
])
def test_a_days_orbit_file_images_the_pass_asked_for(day_files, design, sensor, hour, side):
    """A 26 h file designed to see the scene at 30 deg looking left at 13:00 UTC passes it at 52 deg
    looking right 11 h later: ``look_side`` picks the pass; in the 45 deg file ``orbit_pass_time``
    picks the 56.6 deg pass at 01:07:56 over the designed one, with no warning. Catches the
    sensor's look_side ignored (the nearest pass, looking left, imaged whatever was asked, and
    look_side silently replaced by the file's) and orbit_pass_time not read."""
    (t, oracle_incidence, oracle_side), params, notes = imaged(day_files[design], **sensor)
    assert abs(t - hour * 3600.0) < 360.0 and oracle_side == side == params.look_side, (t, oracle_side)
    assert abs(params.incidence_angle - oracle_incidence) < 0.1
    assert not notes or "orbit_pass_time" not in sensor, notes


def test_a_days_orbit_file_without_a_pass_on_the_side_asked_is_refused(day_files, capsys):
    """The 35 deg right-looking file with look_side = left: its left passes are at 69, 89, 77 and
    3.9 deg (the near-nadir one), none a side-looking SAR's view. Catches the near-nadir pass
    imaged at 3.9 deg with exit 0 and no warning (today): exit 2 naming look_side, geo_origin and
    the passes (the designed one at 13:00:00Z, 35 deg right), one line, no traceback."""
    from sarmitsuba.cli import main
    args = ["info", "trihedral", "--set", f"trajectory={day_files[(35.0, 'right')]}", "--set",
            "geo_origin=" + ", ".join(map(str, DAY_ORIGIN)), "--set", "look_side=left"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "look_side = left" in err and "geo_origin" in err and "Traceback" not in err, err
    assert "2026-06-15T13:00:00Z (incidence 35.0 deg, looking right" in err and "incidence 3.9 deg" in err, err
    assert len(err.strip().splitlines()) == 1, err
