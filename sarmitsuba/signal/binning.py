"""From the tracer's band-limited spectra to raw data (docs/design.md section 5, docs/physics.md (S1), (S2)).

Per pulse ``p`` the tracer returns the spectrum of the term sum
``sum_i a_i (1 + f / fc)^m_i exp(-j 2 pi f (tau_i - t0)) exp(-j k (L_i - L_ref,p))`` over the coarse
sampling band, on a padded grid (:func:`sarmitsuba.tracing.deposit.fast_time.reduce_deposit`). This stage

1. restores the reference carrier phase ``exp(-j k L_ref,p)``, formed in float64 and reduced
   mod 2 pi before the cast (eq. (S1));
2. band-limits it to the transmitted band ``|f| <= B / 2`` with a unit-peak compressed pulse
   ``p_r(t) = sinc(B t)`` (rect spectrum; range compression), or multiplies it by the chirp's
   spectrum and the receiver's response (chirped raw echoes; :mod:`sarmitsuba.signal.signal_model`);
3. keeps the window's samples.

The result is ``sum_i a_i p_r(tau - L_i / c) exp(-j 2 pi fc L_i / c)`` sampled at ``t0 + n / fs``:
the RawData contract of docs/design.md section 3. The ``exact`` kernel's terms are evaluated
directly instead (:func:`exact_compress`).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import fft as sp_fft

from ..core.constants import SPEED_OF_LIGHT
from ..tracing.deposit.fast_time import SPECTRAL_ORDERS, order_factor
from ..core.radar import ParameterError, RadarParameters
from ..core.geometry import AcquisitionGeometry
from ..core.raw import RawData, RawDataError
from .signal_model import received_chirp_spectrum
from ..tracing.driver.trace import PathList, TraceResult
from ..scene.trace_inputs import FastTimeWindow

__all__ = ["check_samples", "MAX_SAMPLE", "compressed_pulse_spectrum", "exact_compress", "range_compress", "range_compress_adjoint", "raw_data_adjoint",
           "reference_carrier_phase", "to_raw_data"]

#: Pulses filtered per block in :func:`range_compress`. Its temporaries are a few
#: [block, n_pad] arrays (the complex128 filter-times-phase the largest: 128 MB at
#: n_pad = 32768), so the block bounds memory whatever the number of pulses, while each
#: threaded inverse FFT call still gets many rows (a memory/throughput choice, from the code).
PULSE_BLOCK = 256
#: Output samples (kernel lanes) per Dr.Jit launch of the ``exact`` kernel. A lane carries about
#: 56 bytes (float64 sample and two float64 sums, uint32 indices, its complex128 output row
#: entry), so 2^21 lanes bound a launch to ~120 MB, and are still thousands per core (a
#: memory/throughput choice, derived from the code).
EXACT_BLOCK_LANES = 1 << 21
#: Below this ``|x|`` the kernel takes ``sin(x) / x = 1``: the neglected ``x^2 / 6 < 2e-9`` is far
#: below float32's resolution (6e-8), and it avoids the 0 / 0 at ``x = 0``.
SINC_SMALL_ARGUMENT = 1e-4


def compressed_pulse_spectrum(n: int, fs: float, bandwidth: float) -> np.ndarray:
    """Range-compression filter of an ``n``-point coarse spectrum, float64 [n] in FFT order:
    ``H(f) = rect(f / B) / g`` with ``g = sum(rect) / n``, which gives the compressed pulse a
    unit peak (eq. (S2))."""
    f = sp_fft.fftfreq(n, d=1.0 / fs)
    band = (np.abs(f) <= 0.5 * bandwidth).astype(np.float64)
    return band / (band.sum() / n)


def range_compress(spectrum: np.ndarray, reference_length: np.ndarray, window: FastTimeWindow,
                   frequency: float, bandwidth: float, block: int = PULSE_BLOCK,
                   chirp: tuple[float, float] | None = None) -> np.ndarray:
    """Samples of the window from the tracer's padded spectra.

    Parameters
    ----------
    spectrum : complex64 [n_pulses, n_pad]
        :attr:`TraceResult.spectrum` (or one bounce order's), FFT order, ``n_pad >= 2 n_samples``:
        filtering never wraps around.
    reference_length : float64 [n_pulses], m
    window : FastTimeWindow
    frequency, bandwidth : float, Hz
    block : int
        Pulses filtered at once (bounds memory).
    chirp : (pulse_length [s], chirp_rate [Hz/s]), optional
        Produce chirped echoes instead, as a receiver records them: the spectrum times
        ``fs S(f) R(f)``, with ``S`` the chirp's exact spectrum and ``R`` the receiver's
        anti-aliasing response (flat over the band, raised-cosine roll-off to ``fs / 2``;
        :func:`sarmitsuba.signal.signal_model.received_chirp_spectrum`).
        :func:`sarmitsuba.focus.range_compression.range_compress` inverts it exactly.

    Returns
    -------
    complex64 [n_pulses, n_samples]
    """
    phase = reference_carrier_phase(reference_length, frequency)
    n, n_pad = window.n_samples, spectrum.shape[1]
    if chirp is None:
        filt = compressed_pulse_spectrum(n_pad, window.fs, bandwidth)
    else:
        f = sp_fft.fftfreq(n_pad, d=1.0 / window.fs)
        filt = received_chirp_spectrum(f, window.fs, bandwidth, *chirp)
    out = np.empty((spectrum.shape[0], n), np.complex64)
    for p0 in range(0, spectrum.shape[0], block):
        rows = slice(p0, p0 + block)
        filtered = spectrum[rows] * (filt[None, :] * np.exp(1j * phase[rows])[:, None]).astype(np.complex64)
        out[rows] = sp_fft.ifft(filtered, axis=1, workers=-1)[:, :n]
    return out


def reference_carrier_phase(reference_length: np.ndarray, frequency: float) -> np.ndarray:
    """The reference carrier phase ``-k L_ref`` of each pulse, formed in float64 and reduced mod
    2 pi before any cast, eq. (S1): float64 [n_pulses], rad in [0, 2 pi), from ``reference_length``
    float64 [n_pulses] in m and the carrier ``frequency`` in Hz."""
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    return np.mod(-k * reference_length, 2.0 * math.pi)


def exact_compress(paths: PathList, n_pulses: int, reference_length: np.ndarray, window: FastTimeWindow,
                   frequency: float, bandwidth: float, block_lanes: int = EXACT_BLOCK_LANES) -> np.ndarray:
    """Range-compressed samples evaluated term by term: the ``exact`` range kernel.

    ``s_p[n] = exp(-j k L_ref,p) sum_i v_i sinc(B (n - x_i) / fs)`` with ``v_i`` the term's
    value relative to the reference phase and ``x_i`` its delay in samples
    (docs/physics.md (D4)): the unit-peak, rect-spectrum compressed pulse of
    :func:`compressed_pulse_spectrum`, without a deposit grid. Every term contributes to
    every sample (its sinc tails included), so the cost is terms x samples: a Dr.Jit kernel
    with one lane per output sample looping over the terms of its pulse, summing in
    float64. Terms of spectral order ``m != 0`` are summed apart and their samples' spectrum
    multiplied by ``(1 + f / fc)^m`` (eq. (PO3)).

    Parameters
    ----------
    paths : PathList
    n_pulses : int
    reference_length : float64 [n_pulses], m
    window : FastTimeWindow
    frequency, bandwidth : float, Hz
    block_lanes : int
        Output samples per kernel launch (bounds memory).

    Returns
    -------
    complex64 [n_pulses, n_samples]
    """
    import drjit as dr
    import mitsuba as mi

    out = np.zeros((n_pulses, window.n_samples), np.complex128)
    for m in SPECTRAL_ORDERS:
        keep = paths.spectral == m
        if not np.any(keep):
            continue
        part = _sinc_sum(paths.pulse[keep], paths.position[keep], paths.value[keep], n_pulses, window,
                         bandwidth / window.fs, block_lanes)
        if m != 0:
            n_pad = 2 * window.n_samples
            f = sp_fft.fftfreq(n_pad, d=1.0 / window.fs)
            part = sp_fft.ifft(sp_fft.fft(part, n=n_pad, axis=1) * order_factor(f, frequency, m),
                               axis=1)[:, :window.n_samples]
        out += part
    phase = reference_carrier_phase(reference_length, frequency)
    return (out * np.exp(1j * phase)[:, None]).astype(np.complex64)


def _sinc_sum(pulse: np.ndarray, position: np.ndarray, values: np.ndarray, n_pulses: int, window: FastTimeWindow,
              ratio: float, block_lanes: int) -> np.ndarray:
    """``sum_i v_i sinc(ratio (n - x_i))`` per pulse and sample, complex128 [n_pulses, n_samples] (Dr.Jit, float64 sums)."""
    import drjit as dr
    import mitsuba as mi

    n = window.n_samples
    order = np.argsort(pulse, kind="stable")
    position, value = position[order], values[order]
    start = np.searchsorted(pulse[order], np.arange(n_pulses + 1)).astype(np.uint32)
    pos = mi.Float64(position)
    v_re, v_im = mi.Float(value.real.astype(np.float32)), mi.Float(value.imag.astype(np.float32))
    out = np.zeros((n_pulses, n), np.complex128)
    per_block = max(1, block_lanes // n)
    for p0 in range(0, n_pulses, per_block):
        p1 = min(n_pulses, p0 + per_block)
        lane = dr.arange(mi.UInt32, (p1 - p0) * n)
        pulse = lane // n
        sample = mi.Float64(lane - pulse * n)
        k = dr.gather(mi.UInt32, mi.UInt32(start[p0:p1]), pulse)
        end = dr.gather(mi.UInt32, mi.UInt32(start[p0 + 1:p1 + 1]), pulse)

        def body(k, acc_re, acc_im):
            x = mi.Float((math.pi * ratio) * (sample - dr.gather(mi.Float64, pos, k)))
            w = mi.Float64(dr.select(dr.abs(x) < SINC_SMALL_ARGUMENT, 1.0, dr.sin(x) / x))
            return (k + 1, acc_re + w * mi.Float64(dr.gather(mi.Float, v_re, k)),
                    acc_im + w * mi.Float64(dr.gather(mi.Float, v_im, k)))

        _, acc_re, acc_im = dr.while_loop((k, mi.Float64(0.0), mi.Float64(0.0)), lambda k, *_: k < end, body,
                                          label="exact_range_kernel")
        out[p0:p1] = (acc_re.numpy() + 1j * acc_im.numpy()).reshape(p1 - p0, n)
    return out


def range_compress_adjoint(samples: np.ndarray, reference_length: np.ndarray, window: FastTimeWindow,
                           frequency: float, bandwidth: float, n_pad: int,
                           chirp: tuple[float, float] | None = None) -> np.ndarray:
    """The adjoint of :func:`range_compress` : samples complex [n_pulses, n_samples]
    back to padded spectra complex128 [n_pulses, n_pad], ``<range_compress(S), y> = <S,
    range_compress_adjoint(y)>``: zero-padded to ``n_pad``, ``fft / n_pad`` (the inverse FFT's
    adjoint), times the conjugate of each pulse's filter and carrier phase."""
    phase = reference_carrier_phase(reference_length, frequency)
    if chirp is None:
        filt = compressed_pulse_spectrum(n_pad, window.fs, bandwidth)
    else:
        filt = received_chirp_spectrum(sp_fft.fftfreq(n_pad, d=1.0 / window.fs), window.fs, bandwidth, *chirp)
    padded = np.zeros((samples.shape[0], n_pad), np.complex128)
    padded[:, :samples.shape[1]] = samples
    factor = (filt[None, :] * np.exp(1j * phase)[:, None]).astype(np.complex64).astype(np.complex128)
    return sp_fft.fft(padded, axis=1) / n_pad * np.conj(factor)


def raw_data_adjoint(samples_gradient: np.ndarray, reference_length: np.ndarray, n_pad: int,
                     window: FastTimeWindow, params: RadarParameters) -> np.ndarray:
    """The adjoint of :func:`to_raw_data`'s map from the trace's spectra (``n_pad`` long, FFT
    order) to the samples, noise aside: the gradient of a real loss with respect to the samples,
    ``dL/dRe + j dL/dIm`` complex [n_pulses, n_samples], to the spectra's, complex128
    [n_pulses, n_pad] (the radar equation's real scale, then :func:`range_compress_adjoint`)."""
    from ..scene.radar_equation import radar_equation
    gradient = np.asarray(samples_gradient, np.complex128)
    equation = radar_equation(params)
    if equation is not None:
        gradient = gradient * equation.amplitude_scale(0.5 * np.asarray(reference_length, float))[:, None]
    chirp = (params.pulse_length, params.chirp_rate) if params.output == "raw" else None
    return range_compress_adjoint(gradient, reference_length, window, params.frequency, params.bandwidth, n_pad, chirp)


#: The largest sample magnitude the raw data may hold: ``sqrt`` of float32's largest value
#: (1.8e19), so that a sample's power ``|x|^2``, which images and energies take in float32, is
#: finite. A physical render stays many decades below (unit-free amplitudes are RCS-like, sqrt(m^2);
#: absolute radiometry gives sqrt(W)).
MAX_SAMPLE = float(np.sqrt(np.finfo(np.float32).max))


def check_samples(data: np.ndarray, metadata: dict) -> None:
    """Raise RawDataError when the traced samples are not finite or exceed :data:`MAX_SAMPLE`
    (a setting outside its approximation's validity, or a tracer fault), before anything is written."""
    magnitude = np.abs(data)
    bad = ~(magnitude <= MAX_SAMPLE)                 # NaN, Inf and overflow alike
    if not bad.any():
        return
    pulse, sample = np.unravel_index(int(np.argmax(bad)), data.shape)
    settings = metadata.get("settings", {}) if isinstance(metadata, dict) else {}
    given = ", ".join(f"{k} = {settings[k]}" for k in ("patch_size", "ray_spacing", "oversample", "pulses_per_trace",
                                                       "max_depth") if k in settings)
    raise RawDataError(
        f"the traced raw data have {int(bad.sum())} samples that are not finite or exceed {MAX_SAMPLE:.3g} "
        f"(their power would overflow float32), the first at (pulse {pulse}, sample {sample}): the render is refused "
        f"and nothing is written (integrator settings: {given or 'none recorded'}); set patch_size, ray_spacing and "
        "pulses_per_trace to 0 (automatic, within their approximations' validity) and report the scene if it persists")


def to_raw_data(contributions: "np.ndarray | PathList", result: TraceResult, window: FastTimeWindow,
                params: RadarParameters, geometry: AcquisitionGeometry, metadata: dict,
                noise_seed: int | None = None) -> RawData:
    """Samples of ``result.contributions(order)`` (spectra or terms) as :class:`RawData`.

    With absolute radiometry (sensor ``transmit_power``) the samples are scaled to sqrt(W) by the
    radar equation at each pulse's reference range (the tracer has applied each return's own
    spreading ``R_ref^2 / (s R_rx)``), and thermal noise of power ``k T B F`` per sample is added
    when the sensor has noise parameters and ``noise_seed`` is given (docs/physics.md (R1)-(R4)).
    """
    from ..scene.radar_equation import radar_equation
    from .radiometry import thermal_noise
    with np.errstate(over="ignore", invalid="ignore"):        # refused below, with the reason
        chirped = params.output == "raw"
        if isinstance(contributions, PathList):
            if chirped:
                raise ParameterError("range_kernel = 'exact' evaluates range-compressed samples; "
                                     "use it with sensor output = 'compressed' (or range_kernel linear|sinc for raw)")
            data = exact_compress(contributions, len(result.reference_length), result.reference_length, window,
                                  params.frequency, params.bandwidth)
        else:
            data = range_compress(contributions, result.reference_length, window, params.frequency, params.bandwidth,
                                  chirp=(params.pulse_length, params.chirp_rate) if chirped else None)
        equation = radar_equation(params)
        if equation is not None:
            scale = equation.amplitude_scale(0.5 * result.reference_length)        # float64 [n_pulses]
            data = (data * scale[:, None]).astype(np.complex64)
            metadata = {**metadata, "units": "sqrt(W) at the receiver, unit-energy matched filter"}
            if equation.noise_power > 0 and noise_seed is not None:
                data += thermal_noise(data.shape, equation.noise_power, params.sampling_rate, params.bandwidth,
                                      noise_seed)
                metadata = {**metadata, "noise_power_w": equation.noise_power}
    check_samples(data, metadata)
    return RawData(
        data=data, fast_time=window.fast_time, pulse_time=geometry.pulse_time.copy(),
        tx_position=geometry.positions.copy(), rx_position=geometry.rx_positions.copy(),
        velocity=geometry.velocity.copy(), fc=params.frequency, bandwidth=params.bandwidth,
        chirp_rate=params.chirp_rate, pulse_length=params.pulse_length, fs=params.sampling_rate,
        prf=params.prf, range_compressed=not chirped, metadata=metadata,
        rx_time=None if geometry.rx_time is None else geometry.rx_time.copy(),
        **_nominal(geometry))


def _nominal(geometry: AcquisitionGeometry) -> dict:
    """The nominal track's RawData fields (motion errors, docs/physics.md (J4)), or none."""
    if geometry.nominal_positions is None:
        return {}
    return dict(nominal_tx_position=geometry.nominal_positions.copy(),
                nominal_rx_position=geometry.nominal_rx_positions.copy(),
                nominal_velocity=geometry.nominal_velocity.copy())
