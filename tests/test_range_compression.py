"""Range compression and range weighting against closed forms (Cumming and Wong 2005, ch. 3;
raw and compressed data of one scene agree: docs/design.md section 5).

Raw chirps come from :mod:`sarmitsuba.analysis.synthetic`; "the truth" is the compressed echo
``a p_r(tau - L/c) exp(-j 2 pi fc L/c)`` written directly by the same generator (its
pulse ``p_r`` is checked against quadrature in ``test_windows.py``). Widths and sidelobes
are measured on the compressed lines by FFT interpolation, independently of the analysis
module.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate

from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import ImageGrid, backproject
from sarmitsuba.focus import windows as w
from sarmitsuba.focus.range_compression import apply_range_window, range_compress
from sarmitsuba.signal.signal_model import chirp_spectrum
from sarmitsuba.analysis.synthetic import PointTarget, simulate_point_targets, straight_track
from test_backprojection import _width

FC = 9.6e9
B = 150e6
TP = 2e-6  # time-bandwidth product 300
WINDOWS = [("rect", {}), ("taylor", {"nbar": 4, "sll": -35}), ("hamming", {}), ("kaiser", {"beta": 2.5})]
IDS = ["rect", "taylor4-35", "hamming", "kaiser2.5"]
TARGETS = [PointTarget((0.37, 0.11, 0.0), 0.9 * np.exp(0.4j)), PointTarget((4.0, -21.3, 0.0), 0.5j),
           PointTarget((-3.0, 12.7, 0.0), 0.3)]


def nrmse_db(x, ref):
    return 20 * np.log10(max(float(np.linalg.norm(x - ref)), 1e-300) / float(np.linalg.norm(ref)))


def scene(n_pulses=9, fs_factor=1.2, *, compressed, window="rect", params=None, anti_alias=True, targets=TARGETS):
    tr = straight_track(n_pulses, 400.0, 100.0, center=(0.0, 4000.0, 3000.0))
    fs = fs_factor * B
    lengths = np.concatenate([2 * np.linalg.norm(tr.position - t.position, axis=1) for t in targets])
    t0 = lengths.min() / C - TP / 2 - 100 / fs
    n = int(np.ceil((lengths.max() - lengths.min()) / C * fs + TP * fs + 200))
    return simulate_point_targets(targets, tr.position, FC, B, fs, t0, n, prf=400.0, velocity=tr.velocity,
                                  pulse_length=TP, compressed=compressed, range_window=window,
                                  range_window_params=params, anti_alias=anti_alias)


def upsample(line, factor):
    """Band-limited (periodic FFT) interpolation of a zero-padded line, Nyquist bin split."""
    n = line.size
    x = np.concatenate([line, np.zeros(n, line.dtype)]).astype(np.complex128)
    spec = np.fft.fft(x)
    big = np.zeros(2 * n * factor, complex)
    h = n
    big[:h] = spec[:h]
    big[-h + 1:] = spec[h + 1:]
    big[h] = big[-h] = 0.5 * spec[h]
    return np.fft.ifft(big)[: n * factor] * factor


def measure(line, fs, factor=64):
    """(peak time [s] from the first sample, peak value, -3 dB width [s], PSLR [dB]) of a line."""
    fine = upsample(line, factor)
    power = np.abs(fine) ** 2
    k = int(np.argmax(power))
    y0, y1, y2 = np.log(power[k - 1:k + 2])
    frac = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    width = _width(power, k) / (fs * factor)
    nl = k
    while power[nl - 1] < power[nl]:
        nl -= 1
    nr = k
    while power[nr + 1] < power[nr]:
        nr += 1
    span = 10 * (nr - k)
    side = max(power[max(nl - span, 0):nl].max(), power[nr + 1:nr + span].max())
    return (k + frac) / (fs * factor), fine[k], width, 10 * np.log10(side / power[k])


# ============================================================================ chirp spectrum
@pytest.mark.parametrize("sign", [1, -1], ids=["up", "down"])
def test_chirp_spectrum_against_quadrature(sign):
    tp, kr = 1e-6, sign * 100e6 / 1e-6
    for f in (0.0, 20e6, -37e6, 49.9e6, 61e6):
        re = scipy.integrate.quad(lambda t: np.cos(np.pi * kr * t * t - 2 * np.pi * f * t), -tp / 2, tp / 2,
                                  limit=2000, epsabs=1e-16)[0]
        im = scipy.integrate.quad(lambda t: np.sin(np.pi * kr * t * t - 2 * np.pi * f * t), -tp / 2, tp / 2,
                                  limit=2000, epsabs=1e-16)[0]
        assert abs(chirp_spectrum(f, tp, kr) - (re + 1j * im)) < 1e-8 * tp


# ============================================================================ raw == compressed
@pytest.mark.parametrize("window, params", WINDOWS, ids=IDS)
def test_raw_and_precompressed_give_the_same_data(window, params):
    raw = scene(compressed=False)
    truth = scene(compressed=True, window=window, params=params)
    out = range_compress(raw, window, **params)
    assert out.range_compressed and out.data.dtype == np.complex64
    assert np.array_equal(out.fast_time, raw.fast_time) and out.fs == raw.fs
    assert nrmse_db(out.data, truth.data) < -60.0
    assert out.metadata["range_window"]["name"] == window


def test_raw_and_precompressed_give_the_same_image():
    """Raw and compressed inputs give the same image (docs/design.md section 5): backprojection
    of both agrees to < -60 dB."""
    targets = [PointTarget((0.3, 0.1, 0.0), 1.0), PointTarget((2.0, -3.0, 0.0), 0.6j)]
    raw = scene(n_pulses=241, compressed=False, targets=targets)
    truth = scene(n_pulses=241, compressed=True, targets=targets)
    grid = ImageGrid.ground((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, -1.0, -1.0), 12.0, 12.0, 0.25)
    a = backproject(range_compress(raw), grid).data
    b = backproject(truth, grid).data
    assert nrmse_db(a, b) < -60.0


def test_directly_sampled_chirps_are_limited_by_aliasing():
    """Without an anti-aliasing filter the in-band error is about 1 / (2 pi sqrt(B T_p) (fs/B - 1))."""
    for fs_factor in (1.2, 1.5):
        raw = scene(compressed=False, anti_alias=False, fs_factor=fs_factor)
        truth = scene(compressed=True, fs_factor=fs_factor)
        bound = 20 * np.log10(1 / (2 * np.pi * np.sqrt(B * TP) * (fs_factor - 1)))
        assert nrmse_db(range_compress(raw).data, truth.data) < bound + 3.0


# ============================================================================ IRW, PSLR, peak
@pytest.mark.parametrize("window, params", WINDOWS, ids=IDS)
def test_compressed_pulse_figures(window, params):
    target = PointTarget((0.37, 0.11, 0.0), 0.9 * np.exp(0.4j))
    raw = scene(n_pulses=1, compressed=False, targets=[target])
    out = range_compress(raw, window, **params)
    length = 2 * np.linalg.norm(raw.tx_position[0] - target.position)
    t_peak, value, width, pslr = measure(out.data[0], raw.fs)
    # IRW: 0.886 c / 2B x broadening, in metres of slant range
    irw = width * C / 2
    assert irw == pytest.approx(0.886 * C / (2 * B) * w.broadening_factor(window, **params), rel=0.01)
    assert irw == pytest.approx(w.impulse_response_width(window, **params) * C / (2 * B), rel=0.002)
    assert pslr == pytest.approx(w.pslr_theory(window, **params), abs=0.5)
    # the peak sits at L/c and carries a exp(-j 2 pi fc L/c)
    assert raw.fast_time[0] + t_peak == pytest.approx(length / C, abs=1e-3 / raw.fs)
    expected = target.amplitude * np.exp(-2j * np.pi * np.mod(FC * length / C, 1.0))
    assert abs(value) == pytest.approx(abs(target.amplitude), rel=1e-3)
    assert abs(np.angle(value / expected, deg=True)) < 0.1


def test_matched_filter_peak_and_width():
    """The plain matched filter keeps the unit-peak normalisation and the sinc width within 2 %."""
    target = PointTarget((0.0, 0.0, 0.0), 0.7)
    raw = scene(n_pulses=1, compressed=False, targets=[target])
    out = range_compress(raw, method="matched")
    _, value, width, _ = measure(out.data[0], raw.fs)
    assert abs(value) == pytest.approx(0.7, rel=0.01)
    assert width * C / 2 == pytest.approx(0.886 * C / (2 * B), rel=0.02)
    assert out.metadata["range_compression"]["method"] == "matched"


# ============================================================================ weighting compressed data
@pytest.mark.parametrize("window, params", WINDOWS, ids=IDS)
def test_apply_range_window_matches_windowed_synthesis(window, params):
    rect = scene(compressed=True)
    truth = scene(compressed=True, window=window, params=params)
    out = apply_range_window(rect, window, **params)
    assert nrmse_db(out.data, truth.data) < -60.0
    assert np.array_equal(out.fast_time, rect.fast_time) and out.range_compressed


def test_rect_window_is_the_identity():
    rect = scene(compressed=True)
    assert nrmse_db(apply_range_window(rect, "rect").data, rect.data) < -120.0


# ============================================================================ errors
def test_rejects_wrong_inputs():
    raw = scene(n_pulses=2, compressed=False)
    compressed = scene(n_pulses=2, compressed=True)
    with pytest.raises(ValueError, match="range_compressed is True"):
        range_compress(compressed)
    with pytest.raises(ValueError, match="range-compressed data"):
        apply_range_window(raw, "hamming")
    with pytest.raises(ValueError, match="unknown window"):
        range_compress(raw, "gauss")
    with pytest.raises(ValueError, match="method"):
        range_compress(raw, method="wiener")
    with pytest.raises(ValueError, match="accuracy_db"):
        range_compress(raw, accuracy_db=0.0)
    import dataclasses
    with pytest.raises(ValueError, match="swept band"):
        range_compress(dataclasses.replace(raw, chirp_rate=raw.chirp_rate / 2))
