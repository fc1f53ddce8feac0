"""The focusers' adjoints (issue 57): dot-product tests, a dense second method, and the forward
map against the independent float64 reference (``numpy.interp``).

Each test names the plausible bug it catches.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.core.raw import RawData
from sarmitsuba.focus import ImageGrid, backproject_reference
from sarmitsuba.focus.linear import backprojection_operator, inner
from sarmitsuba.focus.range_lines import fft_upsample, fft_upsample_adjoint

FC, B = 9.6e9, 150e6
#: The dot-product test's tolerance (the issue asks 1e-6 in float64; the pairs hold to rounding).
DOT_TOL = 1e-9


def _random(shape, seed):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


def _acquisition(*, n_pulses=25, spacing=0.6, bistatic=False, continuous=False, fs_factor=1.2,
                 altitude=3000.0, offset=4000.0) -> RawData:
    """A straight track along +x looking toward -y at a scene at the origin; random data (the
    geometry is what the operator depends on)."""
    xs = (np.arange(n_pulses) - (n_pulses - 1) / 2) * spacing
    tx = np.stack([xs, np.full_like(xs, offset), np.full_like(xs, altitude)], axis=1)
    rx = tx + (np.array([0.0, 40.0, -15.0]) if bistatic else 0.0)
    near = np.linalg.norm(tx[0]) + np.linalg.norm(rx[0]) - 30.0
    fs = fs_factor * B
    n_samples = int(60.0 / C * fs) + 1
    speed = 100.0
    pulse_time = xs / speed
    raw = RawData(data=_random((n_pulses, n_samples), 1).astype(np.complex64),
                  fast_time=near / C + np.arange(n_samples) / fs, pulse_time=pulse_time,
                  tx_position=tx, rx_position=rx, velocity=np.tile([speed, 0.0, 0.0], (n_pulses, 1)),
                  fc=FC, bandwidth=B, chirp_rate=B / 10e-6, pulse_length=10e-6, fs=fs, prf=speed / spacing,
                  range_compressed=True, metadata={"scene": "adjoint test"})
    if continuous:
        raw = dataclasses.replace(raw, rx_time=pulse_time + 2.0 * np.linalg.norm(tx[0]) / C)
    return raw


def _grid(half=3.0, spacing=0.3) -> ImageGrid:
    return ImageGrid.ground((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, -1.0, -1.0), 2 * half, 2 * half, spacing)


CASES = {
    "spotlight": dict(),
    "spotlight-hamming": dict(window_azimuth="hamming"),
    "beam-taylor-pattern": dict(azimuth_beamwidth=0.4, window_azimuth="taylor",
                                azimuth_pattern=1 / np.sin(np.radians(0.2))),
    "squint-kaiser": dict(azimuth_beamwidth=0.4, squint=0.1, window_azimuth=("kaiser", {"beta": 3.0})),
}


@pytest.mark.parametrize("n", [7, 40, 57])
@pytest.mark.parametrize("factor", [1, 3, 8])
def test_fft_upsample_adjoint_passes_the_dot_product_test(n, factor):
    """Catches: the split Nyquist bin taken from one end only, a missing 1/N of the inverse FFT,
    the zero-padded forward FFT transposed as an FFT (a conjugate lost)."""
    x, y = _random(n, 2), _random((n - 1) * factor + 1, 3)
    left, right = inner(fft_upsample(x, factor), y), inner(x, fft_upsample_adjoint(y, n, factor))
    assert abs(left - right) <= DOT_TOL * abs(left)


def test_fft_upsample_adjoint_is_the_dense_matrix_transpose():
    """A second method: the upsampler's matrix built column by column, conjugate-transposed."""
    n, factor = 12, 4
    matrix = np.stack([fft_upsample(np.eye(n, dtype=np.complex128)[k], factor) for k in range(n)], axis=1)
    y = _random(matrix.shape[0], 4)
    np.testing.assert_allclose(fft_upsample_adjoint(y, n, factor), matrix.conj().T @ y, rtol=0, atol=1e-12)


