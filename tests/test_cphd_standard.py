"""CPHD files other tools read (issue 29): standard layout, image area, times, portable metadata.

- sarpy (NGA's older library, independent of sarkit) opens ``raw.cphd`` of ``render trihedral``
  (time of arrival, and ``--cphd-domain fx``: frequency domain), of a small ``urban`` and of a
  quad-pol render, reads the same samples as sarkit, and its CPHD
  consistency check reports no failure; sarkit's ``cphdcheck --thorough`` exits 0, and the file
  header holds only the keys the standard defines (sarmitsuba's own entries are
  ``ProductInfo/CreationInfo/Parameter`` elements).
- The scene reference point of data without radar metadata (the mean of the pulses' closest
  points on the ground) is ``H tan(theta)`` right of a straight level track, at 30 and 60 deg.
- ``ImageArea`` bounds what the data show: the trihedral's box with its layover and 16
  ground-range cells (about 47 m), not +-600 m; without a box, the fast-time window on the ground.
- ``CollectionStart`` is the first pulse's time, ``CreationInfo/DateTime`` the writing moment.
- A file written by the former layout (the same entries as non-standard header keys) still reads.
- No absolute path of the machine travels in the file.

Expected values are computed here by hand from the geometry, not by the code under test.
"""
from __future__ import annotations

import copy
import dataclasses
import datetime
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sarkit_cphd = pytest.importorskip("sarkit.cphd")

from sarmitsuba.cli import main  # noqa: E402
from sarmitsuba.core import georef  # noqa: E402
from sarmitsuba.core.constants import SPEED_OF_LIGHT  # noqa: E402
from sarmitsuba.core.outputs import json_default  # noqa: E402
from sarmitsuba.core.raw import RawData  # noqa: E402
from sarmitsuba.formats import cphd  # noqa: E402
from sarmitsuba.formats.cphd import CphdError, read_cphd, write_cphd  # noqa: E402

#: Keys a CPHD 1.1 file header may hold (NGA.STND.0068-1 sec. 4.1).
STANDARD_KEYS = {"XML_BLOCK_SIZE", "XML_BLOCK_BYTE_OFFSET", "SUPPORT_BLOCK_SIZE", "SUPPORT_BLOCK_BYTE_OFFSET",
                 "PVP_BLOCK_SIZE", "PVP_BLOCK_BYTE_OFFSET", "SIGNAL_BLOCK_SIZE", "SIGNAL_BLOCK_BYTE_OFFSET",
                 "CLASSIFICATION", "RELEASE_INFO"}
START = "2026-11-24T23:40:16.123456+00:00"


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    """name -> folder of `render --cphd`: trihedral (default; TOA and FX domain), urban (32 pulses, depth 1),
    quad-pol trihedral."""
    root = tmp_path_factory.mktemp("renders")
    runs = {"trihedral": ["trihedral"], "trihedral_fx": ["trihedral", "--cphd-domain", "fx"],
            "urban": ["urban", "--pulses", "32", "--max-depth", "1"],
            "quad": ["trihedral", "--pulses", "16", "--set", "polarization=quad"]}
    for name, args in runs.items():
        assert main(["render", *args, "--cphd", "--out", str(root / name), "--no-progress"]) == 0
    return root


FILES = ["trihedral/raw.cphd", "trihedral_fx/raw.cphd", "urban/raw.cphd"] + [f"quad/raw_{p}.cphd"
                                                                              for p in ("HH", "HV", "VH", "VV")]


def read_parts(path):
    """(signal, pvp, xml tree, additional header keys) of channel 1, straight from sarkit."""
    with open(path, "rb") as f, sarkit_cphd.Reader(f) as reader:
        signal, pvp = reader.read_channel("1")
        return signal, pvp, reader.metadata.xmltree, reader.metadata.file_header_part.additional_kvps


