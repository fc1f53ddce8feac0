"""From the tracer's fine fast-time deposit to range-compressed raw data (DESIGN.md section 5).

Per pulse ``p`` the tracer deposits ``sum_i a_i exp(-j k (L_i - L_ref,p))`` on a fine grid of
step ``1 / (oversample fs)``. This stage

1. restores the reference carrier phase ``exp(-j k L_ref,p)``, formed in float64 and reduced
   mod 2 pi before the cast (eq. (S1) of ``docs/physics.md``);
2. band-limits the deposit to the transmitted band ``|f| <= B / 2`` with a unit-peak compressed
   pulse ``p_r(t) = sinc(B t)`` (rect spectrum), dividing out the deposit kernel's spectral
   droop (``sinc^2(f / fs_fine)`` for linear splatting);
3. keeps the spectral bins of the coarse grid, i.e. decimates to ``fs`` exactly.

The result is ``sum_i a_i p_r(tau - L_i / c) exp(-j 2 pi fc L_i / c)`` sampled at
``t0 + n / fs``: the RawData contract of DESIGN.md section 3.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import fft as sp_fft

from .radar import AcquisitionGeometry, ParameterError, RadarParameters
from .raw import RawData
from .trace import FastTimeWindow, PathList, TraceResult

__all__ = ["compressed_pulse_spectrum", "deposit_droop", "exact_compress", "range_compress", "to_raw_data"]


def deposit_droop(nu: np.ndarray, range_kernel: str) -> np.ndarray | float:
    """Spectral response ``D(nu)`` of a deposit kernel, ``nu = f / fs_fine`` (float64, any shape).

    The continuous Fourier transform of the kernel ``h(x)`` (x in fine bins), which the
    deposit multiplies into the spectrum of the path sum (docs/physics.md (D2)):
    1 for ``nearest`` (taken as exact; its error is the up-to-half-bin shift),
    ``sinc^2(nu)`` for ``linear`` (triangle), and for ``sinc`` (Lanczos,
    ``h(x) = sinc(x) sinc(x / A)``) the integral ``int h(x) cos(2 pi nu x) dx`` evaluated
    with Simpson's rule on 64 points per bin (accurate to ~1e-9).
    """
    if range_kernel == "linear":
        return np.sinc(nu) ** 2
    if range_kernel == "sinc":
        from scipy.integrate import simpson

        from .trace import LANCZOS_A
        x = np.linspace(-LANCZOS_A, LANCZOS_A, 128 * LANCZOS_A + 1)
        h = np.sinc(x) * np.sinc(x / LANCZOS_A)
        nu = np.asarray(nu, dtype=np.float64)
        flat = nu.reshape(-1)
        out = np.empty_like(flat)
        for i0 in range(0, flat.size, 1024):            # bounded memory: 1024 frequencies at a time
            out[i0:i0 + 1024] = simpson(h[None, :] * np.cos(2 * np.pi * flat[i0:i0 + 1024, None] * x[None, :]), x=x)
        return out.reshape(nu.shape)
    return 1.0


def compressed_pulse_spectrum(n: int, fs: float, oversample: int, bandwidth: float,
                              range_kernel: str) -> np.ndarray:
    """Filter applied to an ``n``-point coarse spectrum, float64 [n] in FFT order.

    ``H(f) = rect(f / B) / D(f) / g`` with ``D`` the deposit kernel's droop
    (:func:`deposit_droop`) and ``g = sum(rect) / n``, which gives the compressed pulse a
    unit peak.
    """
    f = sp_fft.fftfreq(n, d=1.0 / fs)
    band = (np.abs(f) <= 0.5 * bandwidth)
    droop = np.ones(n)
    droop[band] = deposit_droop(f[band] / (fs * oversample), range_kernel)
    return band.astype(np.float64) / droop / (band.sum() / n)


def range_compress(deposit: np.ndarray, reference_length: np.ndarray, window: FastTimeWindow,
                   frequency: float, bandwidth: float, range_kernel: str, block: int = 256,
                   chirp: tuple[float, float] | None = None) -> np.ndarray:
    """Range-compressed samples from the fine deposit.

    The deposit is zero-padded (to twice the window, and by at least 2048 samples) before filtering, so the compressed
    pulse's sinc tails do not wrap around the window (linear, not circular, convolution).

    Parameters
    ----------
    deposit : complex64 [n_pulses, n_fine]
    reference_length : float64 [n_pulses], m
    window : FastTimeWindow
    frequency, bandwidth : float, Hz
    range_kernel : {"nearest", "linear", "sinc"}
    block : int
        Pulses filtered at once (bounds the memory of the padded FFT).
    chirp : (pulse_length [s], chirp_rate [Hz/s]), optional
        Produce chirped echoes instead, as a receiver records them: the deposit's spectrum times
        ``fs S(f) R(f) / D(f)``, with ``S`` the chirp's exact spectrum, ``R`` the receiver's
        anti-aliasing response (flat over the band, raised-cosine roll-off to ``fs / 2``;
        :func:`sarmitsuba.synthetic.receiver_response`) and ``D`` the deposit kernel's droop.
        :func:`sarmitsuba.focus.range_compression.range_compress` inverts it exactly.

    Returns
    -------
    complex64 [n_pulses, n_samples]
    """
    from .constants import SPEED_OF_LIGHT
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    phase = np.mod(-k * reference_length, 2.0 * math.pi)           # float64, reduced before use
    n, os_ = window.n_samples, window.oversample
    n_pad = sp_fft.next_fast_len(max(2 * n, n + 2048))
    n_fine = n_pad * os_
    keep = np.concatenate([np.arange(0, (n_pad + 1) // 2), np.arange(n_fine - n_pad // 2, n_fine)])
    filt = compressed_pulse_spectrum(n_pad, window.fs, os_, bandwidth, range_kernel)
    if chirp is not None:
        from .focus.range_compression import chirp_spectrum
        from .synthetic import receiver_response
        f = sp_fft.fftfreq(n_pad, d=1.0 / window.fs)
        filt = window.fs * chirp_spectrum(f, *chirp) * receiver_response(f, window.fs, bandwidth) \
            / deposit_droop(f / (window.fs * os_), range_kernel)
    out = np.empty((deposit.shape[0], n), np.complex64)
    for p0 in range(0, deposit.shape[0], block):
        rows = slice(p0, p0 + block)
        spectrum = sp_fft.fft(deposit[rows], n=n_fine, axis=1, workers=-1)
        coarse = spectrum[:, keep] * (filt[None, :] * np.exp(1j * phase[rows])[:, None]).astype(np.complex64)
        out[rows] = sp_fft.ifft(coarse, axis=1, workers=-1)[:, :n]
    return out


def exact_compress(paths: PathList, n_pulses: int, reference_length: np.ndarray, window: FastTimeWindow,
                   frequency: float, bandwidth: float, block_lanes: int = 1 << 21) -> np.ndarray:
    """Range-compressed samples evaluated path by path: the ``exact`` range kernel.

    ``s_p[n] = exp(-j k L_ref,p) sum_i v_i sinc(B (n - x_i) / fs)`` with ``v_i`` the path's
    value relative to the reference phase and ``x_i`` its delay in samples
    (docs/physics.md (D4)): the unit-peak, rect-spectrum compressed pulse of
    :func:`compressed_pulse_spectrum`, without a deposit grid, padding or truncation. Every
    path contributes to every sample (its sinc tails included), so the cost is
    paths x samples: a Dr.Jit kernel with one lane per output sample looping over the
    paths of its pulse, summing in float64.

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

    from .constants import SPEED_OF_LIGHT
    n = window.n_samples
    order = np.argsort(paths.pulse, kind="stable")
    position, value = paths.position[order], paths.value[order]
    start = np.searchsorted(paths.pulse[order], np.arange(n_pulses + 1)).astype(np.uint32)
    pos = mi.Float64(position)
    v_re, v_im = mi.Float(value.real.astype(np.float32)), mi.Float(value.imag.astype(np.float32))
    ratio = bandwidth / window.fs
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
            w = mi.Float64(dr.select(dr.abs(x) < 1e-4, 1.0, dr.sin(x) / x))
            return (k + 1, acc_re + w * mi.Float64(dr.gather(mi.Float, v_re, k)),
                    acc_im + w * mi.Float64(dr.gather(mi.Float, v_im, k)))

        _, acc_re, acc_im = dr.while_loop((k, mi.Float64(0.0), mi.Float64(0.0)), lambda k, *_: k < end, body,
                                          label="exact_range_kernel")
        out[p0:p1] = (acc_re.numpy() + 1j * acc_im.numpy()).reshape(p1 - p0, n)
    k_wave = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    phase = np.mod(-k_wave * reference_length, 2.0 * math.pi)
    return (out * np.exp(1j * phase)[:, None]).astype(np.complex64)