@pytest.mark.parametrize("case", list(CASES))
def test_forward_is_the_reference_backprojection(case):
    """The operator's own interpolation against ``backproject_reference``'s ``numpy.interp``.
    Catches: the padded line's first sample off by one (a delay of one fine sample), the carrier's
    sign, the normalisation left out or per pixel instead of per column."""
    raw, grid = _acquisition(), _grid()
    operator = backprojection_operator(raw, grid, oversample=4, **CASES[case])
    image = operator.forward(raw.data)
    reference = backproject_reference(raw, grid, oversample=4, **CASES[case]).data
    assert np.max(np.abs(image - reference)) <= 2e-6 * np.max(np.abs(reference))


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("motion", ["stop-and-hop", "bistatic", "continuous"])
def test_backprojection_adjoint_passes_the_dot_product_test(case, motion):
    """``<F x, y> = <x, F^H y>`` in float64 to 1e-9. Catches: the carrier's conjugate missing in
    the adjoint (``exp(+j ..)`` instead of ``exp(-j ..)``), the interpolation weights swapped
    between the two fine samples, the normalisation applied twice or not at all, the upsampler's
    adjoint replaced by a decimation."""
    raw = _acquisition(bistatic=motion == "bistatic", continuous=motion == "continuous")
    operator = backprojection_operator(raw, _grid(), oversample=4, **CASES[case])
    x, y = _random(raw.data.shape, 5), _random(operator.grid.shape, 6)
    left, right = inner(operator.forward(x), y), inner(x, operator.adjoint(y))
    assert abs(left) > 0
    assert abs(left - right) <= DOT_TOL * abs(left)


def test_backprojection_adjoint_is_the_dense_matrix_transpose():
    """A second method: the operator's matrix from the forward map on unit vectors. Catches the
    same bugs as the dot-product test, entry by entry."""
    raw = _acquisition(n_pulses=4, spacing=2.0)
    raw = dataclasses.replace(raw, data=raw.data[:, :24], fast_time=raw.fast_time[:24])
    grid = _grid(half=1.0, spacing=0.5)
    operator = backprojection_operator(raw, grid, oversample=2)
    n = raw.data.size
    columns = [operator.forward(np.eye(n, dtype=np.complex128)[k].reshape(raw.data.shape)).reshape(-1)
               for k in range(n)]
    matrix = np.stack(columns, axis=1)
    assert np.count_nonzero(np.abs(matrix) > 0) > 0.05 * matrix.size          # the pixels see the echoes
    y = _random(grid.shape, 7)
    np.testing.assert_allclose(operator.adjoint(y).reshape(-1), matrix.conj().T @ y.reshape(-1),
                               rtol=0, atol=1e-12 * np.abs(matrix).max() * np.abs(y).max() * matrix.shape[0])


def test_a_point_target_backprojects_to_its_amplitude_and_back():
    """Closed form: the echo of a point of amplitude ``a`` focuses to ``a`` at the point (eq. (S3)),
    and the adjoint of a delta at the point is the conjugate-phase echo pattern: its inner product
    with the data is ``conj`` of the image value there. Catches a forward map scaled by the pulse
    count twice, or an adjoint that returns the echo itself instead of its matched filter."""
    raw = _acquisition(n_pulses=41, spacing=0.5, fs_factor=2.0)
    grid = _grid(half=1.0, spacing=0.25)
    point = grid.positions()[4, 4]
    amplitude = 0.8 * np.exp(0.4j)
    lengths = np.linalg.norm(raw.tx_position - point, axis=1) + np.linalg.norm(raw.rx_position - point, axis=1)
    echo = amplitude * np.sinc(B * (raw.fast_time[None, :] - lengths[:, None] / C)) \
        * np.exp(-2j * np.pi * np.mod(FC * lengths / C, 1.0))[:, None]
    operator = backprojection_operator(raw, grid, oversample=8)
    image = operator.forward(echo)
    assert abs(image[4, 4]) == pytest.approx(abs(amplitude), rel=0.02)
    assert abs(np.angle(image[4, 4] / amplitude)) < np.radians(2.0)
    delta = np.zeros(grid.shape, np.complex128)
    delta[4, 4] = 1.0
    assert inner(operator.adjoint(delta), echo) == pytest.approx(image[4, 4], rel=1e-9)


