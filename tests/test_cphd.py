"""CPHD export and import through sarkit (issue 17, item 2): checker, geometry, samples, focusing."""
from __future__ import annotations

import json

import numpy as np
import pytest

sarkit_cphd = pytest.importorskip("sarkit.cphd")
from sarmitsuba.core import georef
from sarmitsuba import pipeline  # noqa: E402
from sarmitsuba.core.constants import SPEED_OF_LIGHT  # noqa: E402
from sarmitsuba.core.outputs import json_default  # noqa: E402
from sarmitsuba.formats.cphd import CphdError, check_cphd, read_cphd, write_cphd  # noqa: E402

#: A place far from the equator and the prime meridian, so that a swapped or dropped axis shows.
REF = georef.GeoReference(48.1, 11.6, 520.0)


@pytest.fixture(scope="module")
def compressed():
    """A tiny trihedral render (range compressed)."""
    return pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 32}).raw


@pytest.fixture(scope="module")
def written(compressed, tmp_path_factory):
    """(RawData, path of its raw.cphd)."""
    path = tmp_path_factory.mktemp("cphd") / "raw.cphd"
    write_cphd(compressed, path, REF)
    return compressed, path


def read_parts(path):
    """(signal, pvp, xml tree) of channel 1, straight from sarkit."""
    with open(path, "rb") as f, sarkit_cphd.Reader(f) as reader:
        signal, pvp = reader.read_channel("1")
        return signal, pvp, reader.metadata.xmltree


def test_sarkit_consistency_checker_reports_no_failures(written):
    assert check_cphd(written[1]) == []


def test_scene_reference_point_is_the_geo_origin_in_wgs84(written):
    """The scene centre is the local origin: sarkit's own geodetic maths must give back REF."""
    import sarkit.wgs84
    raw, path = written
    assert list(raw.metadata["radar"]["scene_center"]) == [0.0, 0.0, 0.0]
    _, pvp, _ = read_parts(path)
    llh = sarkit.wgs84.cartesian_to_geodetic(pvp["SRPPos"])
    np.testing.assert_allclose(llh[:, 0], REF.latitude_deg, atol=1e-9)   # ~0.1 mm
    np.testing.assert_allclose(llh[:, 1], REF.longitude_deg, atol=1e-9)
    np.testing.assert_allclose(llh[:, 2], REF.height_m, atol=1e-3)


def test_pvp_ranges_and_times_match_the_local_geometry(written):
    """A rigid ENU->ECEF map keeps every antenna-to-SRP distance (1 mm) and the two-way delay."""
    raw, path = written
    _, pvp, _ = read_parts(path)
    local = np.linalg.norm(raw.tx_position, axis=1)          # SRP at the local origin
    back = np.linalg.norm(raw.rx_position, axis=1)           # the receiver at the SRP echo's arrival
    np.testing.assert_allclose(np.linalg.norm(pvp["TxPos"] - pvp["SRPPos"], axis=1), local, atol=1e-3)
    np.testing.assert_allclose(np.linalg.norm(pvp["RcvPos"] - pvp["SRPPos"], axis=1), back, atol=1e-3)
    np.testing.assert_allclose(np.linalg.norm(pvp["TxVel"], axis=1), np.linalg.norm(raw.velocity, axis=1),
                               rtol=1e-12)
    np.testing.assert_allclose(pvp["RcvTime"] - pvp["TxTime"], (local + back) / SPEED_OF_LIGHT, rtol=1e-9)
    np.testing.assert_allclose(np.diff(pvp["TxTime"]), np.diff(raw.pulse_time), atol=1e-15)
    # Straight level track: the ECEF velocity is the direction between successive positions.
    step = np.diff(pvp["TxPos"], axis=0)
    np.testing.assert_allclose(step / np.diff(pvp["TxTime"])[:, None], pvp["TxVel"][1:], atol=1e-6)


def test_samples_are_compensated_to_the_scene_reference_point(written):
    """The trihedral sits at the SRP: in the file its peak is at dTOA = 0 with one constant phase."""
    raw, path = written
    signal, pvp, _ = read_parts(path)
    peak = np.argmax(np.abs(signal), axis=1)
    dtoa = pvp["SC0"] + peak * pvp["SCSS"]
    assert np.all(np.abs(dtoa) <= pvp["SCSS"])
    phase = np.unwrap(np.angle(signal[np.arange(len(peak)), peak]))
    assert np.ptp(phase) < 0.05
    raw_peak = np.argmax(np.abs(raw.data), axis=1)
    assert np.ptp(np.unwrap(np.angle(raw.data[np.arange(len(raw_peak)), raw_peak]))) > 1.0  # not yet compensated