def to_raw_data(deposit: "np.ndarray | PathList", result: TraceResult, window: FastTimeWindow, params: RadarParameters,
                geometry: AcquisitionGeometry, range_kernel: str, metadata: dict,
                noise_seed: int | None = None) -> RawData:
    """Range-compress a deposit or path list (``result.contributions(order)``) into :class:`RawData`.

    With absolute radiometry (sensor ``transmit_power``) the samples are scaled to sqrt(W) by the
    radar equation at each pulse's reference range (the tracer has applied the path's own
    ``R_ref^2 / (R_tx R_rx)``), and thermal noise of power ``k T B F`` per sample is added
    when the sensor has noise parameters and ``noise_seed`` is given (docs/physics.md (R1)-(R4)).
    """
    from .radiometry import radar_equation, thermal_noise
    chirped = params.output == "raw"
    if isinstance(deposit, PathList):
        if chirped:
            raise ParameterError("range_kernel = 'exact' evaluates range-compressed samples; "
                                 "use it with sensor output = 'compressed' (or range_kernel linear|sinc for raw)")
        data = exact_compress(deposit, len(result.reference_length), result.reference_length, window,
                              params.frequency, params.bandwidth)
    else:
        data = range_compress(deposit, result.reference_length, window, params.frequency, params.bandwidth,
                              range_kernel, chirp=(params.pulse_length, params.chirp_rate) if chirped else None)
    equation = radar_equation(params)
    if equation is not None:
        scale = equation.amplitude_scale(0.5 * result.reference_length)        # float64 [n_pulses]
        data = (data * scale[:, None]).astype(np.complex64)
        metadata = {**metadata, "units": "sqrt(W) at the receiver, unit-energy matched filter"}
        if equation.noise_power > 0 and noise_seed is not None:
            data += thermal_noise(data.shape, equation.noise_power, params.sampling_rate, params.bandwidth,
                                  noise_seed)
            metadata = {**metadata, "noise_power_w": equation.noise_power}
    return RawData(
        data=data, fast_time=window.fast_time, pulse_time=geometry.pulse_time.copy(),
        tx_position=geometry.positions.copy(), rx_position=geometry.positions.copy(),
        velocity=geometry.velocity.copy(), fc=params.frequency, bandwidth=params.bandwidth,
        chirp_rate=params.chirp_rate, pulse_length=params.pulse_length, fs=params.sampling_rate,
        prf=params.prf, range_compressed=not chirped, metadata=metadata)
