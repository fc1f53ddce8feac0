"""The render's products stream to disk on a thread while the quick-look is drawn (issue 56):
the files are byte for byte those of writing them one after the other, and a failure on either
side still fails the whole write, naming the file, with nothing left in the folder."""
from __future__ import annotations

import types

import numpy as np
import pytest

from sarmitsuba import pipeline
from sarmitsuba.core.outputs import OutputDirectory
from sarmitsuba.core.raw import RawData
from sarmitsuba.products import image_files

from test_products import make_image


def _raw() -> RawData:
    n_pulses, n_samples = 6, 32
    rng = np.random.default_rng(1)
    track = np.stack([np.arange(n_pulses) * 0.5, np.zeros(n_pulses), np.full(n_pulses, 1000.0)], axis=1)
    data = (rng.normal(size=(n_pulses, n_samples)) + 1j * rng.normal(size=(n_pulses, n_samples))).astype(np.complex64)
    return RawData(data=data, fast_time=1e-5 + np.arange(n_samples) / 180e6, pulse_time=np.arange(n_pulses) / 250.0,
                   tx_position=track, rx_position=track.copy(), velocity=np.tile([100.0, 0.0, 0.0], (n_pulses, 1)),
                   fc=9.6e9, bandwidth=150e6, chirp_rate=150e6 / 1e-5, fs=180e6, prf=250.0, pulse_length=1e-5,
                   range_compressed=True,
                   metadata={"scene": "unit test", "settings": {"max_depth": 2}, "polarization": "VV"})


PARAMS = types.SimpleNamespace(frequency=9.6e9, bandwidth=150e6, incidence_angle=45.0, polarization="VV")


def test_streamed_products_equal_sequential_writes(tmp_path):
    raw, image = _raw(), make_image()
    with OutputDirectory(tmp_path / "render", products="replace") as out:
        paths = pipeline._write_products(out, raw, image, PARAMS, suffix="_order2")
    assert list(paths) == ["raw_order2", "image_order2", "exr_order2", "png_order2"]
    title = (f"unit test  9.60 GHz  B=150 MHz  inc=45 deg  VV  depth=2  window {pipeline.window_title(image)}")
    one = tmp_path / "one"
    one.mkdir()
    raw.save(one / "raw.npz")
    image.save(one / "image.npz")
    image_files.write_exr(image, one / "image.exr")
    image_files.write_quicklook(image, one / "image.png", title=title, figsize=(10.0, 8.0), dpi=110)
    for role, name in (("raw", "raw.npz"), ("image", "image.npz"), ("exr", "image.exr"), ("png", "image.png")):
        assert paths[f"{role}_order2"].read_bytes() == (one / name).read_bytes(), role


@pytest.mark.parametrize("failing", ["exr", "png"])
def test_a_failed_product_fails_the_write_and_leaves_nothing(tmp_path, monkeypatch, failing):
    def broken(*args, **kwargs):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(image_files, "write_exr" if failing == "exr" else "write_quicklook", broken)
    folder = tmp_path / "render"
    with pytest.raises(OSError) as caught:
        with OutputDirectory(folder, products="replace") as out:
            pipeline._write_products(out, _raw(), make_image(), PARAMS)
    name = "image.exr" if failing == "exr" else "image.png"
    assert str(folder / name) in str(caught.value) and "No space left" in str(caught.value)
    assert not folder.exists() or not any(folder.iterdir())
