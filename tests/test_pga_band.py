"""Which range lines PGA learns from (sarmitsuba.focus.pga_lines, docs/physics.md (PGA4)): the share of
the beam's Doppler band a line's response fills, against closed forms.

A point, however far a phase error smears it, fills the band (the error moves its energy about and
leaves its spectrum's magnitude alone); a line extended along azimuth over ``l`` samples, a wall's
double bounce, has the spectrum of a ``l``-sample boxcar, ``|sin(pi f l) / (l sin(pi f))|^2``, and
fills a few times ``1 / l`` of it.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.core.image import SarImage
from sarmitsuba.focus.pga_lines import (BAND_DB, POINT_BAND, band_occupancy, doppler_band, point_likeness,
                                        point_lines, signal_pixels)

N = 400
STEP = 0.25                                    # m along azimuth


def _image(data: np.ndarray, beamwidth_deg: float = 1.2, fc: float = 9.6e9) -> SarImage:
    return SarImage(data=data.astype(np.complex64), azimuth=np.arange(data.shape[0]) * STEP,
                    range=np.arange(data.shape[1]) * 0.5, origin=np.zeros(3), azimuth_direction=np.array([1.0, 0, 0]),
                    range_direction=np.array([0, -1.0, 0]),
                    metadata={"radar": {"azimuth_beamwidth": beamwidth_deg, "frequency": fc}, "focus": {"fc": fc}})


def _band_signal(band: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Speckle filling ``band`` (FFT order): the image's background, whose spectrum centres the band."""
    return np.fft.ifft(np.where(band, np.exp(2j * np.pi * rng.uniform(size=N)), 0.0))


@pytest.mark.parametrize("beamwidth_deg, fc", [(1.2, 9.6e9), (3.0, 5.4e9)])
def test_the_doppler_band_is_the_beams(beamwidth_deg, fc):
    """The band holds the FFT bins within 2 sin(theta / 2) / lambda cycles per metre of zero (an
    image whose clutter fills it symmetrically): at 1.2 deg, 9.6 GHz, 0.670 c/m, bins of 0.01 c/m
    (400 x 0.25 m): 2 x 67 + 1. Catches the one-way band taken twice as wide (sin(theta) for
    sin(theta / 2))."""
    half = 2.0 * np.sin(np.radians(beamwidth_deg) / 2.0) * fc / 299792458.0
    f = np.fft.fftfreq(N, d=STEP)
    expected = np.abs(f) <= half
    rng = np.random.default_rng(3)
    data = np.stack([_band_signal(expected, rng) for _ in range(8)], axis=1)
    band = doppler_band(_image(data, beamwidth_deg, fc))
    assert np.array_equal(band, expected)
    assert band.sum() == 2 * int(np.floor(half / (1.0 / (N * STEP)))) + 1


def test_a_point_fills_the_band_and_a_wall_does_not():
    """Column 0: an impulse (a focused point) fills the band (1.0). Column 1: the same point smeared
    by a quadratic phase error of 30 rad at the band's edge (paired echoes over some 10 m) fills
    it too (>= POINT_BAND). Column 2: a boxcar of 64 samples (16 m of wall), its share the
    fraction of band bins where the closed form |sin(pi f l) / (l sin(pi f))|^2 >= -BAND_DB dB.
    Catches a response cut to the brightest sample (every line then fills the band)."""
    f = np.fft.fftfreq(N, d=STEP)
    band = np.abs(f) <= 2.0 * np.sin(np.radians(1.2) / 2.0) * 9.6e9 / 299792458.0
    data = np.zeros((N, 3), complex)
    data[150, 0] = 1.0
    u = f / np.abs(f[band]).max()
    data[:, 1] = np.fft.ifft(np.where(band, np.exp(30j * u ** 2 - 2j * np.pi * f * STEP * 200), 0.0))
    data[100:164, 2] = 1.0
    occupancy = band_occupancy(data, band)
    fc = f[band] * STEP                                     # cycles per sample
    with np.errstate(invalid="ignore", divide="ignore"):
        dirichlet = np.where(fc == 0, 1.0, np.sin(np.pi * fc * 64) / (64 * np.sin(np.pi * fc))) ** 2
    assert occupancy[0] == pytest.approx(1.0)
    assert occupancy[1] >= POINT_BAND
    assert occupancy[2] == pytest.approx(np.mean(dirichlet >= 10.0 ** (-BAND_DB / 10.0)), abs=1.5 / band.sum())
    assert occupancy[2] < 0.2


def test_point_lines_keep_the_broadband_bright_lines():
    """Three lines 30 dB and more over a speckle background: a point (column 3), a point smeared by a
    phase error over some 10 m (column 6) and 16 m of wall (column 9): point_lines keeps the two
    points. Catches the band test left out (the wall kept), and the band taken twice as wide."""
    rng = np.random.default_rng(5)
    f = np.fft.fftfreq(N, d=STEP)
    band = np.abs(f) <= 2.0 * np.sin(np.radians(1.2) / 2.0) * 9.6e9 / 299792458.0
    data = 1e-3 * np.stack([_band_signal(band, rng) for _ in range(12)], axis=1) * np.sqrt(band.sum())
    u = f / np.abs(f[band]).max()
    data[150, 3] += 1.0
    data[:, 6] += np.fft.ifft(np.where(band, np.exp(30j * u ** 2), 0.0)) * 4.0
    data[100:164, 9] += 0.5
    image = _image(data)
    intensity = np.abs(data) ** 2
    assert list(point_lines(intensity, signal_pixels(intensity), band_occupancy(data, doppler_band(image)))) == [3, 6]


def test_point_likeness_measures_distance_round_the_line():
    """A point at sample 2 whose response wraps round the end of the periodic (deramped,
    FFT-upsampled) line, 10 samples either side of it: the window of POINT_EXTENT x 128 lit samples
    (16 either side) about it holds all of its energy. Catches a plain distance from the peak
    (the 10 samples at N - 8 .. N - 1 read some 390 samples away: share 13 / 21)."""
    intensity = np.full((N, 1), 1e-9)
    signal = np.zeros((N, 1), bool)
    signal[:64] = signal[-64:] = True
    rows = (2 + np.arange(-10, 11)) % N
    intensity[rows, 0] = 1.0
    intensity[2, 0] = 4.0
    share, _ = point_likeness(intensity, signal)
    lit = intensity[signal[:, 0], 0].sum()
    assert share[0] == pytest.approx((24.0 + 12 * 1e-9) / lit, rel=1e-6)
