"""Damaged raw.npz / image.npz: every reader (focus, analyze, figures' redraw) exits 2 with one
message naming the file and the specific problem, no traceback, and leaves no output behind.

Truth is hand-made: the damage is done here (truncation, a flipped byte that zipfile itself
confirms breaks the CRC, a text file, arrays of disagreeing lengths, NaN/Inf at known indices),
so the expected count and first position are known without the code under test.
"""
from __future__ import annotations

import struct
import zipfile

import numpy as np
import pytest

from sarmitsuba.products import figures
from sarmitsuba.analysis import synthetic
from sarmitsuba.cli import main
from sarmitsuba.core.image import SarImage, SarImageError
from sarmitsuba.core.raw import RawData, RawDataError
from sarmitsuba.analysis.synthetic import PointTarget

RAW_KEYS = ("data", "fast_time", "pulse_time", "tx_position", "rx_position", "velocity",
            "fc", "bandwidth", "chirp_rate", "pulse_length", "fs", "prf", "range_compressed", "metadata")


@pytest.fixture(scope="module")
def valid(tmp_path_factory):
    """A small point-target raw.npz and the image.npz that `focus` makes of it (both intact)."""
    folder = tmp_path_factory.mktemp("valid")
    raw = synthetic.stripmap(PointTarget((0.0, 0.0, 0.0), 1.0), fc=9.6e9, bandwidth=150e6, fs=180e6, prf=400.0,
                             speed=100.0, n_pulses=64, center=(0.0, 600.0, 500.0))
    raw.save(folder / "raw.npz")
    assert main(["focus", str(folder / "raw.npz"), "--out", str(folder / "focused"), "--algorithm", "bp",
                 "--no-progress"]) == 0                   # control: the intact file focuses
    return folder / "raw.npz", folder / "focused" / "image.npz"


def arrays_of(path) -> dict[str, np.ndarray]:
    with np.load(path) as f:
        return {k: f[k] for k in f.files}


