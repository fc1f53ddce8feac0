"""EXR and PNG products of a SarImage: contents read back, sizes, atomic writes, no warnings."""
from __future__ import annotations

import json
import warnings

import matplotlib.image
import numpy as np
import OpenEXR
import pytest

from sarmitsuba.core.image import SarImage
from sarmitsuba.products.image_files import write_exr, write_quicklook


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


# ============================================================================ issue 13: what the quicklook says
def quicklook_axes(fig):
    """(image axes, colour-bar axes): the bar is an inset of the image axes."""
    ax = fig.axes[0]
    bars = [a for a in (*fig.axes, *ax.child_axes) if hasattr(a, "_colorbar")]
    return ax, bars[0]


@pytest.mark.parametrize("plane, x_from", [("ground", "ground range from scene centre"),
                                           ("slant", "slant range (closest approach)")])
def test_quicklook_marks_range_origin_sensor_side_and_flight(tmp_path, drawn, plane, x_from):
    write_quicklook(make_image(plane=plane), tmp_path / "q.png", figsize=(6, 4.5), dpi=60)
    fig = drawn[-1]
    ax, bar = quicklook_axes(fig)
    renderer = fig.canvas.get_renderer()
    assert ax.get_xlabel().startswith(x_from) and ax.get_ylabel().startswith("azimuth from")
    texts = {t.get_text(): t.get_window_extent(renderer) for t in ax.texts}
    near = [box for text, box in texts.items() if "near range" in text and "sensor" in text]
    far = [box for text, box in texts.items() if "far range" in text]
    assert near and far and any("flight" in text for text in texts)
    assert near[0].x1 < far[0].x0, "near range on the left (small range), far range on the right"
    label = ax.xaxis.label.get_window_extent(renderer)
    assert not near[0].overlaps(label) and not far[0].overlaps(label)
    # the image is 41 x 57 pixels of 0.25 x 0.5 m: wide, so an equal-aspect box is shorter than its cell
    assert bar.get_window_extent(renderer).height == pytest.approx(ax.get_window_extent(renderer).height, rel=0.05)


def test_quicklook_title_gives_fc_and_b_once(tmp_path, drawn):
    """A caller's title with fc and B (as render's) is not followed by them again; without one, the
    metadata's fc and B are given (once)."""
    write_quicklook(make_image(), tmp_path / "a.png", title="dihedral  9.60 GHz  B=150 MHz  inc=45 deg", dpi=30)
    write_quicklook(make_image(), tmp_path / "b.png", dpi=30)
    given, default = (fig.axes[0].get_title() for fig in drawn[-2:])
    assert given.count("GHz") == 1 and given.count("MHz") == 1
    assert default.count("GHz") == 1 and "fc 9.6 GHz" in default and "B 150 MHz" in default


def test_render_quicklook_title_gives_fc_and_b_once(tmp_path, drawn):
    from sarmitsuba.pipeline import render
    render("dihedral", tmp_path / "out", progress=False)
    titles = [fig.axes[0].get_title() for fig in drawn]
    assert titles and all(t.count("GHz") == 1 and t.count("MHz") == 1 for t in titles), titles


@pytest.mark.parametrize("writer, what", [(write_quicklook, "quicklook"), (write_exr, "EXR image")])
def test_unwritable_target_is_named_and_nothing_is_left(tmp_path, unwritable_paths, writer, what):
    from sarmitsuba.products.image_files import WriteError
    for target in unwritable_paths:
        with pytest.raises(WriteError) as caught:
            writer(make_image(), target)
        message = str(caught.value)
        assert message.startswith(f"cannot write {what} {target}: ") and ".partial" not in message
        assert caught.value.filename == str(target) and caught.value.errno is not None
        assert not list(tmp_path.rglob("*.partial"))
    assert (tmp_path / "folder").is_dir() and not any((tmp_path / "folder").iterdir())