def test_wrong_shapes_are_named():
    raw, grid = _acquisition(n_pulses=5), _grid(half=1.0, spacing=0.5)
    operator = backprojection_operator(raw, grid, oversample=2)
    with pytest.raises(ValueError, match="data shape"):
        operator.forward(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="image shape"):
        operator.adjoint(np.zeros((3, 3)))



# ============================================================================ fast factorised backprojection
def _points_echo(raw: RawData, grid: ImageGrid, pixels=((5, 6), (12, 14), (20, 18)),
                 amplitudes=(1.0, 0.7j, 0.5 * np.exp(-1j))) -> np.ndarray:
    """Echoes (complex128 [n_pulses, n_samples], eq. (S1)) of point targets at pixels of ``grid``."""
    echo = np.zeros(raw.data.shape, np.complex128)
    for (i, j), a in zip(pixels, amplitudes):
        point = grid.positions()[i, j]
        lengths = np.linalg.norm(raw.tx_position - point, axis=1) + np.linalg.norm(raw.rx_position - point, axis=1)
        echo += a * np.sinc(B * (raw.fast_time[None, :] - lengths[:, None] / C)) \
            * np.exp(-2j * np.pi * np.mod(FC * lengths / C, 1.0))[:, None]
    return echo


def _ffbp_case(case: str, continuous: bool = False):
    from sarmitsuba.focus.ffbp_linear import ffbp_operator
    raw = _acquisition(n_pulses=64, spacing=0.3, fs_factor=2.0, continuous=continuous)
    grid = _grid(half=3.0, spacing=0.25)
    raw = dataclasses.replace(raw, data=_points_echo(raw, grid).astype(np.complex64))
    return raw, grid, ffbp_operator(raw, grid, oversample=4, subaperture=16, **CASES[case])


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    return float(20.0 * np.log10(np.linalg.norm(a - b) / np.linalg.norm(b)))


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("motion", ["stop-and-hop", "continuous"])
def test_ffbp_adjoint_passes_the_dot_product_test(case, motion):
    """``<F x, y> = <x, F^H y>`` in float64 to 1e-9 for fast factorised backprojection. Catches:
    the pixels' carrier ``exp(+j kappa |x - c|)`` or the polar images' demodulation not conjugated
    in the adjoint, the s-prefilter applied untransposed (it is not symmetric: its mirror start),
    the range upsampler's matrix not conjugate-transposed, a sub-aperture's pulses scattered back
    onto another's lines."""
    raw, grid, operator = _ffbp_case(case, continuous=motion == "continuous")
    assert len(operator.maps) == 4
    x, y = _random(raw.data.shape, 30), _random(grid.shape, 31)
    left, right = inner(operator.forward(x), y), inner(x, operator.adjoint(y))
    assert abs(left) > 0
    assert abs(left - right) <= DOT_TOL * abs(left)


@pytest.mark.parametrize("case", list(CASES))
def test_ffbp_operator_is_the_fast_focuser_and_focuses_points(case):
    """The float64 map against ``ffbp`` itself (complex64, tabulated delays, weights and spline
    weights; -64 dB apart when right) and against direct backprojection (an independent method:
    FFBP's own interpolation error, -46 to -48 dB, or the same -25 dB as ``ffbp`` where its coarse
    normalisation differs with a tapered beam). Catches: the spline taps one sample off in ``s`` or
    ``r``, the carrier's sign, a polar sample's demodulation left out, the normalisation."""
    from sarmitsuba.focus import backproject, ffbp
    raw, grid, operator = _ffbp_case(case)
    image = operator.forward(raw.data)
    fast = ffbp(raw, grid, oversample=4, subaperture=16, **CASES[case]).data
    direct = backproject(raw, grid, oversample=4, **CASES[case]).data
    assert _nrmse_db(image, fast) < -55.0
    assert _nrmse_db(image, direct) < _nrmse_db(fast, direct) + 1.0
    assert _nrmse_db(image, direct) < (-22.0 if "pattern" in case else -40.0)