def test_read_back_gives_the_geometry_and_samples(written):
    raw, path = written
    back = read_cphd(path)
    for name in ("tx_position", "rx_position"):
        np.testing.assert_allclose(getattr(back, name), getattr(raw, name), atol=1e-3, err_msg=name)
    np.testing.assert_allclose(back.velocity, raw.velocity, atol=1e-9)
    np.testing.assert_allclose(back.pulse_time, raw.pulse_time, atol=1e-12)
    np.testing.assert_allclose(back.fast_time, raw.fast_time, rtol=0, atol=1e-15)
    # The SRP phase is taken out and put back in float32: equal within float32 rounding.
    np.testing.assert_allclose(back.data, raw.data, rtol=0, atol=1e-6 * np.abs(raw.data).max())
    assert (back.fc, back.bandwidth, back.fs, back.prf, back.pulse_length, back.chirp_rate) == \
        (raw.fc, raw.bandwidth, raw.fs, raw.prf, raw.pulse_length, raw.chirp_rate)
    assert back.range_compressed
    assert back.metadata == json.loads(json.dumps(raw.metadata, default=json_default))  # as RawData.save keeps it


def test_focusing_the_read_back_data_gives_the_same_image(written):
    raw, path = written
    original = pipeline.refocus(raw, "bp").data
    again = pipeline.refocus(read_cphd(path), "bp").data
    nrmse_db = 20 * np.log10(np.linalg.norm(again - original) / np.linalg.norm(original))
    assert nrmse_db <= -60.0


def test_chirped_data_round_trip_and_pass_the_checker(tmp_path):
    raw = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 16, "output": "raw"}).raw
    assert not raw.range_compressed
    path = write_cphd(raw, tmp_path / "raw.cphd", REF)
    assert check_cphd(path) == []
    back = read_cphd(path)
    assert not back.range_compressed
    np.testing.assert_allclose(back.data, raw.data, rtol=0, atol=1e-6 * np.abs(raw.data).max())


def test_reading_a_file_that_is_no_cphd_names_it(tmp_path):
    path = tmp_path / "raw.cphd"
    path.write_bytes(b"not a phase history\n")
    with pytest.raises(CphdError, match="raw.cphd"):
        read_cphd(path)
    with pytest.raises(CphdError, match="missing.cphd"):
        read_cphd(tmp_path / "missing.cphd")


def test_render_cphd_then_focus_it_gives_the_npz_image(tmp_path, capsys):
    """`render --cphd` writes raw.cphd beside raw.npz; `focus raw.cphd` and `focus raw.npz` agree (-60 dB)."""
    from sarmitsuba.cli import main
    from sarmitsuba.core.image import SarImage
    out = tmp_path / "r"
    assert main(["render", "trihedral", "--pulses", "32", "--cphd", "--out", str(out), "--no-progress",
                 "--set", "geo_origin=-33.9, 151.2, 40"]) == 0
    assert (out / "raw.cphd").is_file() and check_cphd(out / "raw.cphd") == []
    images = {}
    for name in ("raw.npz", "raw.cphd"):
        dest = tmp_path / name.replace(".", "_")
        assert main(["focus", str(out / name), "--algorithm", "bp", "--out", str(dest), "--no-progress"]) == 0
        images[name] = SarImage.load(dest / "image.npz").data
    a, b = images["raw.npz"], images["raw.cphd"]
    assert 20 * np.log10(np.linalg.norm(b - a) / np.linalg.norm(a)) <= -60.0
    # The IARP is the sensor's geo_origin (southern hemisphere, east): a sign slip shows here.
    _, _, tree = read_parts(out / "raw.cphd")
    llh = [float(v.text) for v in tree.find("{*}SceneCoordinates/{*}IARP/{*}LLH")]
    np.testing.assert_allclose(llh, [-33.9, 151.2, 40.0], atol=1e-9)
    # analyze takes the CPHD file for its carrier ramp like the npz one
    capsys.readouterr()
    reports = []
    for raw_name in ("raw.npz", "raw.cphd"):
        assert main(["analyze", str(out / "image.npz"), "--target", "0,0,0", "--raw", str(out / raw_name)]) == 0
        reports.append(json.loads(capsys.readouterr().out))
    assert reports_close(reports[0], reports[1])