def header_keys(path) -> set[str]:
    """The keys of the file header, read line by line up to its terminator (independent of sarkit)."""
    keys = set()
    with open(path, "rb") as f:
        assert f.readline().startswith(b"CPHD/1.1")
        for line in iter(f.readline, b"\f\n"):
            keys.add(line.split(b" := ")[0].decode())
    return keys


@pytest.mark.filterwarnings("ignore:Call to deprecated class CPHDReader:DeprecationWarning")
@pytest.mark.parametrize("name", FILES)
def test_sarpy_opens_the_file_and_its_consistency_check_finds_no_failure(renders, name):
    pytest.importorskip("sarpy")
    import sarpy.io.phase_history
    from sarpy.consistency.cphd_consistency import CphdConsistency
    path = renders / name
    reader = sarpy.io.phase_history.open(str(path))
    signal, _, _, _ = read_parts(path)
    np.testing.assert_array_equal(reader[:, :, 0], signal)
    con = CphdConsistency.from_file(str(path))
    con.check()
    assert not con.failures(), json.dumps(con.failures(), default=str)[:2000]


@pytest.mark.parametrize("name", FILES)
def test_cphdcheck_exits_0_and_the_header_holds_only_standard_keys(renders, name):
    path = renders / name
    assert header_keys(path) <= STANDARD_KEYS, header_keys(path) - STANDARD_KEYS
    script = Path(sys.executable).with_name("cphdcheck")
    command = [str(script)] if script.is_file() else [sys.executable, "-c",
                                                      "import sys; from sarkit.verification import _cphdcheck as c; "
                                                      "sys.exit(c.main())"]
    done = subprocess.run([*command, "--thorough", str(path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]


def test_sarmitsuba_entries_are_creation_info_parameters_and_read_back(renders):
    path = renders / "trihedral" / "raw.cphd"
    raw = RawData.load(renders / "trihedral" / "raw.npz")
    _, _, tree, kvps = read_parts(path)
    assert kvps == {}
    params = {p.get("name"): p.text for p in tree.findall("{*}ProductInfo/{*}CreationInfo/{*}Parameter")}
    assert set(params) == {"SARMITSUBA_METADATA", "SARMITSUBA_PULSE_TIME0", "SARMITSUBA_PRF",
                           "SARMITSUBA_RANGE_COMPRESSED"}
    assert float(params["SARMITSUBA_PULSE_TIME0"]) == raw.pulse_time[0]
    assert float(params["SARMITSUBA_PRF"]) == raw.prf and params["SARMITSUBA_RANGE_COMPRESSED"] == "true"
    back = read_cphd(path)
    assert back.metadata == json.loads(params["SARMITSUBA_METADATA"])
    np.testing.assert_allclose(back.pulse_time, raw.pulse_time, atol=1e-12)


# -- scene reference point of data without radar metadata, and the image area from the window --------

H, SPEED, PRF, FS, BANDWIDTH, N_PULSES, N_SAMPLES = 3000.0, 120.0, 400.0, 180e6, 150e6, 64, 64
TRACK_X0, SRP_Y = 250.0, 40.0


def straight_track(incidence_deg: float) -> RawData:
    """A level track along +x at height H, the fast-time window (an even number of samples) centred on
    the slant range H / cos(theta); the ground point H tan(theta) right of its middle is (250, 40, 0)."""
    theta = np.radians(incidence_deg)
    t = (np.arange(N_PULSES) - (N_PULSES - 1) / 2) / PRF
    pos = np.column_stack([TRACK_X0 + SPEED * t, np.full(N_PULSES, SRP_Y + H * np.tan(theta)), np.full(N_PULSES, H)])
    fast = 2 * H / np.cos(theta) / SPEED_OF_LIGHT + (np.arange(N_SAMPLES) - (N_SAMPLES - 1) / 2) / FS
    return RawData(data=np.ones((N_PULSES, N_SAMPLES), np.complex64), fast_time=fast, pulse_time=t,
                   tx_position=pos, rx_position=pos.copy(), velocity=np.tile([SPEED, 0.0, 0.0], (N_PULSES, 1)),
                   fc=9.6e9, bandwidth=BANDWIDTH, chirp_rate=BANDWIDTH / 1e-5, pulse_length=1e-5, fs=FS, prf=PRF,
                   range_compressed=True, metadata={"scene": "synthetic"})


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_scene_reference_point_without_metadata_is_h_tan_theta_right_of_the_track(tmp_path, incidence):
    path = write_cphd(straight_track(incidence), tmp_path / "raw.cphd")
    _, pvp, tree, _ = read_parts(path)
    srp = georef.ecef_to_enu(pvp["SRPPos"], georef.DEFAULT)
    np.testing.assert_allclose(srp, np.tile([TRACK_X0, SRP_Y, 0.0], (N_PULSES, 1)), atol=1e-3)


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_image_area_without_a_scene_box_is_the_window_on_the_ground(tmp_path, incidence):
    """Across track (y): the ground ranges of the first and last samples; along track (x): the track's
    span and half the swath on either side (1 cm: the middle of 64 pulses is half a pulse off broadside)."""
    raw = straight_track(incidence)
    path = write_cphd(raw, tmp_path / "raw.cphd")
    xml = sarkit_cphd.XmlHelper(read_parts(path)[2])
    track_y = SRP_Y + H * np.tan(np.radians(incidence))
    slant = 0.5 * SPEED_OF_LIGHT * raw.fast_time[[0, -1]]
    near, far = np.sqrt(slant ** 2 - H ** 2)
    half_swath = 0.5 * (far - near)
    span = SPEED * (N_PULSES - 1) / PRF
    expected = [[TRACK_X0 - 0.5 * span - half_swath, track_y - far], [TRACK_X0 + 0.5 * span + half_swath, track_y - near]]
    area = [xml.load("{*}SceneCoordinates/{*}ImageArea/{*}X1Y1"), xml.load("{*}SceneCoordinates/{*}ImageArea/{*}X2Y2")]
    np.testing.assert_allclose(area, expected, atol=0.01)


def test_image_area_of_a_scene_box_in_a_shifted_frame_adds_the_frame_offset(tmp_path):
    """A flat 10 m x 6 m box traced in a frame shifted to (250, 40): the area is the box about (250, 40)
    plus 16 ground-range cells c / (2 B sin 45 deg), not about the origin."""
    raw = straight_track(45.0)
    meta = {"scene": "synthetic", "frame_offset": [TRACK_X0, SRP_Y, 0.0],
            "scene_info": {"bbox_min": [-5.0, -3.0, 0.0], "bbox_max": [5.0, 3.0, 0.0]}}
    path = write_cphd(with_metadata(raw, meta), tmp_path / "raw.cphd")
    xml = sarkit_cphd.XmlHelper(read_parts(path)[2])
    margin = 16 * SPEED_OF_LIGHT / (2 * BANDWIDTH * np.sin(np.radians(45.0)))
    expected = [[TRACK_X0 - 5 - margin, SRP_Y - 3 - margin], [TRACK_X0 + 5 + margin, SRP_Y + 3 + margin]]
    area = [xml.load("{*}SceneCoordinates/{*}ImageArea/{*}X1Y1"), xml.load("{*}SceneCoordinates/{*}ImageArea/{*}X2Y2")]
    np.testing.assert_allclose(area, expected, atol=1e-3)


# -- image area of a render: the scene's box ---------------------------------------------------------

def test_image_area_bounds_the_trihedrals_box_not_600_m(renders):
    """Box corners, the top's layover toward the sensor (+y, about dz / tan(45 deg)), then 16 ground-range
    cells c / (2 B sin(theta)) on every side: about 47 m square."""
    raw = RawData.load(renders / "trihedral" / "raw.npz")
    info, radar = raw.metadata["scene_info"], raw.metadata["radar"]
    lo, hi = np.array(info["bbox_min"]), np.array(info["bbox_max"])
    theta = np.radians(radar["incidence_angle"])
    margin = 16 * SPEED_OF_LIGHT / (2 * radar["bandwidth"] * np.sin(theta))
    layover = (hi[2] - lo[2]) / np.tan(theta)
    expected = [[lo[0] - margin, lo[1] - margin], [hi[0] + margin, hi[1] + layover + margin]]
    _, _, tree, _ = read_parts(renders / "trihedral" / "raw.cphd")
    xml = sarkit_cphd.XmlHelper(tree)
    for where in ("{*}SceneCoordinates/{*}ImageArea", "{*}Channel/{*}Parameters/{*}ImageArea"):
        area = np.array([xml.load(where + "/{*}X1Y1"), xml.load(where + "/{*}X2Y2")])
        np.testing.assert_allclose(area, expected, atol=0.05)      # the exact layover differs by mm
        assert np.all(area[1] - area[0] < 60.0)
    lines = xml.load("{*}SceneCoordinates/{*}ImageGrid/{*}IAXExtent/{*}NumLines")
    spacing = xml.load("{*}SceneCoordinates/{*}ImageGrid/{*}IAXExtent/{*}LineSpacing")
    assert lines * spacing == pytest.approx(expected[1][0] - expected[0][0], abs=0.05)


# -- times ---------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def small_raw(renders):
    return RawData.load(renders / "quad" / "raw_VV.npz")


def with_radar(raw: RawData, **changes) -> RawData:
    """``raw`` with a copy of its metadata whose ``radar`` entries are updated by ``changes``."""
    meta = copy.deepcopy(raw.metadata)
    meta["radar"].update(changes)
    return with_metadata(raw, meta)


def with_metadata(raw: RawData, meta: dict) -> RawData:
    return dataclasses.replace(raw, metadata=meta)


def timeline(path):
    xml = sarkit_cphd.XmlHelper(read_parts(path)[2])
    return (xml.load("{*}Global/{*}Timeline/{*}CollectionStart"),
            xml.load("{*}ProductInfo/{*}CreationInfo/{*}DateTime"), xml.load("{*}Global/{*}Timeline/{*}TxTime1"))


def test_collection_start_is_the_first_pulse_and_creation_the_writing_moment(small_raw, tmp_path, monkeypatch):
    written = datetime.datetime(2030, 5, 6, 7, 8, 9, 250000, tzinfo=datetime.timezone.utc)
    monkeypatch.setattr(cphd, "utc_now", lambda: written)
    path = write_cphd(with_radar(small_raw, collection_start=START), tmp_path / "a.cphd")
    start, created, tx1 = timeline(path)
    assert start == datetime.datetime.fromisoformat(START) and created == written and tx1 == 0.0
    # Reproducible bytes: the same collection start and clock give the same file.
    again = write_cphd(with_radar(small_raw, collection_start=START), tmp_path / "b.cphd")
    assert again.read_bytes() == path.read_bytes()
    # Another zone is the same instant.
    other = write_cphd(with_radar(small_raw, collection_start="2026-11-25T01:40:16.123456+02:00"), tmp_path / "c.cphd")
    assert timeline(other)[0] == datetime.datetime.fromisoformat(START)


@pytest.mark.parametrize("missing", ["absent", None])
def test_collection_start_missing_falls_back_to_2000(small_raw, tmp_path, missing):
    raw = with_radar(small_raw, collection_start=None)
    if missing == "absent":
        del raw.metadata["radar"]["collection_start"]
    before = datetime.datetime.now(datetime.timezone.utc)
    start, created, _ = timeline(write_cphd(raw, tmp_path / "raw.cphd"))
    assert start == datetime.datetime(2000, 1, 1, tzinfo=datetime.timezone.utc)
    assert before - datetime.timedelta(seconds=1) <= created <= datetime.datetime.now(datetime.timezone.utc)


def test_a_collection_start_without_offset_is_refused_naming_the_file(small_raw, tmp_path):
    with pytest.raises(CphdError, match=r"raw\.cphd.*collection_start"):
        write_cphd(with_radar(small_raw, collection_start="2026-11-24T23:40:16"), tmp_path / "raw.cphd")
    assert not (tmp_path / "raw.cphd").exists()


def test_the_render_writes_its_collection_start(renders):
    raw = RawData.load(renders / "trihedral" / "raw.npz")
    given = raw.metadata["radar"].get("collection_start")
    start, _, _ = timeline(renders / "trihedral" / "raw.cphd")
    expected = datetime.datetime.fromisoformat(given) if given else datetime.datetime(2000, 1, 1,
                                                                                       tzinfo=datetime.timezone.utc)
    assert start == expected


# -- no absolute paths --------------------------------------------------------------------------------

def test_no_absolute_scene_path_is_written(small_raw, tmp_path):
    meta = copy.deepcopy(small_raw.metadata)
    meta["scene_path"] = "/home/someone/private/scenes/trihedral.xml"
    meta["extra"] = [{"scene_path": "C:\\Users\\someone\\scenes\\urban.xml"}]
    path = write_cphd(with_metadata(small_raw, meta), tmp_path / "raw.cphd")
    content = path.read_bytes()
    assert b"someone" not in content
    back = read_cphd(path)
    assert back.metadata["scene_path"] == "trihedral.xml"
    assert back.metadata["extra"] == [{"scene_path": "urban.xml"}]


# -- files of the former layout ----------------------------------------------------------------------

def write_former_layout(raw: RawData, path: Path) -> None:
    """A CPHD file as sarmitsuba wrote them before issue 29, built with sarkit here: no ProductInfo,
    CollectionStart 2000-01-01, and the entries as file-header keys ('=' escaped in the JSON)."""
    tmp = path.with_suffix(".new.cphd")
    write_cphd(raw, tmp)
    signal, pvp, tree, _ = read_parts(tmp)
    root = tree.getroot()
    for elem in root.findall("{*}ProductInfo"):
        root.remove(elem)
    sarkit_cphd.XmlHelper(tree).set("{*}Global/{*}Timeline/{*}CollectionStart",
                                    datetime.datetime(2000, 1, 1, tzinfo=datetime.timezone.utc))
    text = json.dumps(raw.metadata, default=json_default, ensure_ascii=True).replace("=", "\\u003d")
    kvps = {"SARMITSUBA_METADATA": text, "SARMITSUBA_PULSE_TIME0": repr(float(raw.pulse_time[0])),
            "SARMITSUBA_PRF": repr(float(raw.prf)),
            "SARMITSUBA_RANGE_COMPRESSED": "true" if raw.range_compressed else "false"}
    metadata = sarkit_cphd.Metadata(xmltree=tree, file_header_part=sarkit_cphd.FileHeaderPart(additional_kvps=kvps))
    with open(path, "wb") as f, sarkit_cphd.Writer(f, metadata) as writer:
        writer.write_signal("1", signal)
        writer.write_pvp("1", pvp)


def test_a_file_of_the_former_layout_still_reads(small_raw, tmp_path):
    raw = with_radar(small_raw, collection_start=None)
    raw.metadata["effects"] = ["a = b"]                          # the escaped '=' comes back
    path = tmp_path / "old.cphd"
    write_former_layout(raw, path)
    assert "SARMITSUBA_METADATA" in read_parts(path)[3] and read_parts(path)[2].find("{*}ProductInfo") is None
    back = read_cphd(path)
    assert back.metadata == json.loads(json.dumps(raw.metadata, default=json_default))
    np.testing.assert_allclose(back.pulse_time, raw.pulse_time, atol=1e-12)
    assert back.prf == raw.prf and back.range_compressed == raw.range_compressed
    np.testing.assert_allclose(back.data, raw.data, rtol=0, atol=1e-6 * np.abs(raw.data).max())