def test_ffbp_point_target_focuses_to_its_amplitude():
    """Closed form (eq. (S3)): a lone point of amplitude ``a`` focuses to ``a`` at its pixel, without
    a beam (every pulse sees it, normalised by the pulse count). Catches a normalisation applied
    twice, a sub-aperture dropped from the sum."""
    _, grid, operator = _ffbp_case("spotlight")
    for pixel, a in (((12, 14), 0.7j), ((5, 20), 0.4 * np.exp(2j))):
        image = operator.forward(_points_echo(operator.raw, grid, [pixel], [a]))
        assert abs(image[pixel]) == pytest.approx(abs(a), rel=0.02)
        assert abs(np.angle(image[pixel] / a)) < np.radians(2.0)


def test_ffbp_operator_refuses_what_ffbp_refuses():
    from sarmitsuba.focus.ffbp import GeometryNotSupported
    from sarmitsuba.focus.ffbp_linear import ffbp_operator
    with pytest.raises(GeometryNotSupported, match="monostatic"):
        ffbp_operator(_acquisition(n_pulses=8, bistatic=True), _grid(half=1.0, spacing=0.5))
    with pytest.raises(ValueError, match="subaperture"):
        ffbp_operator(_acquisition(n_pulses=8), _grid(half=1.0, spacing=0.5), subaperture=0)

# ============================================================================ omega-K
def _stripmap(name: str, n_pulses: int = 128, n_samples: int = 96) -> RawData:
    from sarmitsuba.analysis.reference_cases import AIRBORNE_X, CW_HIGH, simulate_case
    case = dataclasses.replace({"airborne": AIRBORNE_X, "squinted": CW_HIGH}[name], n_pulses=n_pulses,
                               n_samples=n_samples)
    return simulate_case(case)


#: FFT focuser set-ups: name -> (operator builder, fast focuser, data, options), by import path.
FFT_CASES = {
    "omegak-airborne-rect": ("omega_k", "airborne", dict()),
    "omegak-airborne-taylor-6taps": ("omega_k", "airborne", dict(window_range="taylor", window_azimuth="taylor", taps=6)),
    "omegak-squinted-kaiser-band": ("omega_k", "squinted", dict(window_azimuth=("kaiser", {"beta": 2.5}),
                                                               doppler_bandwidth=80.0, oversample=1.25)),
    "rda-airborne-rect": ("range_doppler", "airborne", dict()),
    "rda-airborne-taylor-src2d": ("range_doppler", "airborne", dict(window_range="taylor", window_azimuth="taylor",
                                                                   src="2d")),
    "rda-squinted-src-range-band": ("range_doppler", "squinted", dict(src="range", doppler_bandwidth=80.0, upsample=3,
                                                                     taps=6)),
}


def _fft_case(case: str):
    """(raw data, float64 operator, fast focuser's image) of an FFT focuser set-up."""
    from sarmitsuba.focus import linear
    from sarmitsuba.focus.omegak import omega_k
    from sarmitsuba.focus.rda import range_doppler
    focuser, name, options = FFT_CASES[case]
    raw = _stripmap(name)
    operator = getattr(linear, f"{focuser}_operator")(raw, **options)
    fast = {"omega_k": omega_k, "range_doppler": range_doppler}[focuser]
    return raw, operator, lambda: fast(raw, workers=1, **options).data