def reports_close(a, b):
    """Nested reports equal within 1e-6 relative (numbers) and exactly (everything else)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(reports_close(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(reports_close(x, y) for x, y in zip(a, b))
    if isinstance(a, float):
        return a == pytest.approx(b, rel=1e-6, abs=1e-9)
    return a == b


def test_quad_pol_render_writes_one_cphd_per_channel(tmp_path):
    from sarmitsuba.cli import main
    out = tmp_path / "q"
    assert main(["render", "trihedral", "--pulses", "16", "--cphd", "--out", str(out), "--no-progress",
                 "--set", "polarization=quad"]) == 0
    for name in ("HH", "HV", "VH", "VV"):
        back = read_cphd(out / f"raw_{name}.cphd")
        assert back.metadata["polarization"] == name
        _, _, tree = read_parts(out / f"raw_{name}.cphd")
        assert tree.findtext("{*}Channel/{*}Parameters/{*}Polarization/{*}TxPol") == name[0]
        assert tree.findtext("{*}Channel/{*}Parameters/{*}Polarization/{*}RcvPol") == name[1]


def test_focus_of_a_damaged_cphd_exits_2_naming_it(tmp_path, capsys):
    from sarmitsuba.cli import main
    bad = tmp_path / "raw.cphd"
    bad.write_bytes(b"CPHD/1.1.0\nnot really\n")
    assert main(["focus", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "raw.cphd" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


# -- the frequency (FX) domain: the same data, the same image --------------------------------------------


def test_fx_and_toa_files_focus_to_the_same_image(written, tmp_path):
    """The data written in the FX domain and read back focus (bp) to the image of the TOA file within -60 dB,
    and the FX file passes sarkit's checker. Bug caught: FX keeping only the bins of the transmitted band
    (the leakage of the window's edges, which the TOA samples hold and focusing keeps, is lost: -48 dB)."""
    raw, toa_path = written
    fx_path = write_cphd(raw, tmp_path / "fx.cphd", REF, domain="fx")
    assert check_cphd(fx_path) == []
    _, _, tree = read_parts(fx_path)
    assert tree.findtext("{*}Global/{*}DomainType") == "FX"
    toa = pipeline.refocus(read_cphd(toa_path), "bp").data
    fx = pipeline.refocus(read_cphd(fx_path), "bp").data
    assert 20 * np.log10(np.linalg.norm(fx - toa) / np.linalg.norm(toa)) <= -60.0


def test_render_and_focus_write_the_fx_domain_that_focus_reads(tmp_path):
    """`render --cphd --cphd-domain fx` writes an FX raw.cphd that `focus` reads into the image of raw.npz
    (-60 dB); `focus raw.npz --cphd --cphd-domain fx` writes the same samples. Bug caught: --cphd-domain not
    passed on from the command line (a TOA file written)."""
    from sarmitsuba.cli import main
    from sarmitsuba.core.image import SarImage
    out = tmp_path / "r"
    assert main(["render", "trihedral", "--pulses", "32", "--cphd", "--cphd-domain", "fx", "--out", str(out),
                 "--no-progress"]) == 0
    signal, _, tree = read_parts(out / "raw.cphd")
    assert tree.findtext("{*}Global/{*}DomainType") == "FX"
    images = {}
    for name in ("raw.npz", "raw.cphd"):
        dest = tmp_path / name.replace(".", "_")
        assert main(["focus", str(out / name), "--algorithm", "bp", "--out", str(dest), "--no-progress",
                     "--cphd", "--cphd-domain", "fx"]) == 0
        images[name] = SarImage.load(dest / "image.npz").data
    a, b = images["raw.npz"], images["raw.cphd"]
    assert 20 * np.log10(np.linalg.norm(b - a) / np.linalg.norm(a)) <= -60.0
    again, _, tree = read_parts(tmp_path / "raw_npz" / "raw.cphd")
    assert tree.findtext("{*}Global/{*}DomainType") == "FX"
    np.testing.assert_allclose(again, signal, rtol=0, atol=1e-6 * np.abs(signal).max())


def test_fx_of_chirped_data_exits_2_before_tracing_or_focusing(tmp_path, capsys, monkeypatch):
    """Chirped echoes (output=raw) have no FX form: `render ... --cphd --cphd-domain fx` stops before tracing
    and `focus chirped raw.npz --cphd --cphd-domain fx` before focusing, exit 2, one line naming
    --cphd-domain, no output folder. Bug caught: the check only where the file is written (after the trace)."""
    from sarmitsuba.cli import main
    raw = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 8, "output": "raw"}).raw
    raw.save(tmp_path / "chirped.npz")

    def no_work(*args, **kwargs):
        raise AssertionError("traced or focused before the refusal")
    monkeypatch.setattr(pipeline, "trace", no_work)
    monkeypatch.setattr(pipeline, "refocus", no_work)
    for argv in (["render", "trihedral", "--set", "output=raw"], ["focus", str(tmp_path / "chirped.npz")]):
        capsys.readouterr()
        assert main([*argv, "--cphd", "--cphd-domain", "fx", "--out", str(tmp_path / "o"), "--no-progress"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: --cphd-domain fx") and "chirped" in err and "\n" not in err, err
        assert not (tmp_path / "o").exists()
