"""EXR and PNG products of a SarImage: contents read back, sizes, atomic writes, no warnings."""
from __future__ import annotations

import json
import warnings

import matplotlib.image
import numpy as np
import OpenEXR
import pytest

from sarmitsuba.image import SarImage
from sarmitsuba.products import write_exr, write_quicklook


def make_image(data: np.ndarray | None = None, plane: str = "ground") -> SarImage:
    """A 41 x 57 image: a 2-D sinc point response with a phase ramp, axes in metres."""
    azimuth = (np.arange(41) - 20) * 0.25
    rng_axis = (np.arange(57) - 28) * 0.5 + 3.0
    if data is None:
        response = np.sinc(azimuth[:, None] / 0.5) * np.sinc((rng_axis[None, :] - 3.0) / 1.1)
        data = (response * np.exp(1j * (0.3 + 2.0 * rng_axis[None, :]))).astype(np.complex64)
    return SarImage(data=data, azimuth=azimuth, range=rng_axis, origin=np.array([0.0, 0.0, 0.0]),
                    azimuth_direction=np.array([1.0, 0.0, 0.0]), range_direction=np.array([0.0, -1.0, 0.0]),
                    plane=plane, metadata={"scene": "unit test", "focus": {"fc": 9.6e9, "bandwidth": 150e6,
                                                                           "n_pulses": 561}})


def read_exr(path) -> tuple[dict[str, np.ndarray], dict]:
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: ch.pixels.copy() for name, ch in f.channels().items()}, dict(f.header())


def no_partial_files(directory) -> bool:
    return not any(p.name.endswith(".partial") for p in directory.iterdir())


# ============================================================================ EXR
def test_exr_round_trip(tmp_path):
    image = make_image()
    path = write_exr(image, tmp_path / "image.exr")
    assert path.exists() and no_partial_files(tmp_path)
    channels, header = read_exr(path)
    assert set(channels) == {"intensity", "real", "imag"}
    for name, pixels in channels.items():
        assert pixels.dtype == np.float32 and pixels.shape == image.data.shape, name
    intensity = np.abs(image.data.astype(np.complex128)) ** 2
    f32 = np.finfo(np.float32)
    np.testing.assert_allclose(channels["intensity"], intensity, rtol=2 * f32.eps, atol=f32.tiny)  # tiny: underflow
    assert np.array_equal(channels["real"], image.data.real)
    assert np.array_equal(channels["imag"], image.data.imag)
    info = json.loads(header["sarmitsuba"])
    assert info["plane"] == "ground" and info["algorithm"] == "backprojection"
    assert np.allclose(info["azimuth"], image.azimuth) and np.allclose(info["range"], image.range)
    assert info["metadata"]["scene"] == "unit test"


def test_exr_overwrite_is_atomic(tmp_path, monkeypatch):
    path = write_exr(make_image(), tmp_path / "image.exr")
    before = path.read_bytes()

    def fail(self, filename):
        with open(filename, "wb") as f:
            f.write(b"half a file")
        raise OSError("disk full")

    monkeypatch.setattr(OpenEXR.File, "write", fail)
    with pytest.raises(OSError, match="disk full"):
        write_exr(make_image(np.zeros((41, 57), np.complex64)), path)
    assert path.read_bytes() == before and no_partial_files(tmp_path)


# ============================================================================ PNG quicklook
@pytest.mark.parametrize("plane", ["ground", "slant"])
def test_quicklook_png(tmp_path, plane):
    path = write_quicklook(make_image(plane=plane), tmp_path / "quicklook.png", title="point target")
    assert path.exists() and no_partial_files(tmp_path)
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[:2] == (600, 800)  # default figsize (8, 6) at 100 dpi
    assert np.std(pixels[..., :3]) > 0


def test_quicklook_size_follows_figsize_and_dpi(tmp_path):
    path = write_quicklook(make_image(), tmp_path / "small.png", dynamic_range_db=25, figsize=(4, 3), dpi=50)
    assert matplotlib.image.imread(path).shape[:2] == (150, 200)


def test_quicklook_rejects_bad_dynamic_range(tmp_path):
    for value in (0, -10, np.nan):
        with pytest.raises(ValueError, match="dynamic_range_db"):
            write_quicklook(make_image(), tmp_path / "bad.png", dynamic_range_db=value)
    assert not (tmp_path / "bad.png").exists() and no_partial_files(tmp_path)


# ============================================================================ degenerate images
def test_all_zero_image_writes_without_warnings(tmp_path):
    image = make_image(np.zeros((41, 57), np.complex64))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exr = write_exr(image, tmp_path / "zero.exr")
        png = write_quicklook(image, tmp_path / "zero.png")
    channels, _ = read_exr(exr)
    assert not np.any(channels["intensity"])
    pixels = matplotlib.image.imread(png)
    assert pixels.shape[:2] == (600, 800) and np.all(np.isfinite(pixels))
    assert np.std(pixels[..., :3]) > 0  # axes, labels and colour bar are still drawn


def test_single_pixel_and_non_finite_images(tmp_path):
    one = SarImage(data=np.ones((1, 1), np.complex64), azimuth=np.zeros(1), range=np.zeros(1),
                   origin=np.zeros(3), azimuth_direction=np.array([1.0, 0, 0]),
                   range_direction=np.array([0, -1.0, 0]))
    data = make_image().data.copy()
    data[3, 4] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_quicklook(one, tmp_path / "one.png")
        write_quicklook(make_image(data), tmp_path / "nan.png")
    assert matplotlib.image.imread(tmp_path / "nan.png").shape[:2] == (600, 800)
