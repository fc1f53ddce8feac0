"""The Pauli RGB picture (sarmitsuba.products.figures_pol), against hand-made scattering matrices.

Truth: an ideal dihedral (HH = 1, VV = -1) is pure even bounce, a trihedral or plate
(HH = VV) pure odd bounce, a 45-degree rotated dihedral (HV = VH, HH = VV = 0) pure k3
(Lee and Pottier 2009, ch. 3). Colours are ``1 + dB / dynamic_range`` re one common
reference, so a power 10 dB below the reference sits at ``1 - 10 / dynamic_range``.
"""
from __future__ import annotations

import math
import warnings

import matplotlib.image
import numpy as np
import pytest

from sarmitsuba.products.figures_pol import pauli_components, pauli_rgb, write_pauli
from sarmitsuba.core.image import SarImage
from sarmitsuba.core.outputs import WriteError

DR = 30.0
RED, GREEN, BLUE = 0, 1, 2


def image(data, range_shift: float = 0.0) -> SarImage:
    """A SarImage of ``data`` [n_az, n_rg] on a 0.5 m ground grid."""
    data = np.asarray(data, dtype=np.complex64)
    n_az, n_rg = data.shape
    return SarImage(data=data, azimuth=(np.arange(n_az) - n_az // 2) * 0.5,
                    range=(np.arange(n_rg) - n_rg // 2) * 0.5 + range_shift, origin=np.zeros(3),
                    azimuth_direction=np.array([1.0, 0.0, 0.0]), range_direction=np.array([0.0, -1.0, 0.0]),
                    metadata={"scene": "pauli test"})


def quad(hh, hv, vh, vv) -> dict[str, SarImage]:
    """A quad-pol image set from four arrays (or scalars broadcast to a 4 x 6 image)."""
    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=np.complex128) for x in (hh, hv, vh, vv)))
    if arrays[0].ndim == 0:
        arrays = [np.full((4, 6), a) for a in arrays]
    return {name: image(a) for name, a in zip(("HH", "HV", "VH", "VV"), arrays)}


# ============================================================================ the numbers
def test_pauli_components_of_canonical_scatterers():
    """k1 = (HH+VV)/sqrt2, k2 = (HH-VV)/sqrt2, k3 = (HV+VH)/sqrt2, in the images' unit."""
    k1, k2, k3 = pauli_components(quad(1.0, 0.0, 0.0, -1.0))          # dihedral: all in k2
    assert np.allclose(k2, math.sqrt(2.0)) and np.allclose(k1, 0.0) and np.allclose(k3, 0.0)
    k1, k2, k3 = pauli_components(quad(2.0j, 0.5, 0.5, 2.0j))         # trihedral + HV: k1, k3
    assert np.allclose(k1, 4.0j / math.sqrt(2.0)) and np.allclose(k2, 0.0)
    assert np.allclose(k3, 1.0 / math.sqrt(2.0))
    assert k1.shape == (4, 6) and np.iscomplexobj(k1)


@pytest.mark.parametrize("hh, hv, vh, vv, colour", [
    (1.0, 0.0, 0.0, -1.0, RED),       # ideal dihedral: even bounce
    (1.0, 0.0, 0.0, 1.0, BLUE),       # trihedral: odd bounce
    (-1.0, 0.0, 0.0, -1.0, BLUE),     # PEC plate at normal incidence (S = -I): odd bounce too
    (0.0, 1.0, 1.0, 0.0, GREEN),      # dihedral rotated by 45 degrees
])
def test_canonical_scatterers_are_pure_colours(hh, hv, vh, vv, colour):
    """Catches a swapped channel order (R must be HH-VV, B HH+VV) and a wrong colour for k3."""
    rgb = pauli_rgb(quad(hh, hv, vh, vv), DR)
    assert rgb.shape == (4, 6, 3)
    expected = np.zeros(3)
    expected[colour] = 1.0
    assert np.allclose(rgb, expected)


def test_cross_polar_channels_enter_as_a_sum():
    """HV = -VH cancels in k3 (no green); a difference HV - VH would give full green."""
    hh = np.ones((4, 6))
    hv = np.zeros((4, 6))
    hv[0, 0] = 1.0                                            # one pixel with HV = -VH next to trihedrals
    rgb = pauli_rgb(quad(hh, hv, -hv, hh), DR)
    assert np.all(rgb[..., GREEN] == 0.0)
    assert np.allclose(rgb[..., BLUE], 1.0)


def test_a_pixel_ten_db_weaker_sits_at_one_minus_ten_over_the_range():
    """Linear dB scale of each channel: catches an amplitude (not power) scale, which would put
    the pixel at 1 - 5/DR, and a linear-intensity scale, which would put it at 0.1."""
    a = np.ones((4, 6))
    a[1, 2] = 10.0 ** (-10.0 / 20.0)                          # amplitude -10 dB -> power -10 dB
    rgb = pauli_rgb(quad(a, 0.0, 0.0, -a), DR)
    assert rgb[1, 2, RED] == pytest.approx(1.0 - 10.0 / DR, abs=1e-6)
    assert rgb[0, 0, RED] == pytest.approx(1.0)
    rgb = pauli_rgb(quad(a, 0.0, 0.0, -a), 20.0)              # the same pixel on a 20 dB display
    assert rgb[1, 2, RED] == pytest.approx(0.5, abs=1e-6)