@pytest.mark.parametrize("case", list(FFT_CASES))
def test_fft_focuser_adjoint_passes_the_dot_product_test(case):
    """``<F x, y> = <x, F^H y>`` in float64 to 1e-9, omega-K and range-Doppler. Catches: a forward
    FFT's adjoint taken as an FFT (not ``N`` times the inverse), an inverse FFT's adjoint without
    its 1 / N, the Stolt kernel's scatter on the wrong wrapped bin, the factors', range filter's or
    SRC's conjugate missing, the upsampling's spectrum halves swapped, the crop to the data's range
    samples not undone by zero-padding."""
    raw, operator, _ = _fft_case(case)
    x, y = _random(raw.data.shape, 8), _random(raw.data.shape, 9)
    left, right = inner(operator.forward(x), y), inner(x, operator.adjoint(y))
    assert abs(left) > 0
    assert abs(left - right) <= DOT_TOL * abs(left)


@pytest.mark.parametrize("case", list(FFT_CASES))
def test_fft_operator_is_the_fast_focuser(case):
    """The float64 map (exact Stolt or RCMC kernel) against ``omega_k`` or ``range_doppler`` itself
    (complex64, tabulated kernels) on point targets: a second implementation of the same steps.
    Catches a missing step (the deconvolution, the Jacobian, the fast-time origin), a phase's
    sign, RCMC taps beyond a row's ends read as its edge samples instead of zeros."""
    raw, operator, fast = _fft_case(case)
    image, reference = operator.forward(raw.data), fast()
    assert np.max(np.abs(image - reference)) <= 1e-3 * np.max(np.abs(reference))
    assert np.max(np.abs(reference)) > 0.1 * np.max(np.abs(raw.data))


# ============================================================================ the binning's adjoints
@pytest.mark.parametrize("kernel", ["linear", "sinc"])
def test_reduce_deposit_adjoint_passes_the_dot_product_test(kernel):
    """``<R h, y> = <h, R^H y>`` for the fine histogram's reduction to spectra (float32 inside:
    to 1e-5). Catches the kept bins' negative half put back at the wrong end of the transform,
    the zero-padded FFT transposed as an FFT."""
    from sarmitsuba.tracing.deposit.fast_time import SPECTRAL_ORDERS, reduce_deposit, reduce_deposit_adjoint
    n_pulses, n_fine, oversample, n_pad, fs = 5, 96, 4, 40, 180e6
    h = _random((len(SPECTRAL_ORDERS), n_pulses, n_fine), 20).astype(np.complex64)
    y = _random((n_pulses, n_pad), 21)
    left = inner(reduce_deposit(h, fs, oversample, FC, kernel, n_pad), y)
    right = inner(h, reduce_deposit_adjoint(y, n_fine, fs, oversample, FC, kernel))
    assert abs(left - right) <= 1e-5 * abs(left)


@pytest.mark.parametrize("output", ["compressed", "raw"])
def test_range_compress_adjoint_passes_the_dot_product_test(output):
    """``<C s, y> = <s, C^H y>`` for the spectra's range compression to samples (compressed
    pulses, or chirped echoes). Catches the carrier phase not conjugated, the inverse FFT's
    adjoint without its 1 / N, the crop to the window not undone by zero-padding."""
    from types import SimpleNamespace
    from sarmitsuba.signal.binning import range_compress, range_compress_adjoint
    n_pulses, n_pad, n = 4, 64, 25
    window = SimpleNamespace(n_samples=n, fs=180e6)
    lengths = 2000.0 + 0.37 * np.arange(n_pulses)
    chirp = (10e-6, B / 10e-6) if output == "raw" else None
    s, y = _random((n_pulses, n_pad), 22).astype(np.complex64), _random((n_pulses, n), 23)
    left = inner(range_compress(s, lengths, window, FC, B, chirp=chirp), y)
    right = inner(s, range_compress_adjoint(y, lengths, window, FC, B, n_pad, chirp))
    assert abs(left - right) <= 1e-5 * abs(left)
