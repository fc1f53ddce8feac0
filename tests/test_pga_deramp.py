"""The deramp of a backprojected image for PGA (sarmitsuba.focus.pga_deramp, docs/physics.md (PGA2)):
its sampling against the band the antenna positions span, and the spectra of lines at different
ranges read at the same positions, against closed forms.

The deramped spectrum of a line at closest-approach range ``R0`` stands for the antenna position
``s = -f lambda R0 / 2``: a track ``L`` long spans ``2 L / (lambda R0)`` cycles per metre, whatever
the image's extent. The urban scene's estimation image (1160 rows of 0.33 m, a 311 m track, ranges
1280 to 1563 m) needs 5.7 times its sampling for that, and PGA ran there without a deramp: it could
not read its estimate at the pulses, and said it had not been applied.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.core.image import SarImage
from sarmitsuba.focus.pga_deramp import aperture_grid, column_phase, fresnel_frame, line_spectra

C = 299792458.0
FC = 9.6e9
WAVELENGTH = C / FC


def _image(n_az: int, step: float, ranges: np.ndarray, length: float) -> SarImage:
    """A backprojected image's frame: track at (0, 1000, 1000) m along +x, ground range along -y."""
    return SarImage(data=np.zeros((n_az, ranges.size), np.complex64), azimuth=(np.arange(n_az) - n_az // 2) * step,
                    range=ranges, origin=np.zeros(3), azimuth_direction=np.array([1.0, 0.0, 0.0]),
                    range_direction=np.array([0.0, -1.0, 0.0]),
                    metadata={"focus": {"fc": FC, "track": {"position": [0.0, 1000.0, 1000.0],
                                                            "direction": [1.0, 0.0, 0.0], "length": length}}})


@pytest.mark.parametrize("n_az, step, length", [(1160, 0.3302, 311.2), (240, 0.33, 69.6)])
def test_the_upsampled_rows_hold_the_band_of_the_track(n_az, step, length):
    """The urban scene's estimation image and the built-in trihedral's: the upsampled rows' Nyquist
    band (1 / step cycles per metre) holds the antenna positions' band 2 L / (lambda R0) at the
    nearest column, and is less than twice it (the rows are not wastefully fine). Catches the band
    taken as the image's extent plus the track's with the upsampling capped at 8, the original
    defect (the urban image then needs 11.5 times its sampling and is not deramped at all)."""
    ranges = np.linspace(-200.0, 200.0, 5)
    frame = fresnel_frame(_image(n_az, step, ranges, length))
    assert frame is not None
    r0 = np.hypot(ranges + 1000.0, 1000.0)
    assert frame.r0 == pytest.approx(r0)
    band = 2.0 * length / (WAVELENGTH * r0.min())
    assert band <= 1.0 / abs(frame.step) < 2.0 * band
    assert frame.phase.shape == (n_az * frame.factor, 5)


def test_lines_at_different_ranges_are_read_at_the_same_antenna_position():
    """One pulse at s = 40 m seen by two lines, at R0 = 1400 m and 1540 m (10 % farther): their
    deramped images are ``exp(-j 2 k x s / R0)``; read at the grid of 1400 m both spectra peak at the
    sample standing for 40 m (the plain FFT puts the far line's at 36.4 m, 1400 / 1540 of it).
    Catches the scale inverted (the far line at 44 m) and the plain FFT for every line."""
    n, step = 2048, 0.05
    x = (np.arange(n) - n // 2) * step
    k = 2.0 * np.pi / WAVELENGTH
    r0 = np.array([1400.0, 1540.0])
    lines = np.exp(-2j * k * np.outer(x, 40.0 / r0))
    spectra = line_spectra(lines, r0, 1400.0)
    frame = type("Frame", (), {"step": step, "sense": 1.0, "wavelength": WAVELENGTH})()
    s = aperture_grid(frame, n, 1400.0)
    cell = abs(s[1] - s[0])
    for j in range(2):
        assert s[int(np.argmax(np.abs(spectra[:, j])))] == pytest.approx(40.0, abs=cell)


def test_a_phase_on_the_grid_is_read_at_each_columns_positions():
    """A linear phase ``a s`` given on the grid of r_ref = 1400 m is read on a column at R0 = 1540 m
    at the positions ``s R0 / r_ref``: ``a s 1.1`` (held at the grid's ends beyond it). Catches the
    scale inverted and the phase read as if every column stood at r_ref."""
    s = np.linspace(60.0, -60.0, 121)
    phase = column_phase(0.2 * s, s, np.array([1400.0, 1540.0]), 1400.0)
    inside = np.abs(s) <= 50.0
    assert phase[:, 0] == pytest.approx(0.2 * s)
    assert phase[inside, 1] == pytest.approx(0.2 * 1.1 * s[inside])