def test_one_reference_for_all_three_channels():
    """Blue 10 dB below red everywhere stays 10 dB below it: a per-channel reference would
    stretch every channel to 1 and make this scene white-ish magenta."""
    amp = 10.0 ** (-10.0 / 20.0)
    dihedral, trihedral = np.array([1.0, -1.0]), amp * np.array([1.0, 1.0])
    hh, vv = dihedral + trihedral                              # HH and VV of the sum of both
    rgb = pauli_rgb(quad(hh, 0.0, 0.0, vv), DR)
    assert np.allclose(rgb[..., RED], 1.0)
    assert np.allclose(rgb[..., BLUE], 1.0 - 10.0 / DR, atol=1e-6)
    assert np.all(rgb[..., GREEN] == 0.0)


def test_powers_are_block_averaged_by_whole_looks():
    """4 x 6 pixels shown in at most 3 per axis: 2 x 2 looks, the mean power of each block.

    Catches no multilooking (shape), a block maximum (would show the quarter block at 1) and
    an amplitude average (would put it at -12 dB instead of -6 dB)."""
    hh = np.zeros((4, 6))
    hh[:, 0:2] = 1.0                                           # blocks (0, 0), (1, 0): all dihedral
    hh[0, 2] = 1.0                                             # block (0, 1): one pixel of four
    rgb = pauli_rgb(quad(hh, 0.0, 0.0, -hh), DR, max_pixels=3)
    assert rgb.shape == (2, 3, 3)
    assert rgb[0, 0, RED] == pytest.approx(1.0) and rgb[1, 0, RED] == pytest.approx(1.0)
    assert rgb[0, 1, RED] == pytest.approx(1.0 - 10.0 * math.log10(4.0) / DR, abs=1e-6)
    assert rgb[1, 1, RED] == 0.0 and rgb[0, 2, RED] == 0.0


def test_all_zero_images_are_black_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rgb = pauli_rgb(quad(0.0, 0.0, 0.0, 0.0), DR)
    assert rgb.shape == (4, 6, 3) and np.all(rgb == 0.0)


# ============================================================================ bad input
def test_missing_channel_is_named():
    images = quad(1.0, 0.0, 0.0, 1.0)
    del images["VH"]
    with pytest.raises(ValueError, match="VH"):
        pauli_rgb(images, DR)


def test_channels_on_different_grids_are_refused():
    images = quad(1.0, 0.0, 0.0, 1.0)
    images["VV"] = image(np.ones((4, 5)))                      # shape differs
    with pytest.raises(ValueError, match="VV.*shape"):
        pauli_components(images)
    images["VV"] = image(np.ones((4, 6)), range_shift=2.0)    # same shape, range axis differs
    with pytest.raises(ValueError, match="VV.*range"):
        pauli_components(images)


@pytest.mark.parametrize("bad", [0.0, -10.0, float("nan"), float("inf")])
def test_bad_dynamic_range_is_refused(bad, tmp_path):
    images = quad(1.0, 0.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="dynamic_range_db"):
        pauli_rgb(images, bad)
    with pytest.raises(ValueError, match="dynamic_range_db"):
        write_pauli(images, tmp_path / "pauli.png", bad)
    assert not list(tmp_path.iterdir())


# ============================================================================ the PNG
def test_png_has_the_figure_size_and_all_zero_input_draws_without_warnings(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = write_pauli(quad(0.0, 0.0, 0.0, 0.0), tmp_path / "zero.png")
        assert path == tmp_path / "zero.png"
        assert matplotlib.image.imread(path).shape[:2] == (880, 1100)   # (8 x 110, 10 x 110) pixels
        small = write_pauli(quad(1.0, 0.0, 0.0, -1.0), tmp_path / "dihedral.png", title="x", figsize=(4.0, 3.0),
                            dpi=50)
    assert matplotlib.image.imread(small).shape[:2] == (150, 200)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dihedral.png", "zero.png"]


def test_unwritable_path_raises_write_error_naming_it(tmp_path, unwritable_paths):
    """The quicklook's WriteError: names the target, leaves no partial file."""
    for target in unwritable_paths:
        with pytest.raises(WriteError) as caught:
            write_pauli(quad(1.0, 0.0, 0.0, 1.0), target, figsize=(3.0, 2.0), dpi=40)
        assert str(caught.value).startswith(f"cannot write Pauli picture {target}: ")
        assert caught.value.filename == str(target)
    assert not list(tmp_path.rglob("*.partial")) and not list(tmp_path.rglob("*.png"))