# ============================================================================ ways to damage a file
def truncate(src, dst):
    payload = src.read_bytes()
    dst.write_bytes(payload[: len(payload) // 2])


def flip_byte_in(src, dst, member="data.npy"):
    """Flip one byte in the middle of ``member``'s stored bytes; check the CRC now fails."""
    payload = bytearray(src.read_bytes())
    with zipfile.ZipFile(src) as z:
        info = z.getinfo(member)
    assert info.compress_type == zipfile.ZIP_STORED
    name_len, extra_len = struct.unpack("<HH", payload[info.header_offset + 26: info.header_offset + 30])
    start = info.header_offset + 30 + name_len + extra_len
    payload[start + info.compress_size // 2] ^= 0xFF
    dst.write_bytes(bytes(payload))
    with zipfile.ZipFile(dst) as z:
        assert z.testzip() == member                      # zipfile itself sees the bad CRC


def write_text(src, dst):
    dst.write_text("pulse,sample,re,im\n0,0,1.0,0.0\n")


def write_npy(src, dst):
    with open(dst, "wb") as f:                            # a bare .npy, not an .npz archive
        np.save(f, arrays_of(src)["data"])


def raw_with(**changes):
    def damage(src, dst):
        arrays = arrays_of(src)
        for key, change in changes.items():
            arrays[key] = change(arrays[key])
        with open(dst, "wb") as f:
            np.savez(f, **arrays)
    return damage


def without(key):
    def damage(src, dst):
        arrays = arrays_of(src)
        del arrays[key]
        with open(dst, "wb") as f:
            np.savez(f, **arrays)
    return damage


def set_values(value, *indices):
    def change(array):
        array = array.copy()
        for index in indices:
            array[index] = value
        return array
    return change


def assert_refused(capsys, code, path, *fragments, out=None):
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and str(path) in err
    for fragment in fragments:
        assert fragment in err, err
    assert len(err.strip().splitlines()) == 1, err         # one message
    if out is not None:
        assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())


# ============================================================================ focus raw.npz
RAW_DAMAGE = {
    "truncated": (truncate, ["damaged .npz archive", "truncated"]),
    "bad_crc": (flip_byte_in, ["damaged .npz archive", "Bad CRC-32", "data.npy"]),
    "text": (write_text, ["not an .npz RawData file"]),
    "npy": (write_npy, ["not an .npz RawData file"]),
    "missing_field": (without("prf"), ["not a RawData file, missing ['prf']"]),
    "ten_columns": (raw_with(data=lambda d: d[:, :10]),
                    ["data has 10 fast-time samples (columns) but fast_time has 335 entries"]),
    "pulse_time_short": (raw_with(pulse_time=lambda t: t[:-1]),
                         ["data has 64 pulses (rows) but pulse_time has 63 entries"]),
    "one_nan": (raw_with(data=set_values(np.nan, (3, 17))),
                ["data has 1 non-finite sample (NaN or Inf)", "(pulse 3, sample 17)", "nan_to_num"]),
    # the first in (pulse, sample) order is (3, 40), though (5, 2) has the lower sample index
    "three_bad": (raw_with(data=set_values(complex(0, np.inf), (5, 2), (3, 40), (60, 300))),
                  ["data has 3 non-finite samples", "(pulse 3, sample 40)"]),
    "nan_position": (raw_with(tx_position=set_values(np.nan, (5, 2))),
                     ["tx_position has 1 non-finite value", "(pulse 5, axis z)"]),
    "inf_fast_time": (raw_with(fast_time=set_values(np.inf, 7)),
                      ["fast_time has 1 non-finite value", "(sample 7)"]),
    "nan_pulse_time": (raw_with(pulse_time=set_values(np.nan, 9, 12)),
                       ["pulse_time has 2 non-finite values", "(pulse 9)"]),
}


@pytest.mark.parametrize("damage", RAW_DAMAGE, ids=list(RAW_DAMAGE))
def test_focus_refuses_damaged_raw(valid, tmp_path, capsys, damage):
    make, fragments = RAW_DAMAGE[damage]
    path = tmp_path / "raw.npz"
    make(valid[0], path)
    out = tmp_path / "o"
    code = main(["focus", str(path), "--out", str(out), "--no-progress"])
    assert_refused(capsys, code, path, *fragments, out=out)
    assert "allow_pickle" not in capsys.readouterr().err


def test_focus_of_missing_file_names_it(tmp_path, capsys):
    path = tmp_path / "nothing.npz"
    code = main(["focus", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert_refused(capsys, code, path, "No such file", out=tmp_path / "o")


def test_in_memory_raw_data_refuses_non_finite_samples(valid):
    """The tracer's in-memory RawData gets the same check (one np.isfinite pass)."""
    raw = RawData.load(valid[0])
    data = raw.data.copy()
    data[10, 0] = np.nan
    kwargs = {k: getattr(raw, k) for k in RAW_KEYS if k != "data"}
    with pytest.raises(RawDataError, match=r"1 non-finite sample .*\(pulse 10, sample 0\)"):
        RawData(data=data, **kwargs)


# ============================================================================ analyze image.npz
def image_with(**changes):
    return raw_with(**changes)


IMAGE_DAMAGE = {
    "truncated": (truncate, ["damaged .npz archive", "truncated"]),
    "bad_crc": (flip_byte_in, ["damaged .npz archive", "Bad CRC-32", "data.npy"]),
    "text": (write_text, ["not an .npz SarImage file"]),
    "missing_field": (without("range_direction"), ["not a SarImage file, missing ['range_direction']"]),
    "short_azimuth": (image_with(azimuth=lambda a: a[:-2]), ["data has 64 azimuth rows but azimuth has 62 entries"]),
    "short_range": (image_with(data=lambda d: d[:, :-1]), ["data has 334 range columns but range has 335 entries"]),
    "one_nan": (image_with(data=set_values(np.nan, (4, 9))),
                ["data has 1 non-finite pixel (NaN or Inf)", "(azimuth 4, range 9)"]),
    "two_inf": (image_with(data=set_values(np.inf, (40, 3), (7, 300))),
                ["data has 2 non-finite pixels", "(azimuth 7, range 300)"]),
    "nan_origin": (image_with(origin=set_values(np.nan, 1)), ["origin has 1 non-finite value", "(axis y)"]),
}


@pytest.mark.parametrize("damage", IMAGE_DAMAGE, ids=list(IMAGE_DAMAGE))
def test_analyze_refuses_damaged_image(valid, tmp_path, capsys, damage):
    make, fragments = IMAGE_DAMAGE[damage]
    path = tmp_path / "image.npz"
    make(valid[1], path)
    figure = tmp_path / "fig" / "chip.png"
    code = main(["analyze", str(path), "--target", "0,0,0", "--chip", "16", "--figure", str(figure)])
    assert_refused(capsys, code, path, *fragments)
    assert not figure.exists()


def test_analyze_refuses_damaged_raw_beside_the_image(valid, tmp_path, capsys):
    """The raw.npz read for the carrier ramp is not silently skipped when damaged."""
    (tmp_path / "image.npz").write_bytes(valid[1].read_bytes())
    raw = tmp_path / "raw.npz"
    raw_with(data=set_values(np.nan, (3, 17)))(valid[0], raw)
    code = main(["analyze", str(tmp_path / "image.npz"), "--target", "0,0,0", "--chip", "16"])
    assert_refused(capsys, code, raw, "(pulse 3, sample 17)", "carrier ramp")


def test_analyze_uses_an_intact_raw(valid, capsys):
    """Control for the test above: with the intact raw data, the carrier comes from them."""
    code = main(["analyze", str(valid[1]), "--target", "0,0,0", "--chip", "16", "--raw", str(valid[0])])
    out = capsys.readouterr().out
    assert code == 0 and '"carrier": "given"' in out


def test_analyze_refuses_missing_explicit_raw(valid, tmp_path, capsys):
    path = tmp_path / "absent.npz"
    code = main(["analyze", str(valid[1]), "--target", "0,0,0", "--chip", "16", "--raw", str(path)])
    assert_refused(capsys, code, path, "No such file")


def test_in_memory_image_may_hold_nan_but_load_refuses(valid, tmp_path):
    """A focuser's image with NaN stays drawable (quick-look); reading one back is refused."""
    image = SarImage.load(valid[1])
    data = image.data.copy()
    data[0, 5] = np.nan
    bad = SarImage(data=data, azimuth=image.azimuth, range=image.range, origin=image.origin,
                   azimuth_direction=image.azimuth_direction, range_direction=image.range_direction)
    bad.save(tmp_path / "image.npz")
    with pytest.raises(SarImageError, match=r"image\.npz: data has 1 non-finite pixel .*\(azimuth 0, range 5\)"):
        SarImage.load(tmp_path / "image.npz")


# ============================================================================ figures.redraw
@pytest.mark.parametrize("name, damage, error, fragment", [
    ("image.npz", flip_byte_in, SarImageError, "Bad CRC-32"),
    ("raw.npz", raw_with(data=set_values(np.nan, (2, 5))), RawDataError, r"\(pulse 2, sample 5\)"),
])
def test_redraw_refuses_damaged_files(valid, tmp_path, name, damage, error, fragment):
    for intact in valid:
        (tmp_path / intact.name).write_bytes(intact.read_bytes())
    damage(valid[0] if name == "raw.npz" else valid[1], tmp_path / name)
    with pytest.raises(error, match=f"{name}: .*{fragment}"):
        figures.redraw(tmp_path, scene=False)
    assert not list(tmp_path.glob("fig_*"))
