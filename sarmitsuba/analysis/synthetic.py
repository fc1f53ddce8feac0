"""Analytic point-target raw data: the test oracle for every focuser (docs/design.md section 9).

:func:`simulate_point_targets` writes, for point targets of complex amplitude ``a`` at
positions ``X``, the echo that docs/design.md section 5 prescribes, exactly and in float64:

* raw chirp (``compressed=False``)::

      a * rect((tau - L/c) / T_p) * exp(j pi K_r (tau - L/c)^2) * exp(-j 2 pi fc L / c)

* range compressed (``compressed=True``)::

      a * p_r(tau - L/c) * exp(-j 2 pi fc L / c)

  with ``p_r`` the unit-peak compressed pulse of the range window over the band
  (``sinc(B t)`` for rect; :func:`sarmitsuba.focus.windows.compressed_pulse`),

where ``L = |T_p - X| + |X - R_p|`` is the two-way length from the transmitter ``T_p`` to the
receiver ``R_p`` of pulse ``p`` (stop and hop). ``L`` is formed in float64 and the carrier
phase ``fc L / c`` is reduced modulo one cycle in float64 before the cast to complex64, so
the data do not depend on how far away the sensor is.

An optional :class:`AzimuthBeam` restricts the pulses that see each target (an ideal
azimuth beam: all or nothing, no antenna pattern), for stripmap with squint or spotlight.
:func:`straight_track` builds a straight level track; :func:`stripmap` and
:func:`spotlight` put the pieces together for the common airborne/spaceborne test cases.

Frame: right-handed, metres, z up; by default the track runs along +x and the sensor looks
right, toward -y (docs/design.md section 4).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.arrays import readonly, vector3
from ..focus.windows import check_window, compressed_pulse
from ..core.raw import RawData
from ..signal.signal_model import received_chirp_spectrum

__all__ = ["PointTarget", "Track", "AzimuthBeam", "straight_track", "simulate_point_targets",
           "two_way_length", "along_track_angle", "illuminated", "stripmap", "spotlight"]

C = SPEED_OF_LIGHT


def _positive(name: str, value: Any, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite positive number [{unit}], got {value!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite positive number [{unit}], got {value!r}")
    return v


# ============================================================================ containers
@dataclass(frozen=True, eq=False)
class PointTarget:
    """An ideal point scatterer.

    Attributes
    ----------
    position : float64 [3], m
        World position (z up).
    amplitude : complex, sqrt(m^2)
        Complex amplitude ``a``: the focused image of the target has peak ``a`` (its RCS
        is ``|a|^2`` in normalised radiometry).

    Raises
    ------
    ValueError
        When ``position`` is not 3 finite numbers or ``amplitude`` is not finite.
    """

    position: np.ndarray
    amplitude: complex = 1.0 + 0.0j

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", readonly(vector3("position", self.position)))
        a = complex(self.amplitude)
        if not np.isfinite(a):
            raise ValueError(f"amplitude must be a finite complex number, got {self.amplitude!r}")
        object.__setattr__(self, "amplitude", a)


@dataclass(frozen=True, eq=False)
class Track:
    """Antenna phase-centre positions and velocities of a pulse train.

    Attributes
    ----------
    position : float64 [n_pulses, 3], m
        Antenna position at each pulse (monostatic: transmitter = receiver).
    velocity : float64 [n_pulses, 3], m/s
        Platform velocity at each pulse.
    pulse_time : float64 [n_pulses], s
        Transmission time of each pulse.
    prf : float, Hz
        Pulse repetition frequency.
    """

    position: np.ndarray
    velocity: np.ndarray
    pulse_time: np.ndarray
    prf: float

    def __post_init__(self) -> None:
        for name in ("position", "velocity"):
            arr = np.asarray(getattr(self, name), dtype=np.float64)
            if arr.ndim != 2 or arr.shape[1] != 3 or not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} must be finite float64 [n_pulses, 3], got shape {arr.shape}")
            object.__setattr__(self, name, readonly(arr))
        t = np.asarray(self.pulse_time, dtype=np.float64)
        if t.shape != (self.position.shape[0],) or self.velocity.shape != self.position.shape:
            raise ValueError("position, velocity and pulse_time must agree in the number of pulses")
        object.__setattr__(self, "pulse_time", readonly(t))
        object.__setattr__(self, "prf", _positive("prf", self.prf, "Hz"))

    @property
    def n_pulses(self) -> int:
        """Number of pulses."""
        return self.position.shape[0]


@dataclass(frozen=True, eq=False)
class AzimuthBeam:
    """Ideal azimuth beam: a target is seen by a pulse only inside the beam (no pattern).

    The *along-track angle* of a direction ``u`` (unit vector from the antenna) is
    ``asin(u . v / |v|)``: its angle from the zero-Doppler plane (the plane through the
    antenna normal to the velocity ``v``), positive forward. A target is illuminated by a
    pulse when the along-track angle of its line of sight differs from that of the beam
    centre by at most ``width / 2``.

    Attributes
    ----------
    width : float, deg
        Full azimuth beamwidth, in (0, 180).
    squint : float, deg
        Stripmap: along-track angle of the beam centre, positive = forward along the
        velocity. Ignored when ``center`` is given. Must lie in (-90, 90).
    center : float64 [3] or None, m
        Spotlight: the beam centre always points at this fixed world point.

    Raises
    ------
    ValueError
        When an angle is out of range or ``center`` is not 3 finite numbers.
    """

    width: float
    squint: float = 0.0
    center: np.ndarray | None = None

    def __post_init__(self) -> None:
        width = float(self.width)
        if not (np.isfinite(width) and 0 < width < 180):
            raise ValueError(f"beam width must be in (0, 180) deg, got {self.width!r}")
        squint = float(self.squint)
        if not (np.isfinite(squint) and -90 < squint < 90):
            raise ValueError(f"beam squint must be in (-90, 90) deg, got {self.squint!r}")
        object.__setattr__(self, "width", width)
        object.__setattr__(self, "squint", squint)
        if self.center is not None:
            object.__setattr__(self, "center", readonly(vector3("beam center", self.center)))

    @property
    def mode(self) -> str:
        """``"spotlight"`` when the beam follows a fixed point, else ``"stripmap"``."""
        return "stripmap" if self.center is None else "spotlight"


# ============================================================================ geometry
def straight_track(n_pulses: int, prf: float, velocity: float | Sequence[float], *,
                   center: Sequence[float] | None = None, start: Sequence[float] | None = None,
                   direction: Sequence[float] = (1.0, 0.0, 0.0)) -> Track:
    """Straight track at constant velocity (level when ``direction`` is horizontal).

    Parameters
    ----------
    n_pulses : int
        Number of pulses, >= 1.
    prf : float, Hz
        Pulse repetition frequency (> 0); pulses are ``1 / prf`` apart.
    velocity : float or sequence of 3 floats
        Speed [m/s] (> 0) along ``direction``, or the velocity vector [m/s] itself (then
        ``direction`` is ignored).
    center, start : sequence of 3 floats, m
        Exactly one of them: the antenna position at the middle of the track (the mean of
        the first and last pulse positions) or at the first pulse.
    direction : sequence of 3 floats, default (1, 0, 0)
        Flight direction (normalised here).

    Returns
    -------
    Track
        ``position[k] = start + velocity * k / prf``, ``pulse_time[k] = k / prf - t_c``
        with ``t_c = (n_pulses - 1) / (2 prf)`` when ``center`` is given (time 0 at the
        track centre) and ``t_c = 0`` when ``start`` is given.

    Raises
    ------
    ValueError
        When ``n_pulses < 1``, ``prf`` or the speed is not positive, both or neither of
        ``center`` and ``start`` are given, or a vector is not 3 finite numbers.

    Examples
    --------
    >>> track = straight_track(201, 400.0, 100.0, center=(0.0, 4000.0, 3000.0))
    >>> track.position[[0, -1], 0].tolist()
    [-25.0, 25.0]
    """
    if isinstance(n_pulses, bool) or not isinstance(n_pulses, (int, np.integer)) or n_pulses < 1:
        raise ValueError(f"n_pulses must be an integer >= 1, got {n_pulses!r}")
    prf = _positive("prf", prf, "Hz")
    if np.ndim(velocity) == 0:
        speed = _positive("velocity", velocity, "m/s")
        d = vector3("direction", direction)
        norm = np.linalg.norm(d)
        if not norm > 0:
            raise ValueError("direction must be a non-zero vector")
        v = speed * d / norm
    else:
        v = vector3("velocity", velocity)
        if not np.linalg.norm(v) > 0:
            raise ValueError("velocity must be a non-zero vector [m/s]")
    if (center is None) == (start is None):
        raise ValueError("give exactly one of center= and start= (antenna position at the track middle or start)")
    k = np.arange(n_pulses, dtype=np.float64)
    if center is not None:
        t = (k - (n_pulses - 1) / 2.0) / prf
        pos = vector3("center", center)[None, :] + t[:, None] * v[None, :]
    else:
        t = k / prf
        pos = vector3("start", start)[None, :] + t[:, None] * v[None, :]
    return Track(position=pos, velocity=np.tile(v, (n_pulses, 1)), pulse_time=t, prf=prf)


def two_way_length(tx_position: np.ndarray, point: np.ndarray,
                   rx_position: np.ndarray | None = None) -> np.ndarray:
    """Two-way path length ``|T_p - X| + |X - R_p|`` in float64.

    Parameters
    ----------
    tx_position : float64 [n_pulses, 3], m
    point : float64 [3], m
    rx_position : float64 [n_pulses, 3], m, optional
        Receiver positions; default: monostatic (``2 |T_p - X|``).

    Returns
    -------
    float64 [n_pulses], m
    """
    tx = np.asarray(tx_position, dtype=np.float64)
    x = np.asarray(point, dtype=np.float64)
    one = np.linalg.norm(tx - x, axis=-1)
    if rx_position is None:
        return 2.0 * one
    return one + np.linalg.norm(x - np.asarray(rx_position, dtype=np.float64), axis=-1)


def along_track_angle(antenna: np.ndarray, velocity: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Along-track angle [rad] of the line of sight from each antenna to ``point``.

    ``asin(u . v / |v|)`` with ``u`` the unit vector from the antenna to the point: the
    angle from the zero-Doppler plane, positive when the point lies ahead.

    Parameters
    ----------
    antenna : float64 [n_pulses, 3], m
    velocity : float64 [n_pulses, 3], m/s
    point : float64 [3] or [n_pulses, 3], m

    Returns
    -------
    float64 [n_pulses], rad, in [-pi/2, pi/2]
    """
    los = np.asarray(point, dtype=np.float64) - np.asarray(antenna, dtype=np.float64)
    v = np.asarray(velocity, dtype=np.float64)
    s = np.einsum("ij,ij->i", los, v) / (np.linalg.norm(los, axis=-1) * np.linalg.norm(v, axis=-1))
    return np.arcsin(np.clip(s, -1.0, 1.0))


def illuminated(beam: AzimuthBeam | None, antenna: np.ndarray, velocity: np.ndarray,
                point: np.ndarray) -> np.ndarray:
    """Pulses whose beam sees ``point``: bool [n_pulses] (all true when ``beam`` is None).

    True where ``|theta(point) - theta_c| <= width / 2`` (plus 1e-12 rad of tolerance),
    with ``theta`` the :func:`along_track_angle` and ``theta_c`` the beam centre's: the
    squint for stripmap, the along-track angle of ``beam.center`` for spotlight.
    """
    antenna = np.asarray(antenna, dtype=np.float64)
    if beam is None:
        return np.ones(antenna.shape[0], dtype=bool)
    theta = along_track_angle(antenna, velocity, point)
    if beam.center is None:
        centre = np.deg2rad(beam.squint)
    else:
        centre = along_track_angle(antenna, velocity, beam.center)
    return np.abs(theta - centre) <= np.deg2rad(beam.width) / 2.0 + 1e-12


# ============================================================================ simulation
def simulate_point_targets(targets: Iterable[PointTarget] | PointTarget, tx_position: np.ndarray,
                           fc: float, bandwidth: float, fs: float, fast_time0: float, n_samples: int, *,
                           prf: float, velocity: np.ndarray, pulse_length: float, compressed: bool = True,
                           range_window: str = "rect", range_window_params: dict[str, Any] | None = None,
                           beam: AzimuthBeam | None = None, pulse_time: np.ndarray | None = None,
                           rx_position: np.ndarray | None = None, chirp_rate: float | None = None,
                           anti_alias: bool = False, metadata: dict[str, Any] | None = None) -> RawData:
    """Exact echoes of point targets as :class:`~sarmitsuba.core.raw.RawData`.

    Parameters
    ----------
    targets : PointTarget or iterable of PointTarget
        The scatterers (an empty iterable gives zero data).
    tx_position : float64 [n_pulses, 3], m
        Transmitter (and, by default, receiver) phase centre of each pulse.
    fc : float, Hz
        Carrier frequency.
    bandwidth : float, Hz
        Chirp bandwidth ``B``.
    fs : float, Hz
        Fast-time sampling rate (complex samples; ``fs >= B`` avoids aliasing).
    fast_time0 : float, s
        Two-way delay of the first sample; sample ``i`` is at ``fast_time0 + i / fs``.
    n_samples : int
        Samples per pulse, >= 2.
    prf : float, Hz
        Pulse repetition frequency (stored; ``pulse_time`` defaults to ``k / prf``).
    velocity : float64 [n_pulses, 3], m/s
        Platform velocity (stored, and used by ``beam``).
    pulse_length : float, s
        Chirp duration ``T_p``.
    compressed : bool, default True
        True: range-compressed echoes ``a p_r(tau - L/c) exp(-j 2 pi fc L/c)``; False: raw
        chirps ``a rect((tau - L/c)/T_p) exp(j pi K_r (tau - L/c)^2) exp(-j 2 pi fc L/c)``
        (the chirp is centred on the delay ``L/c``).
    range_window : str, default "rect"
        Range window of the compressed pulse (``compressed=True`` only; raw chirps are
        unweighted). ``p_r`` is the unit-peak inverse transform of the windowed rect
        spectrum, :func:`sarmitsuba.focus.windows.compressed_pulse`.
    range_window_params : dict, optional
        Its parameters (e.g. ``{"beta": 2.5}``).
    beam : AzimuthBeam, optional
        Only pulses whose beam sees a target receive its echo (:func:`illuminated`).
    pulse_time : float64 [n_pulses], s, optional
        Default ``k / prf``.
    rx_position : float64 [n_pulses, 3], m, optional
        Receiver positions for bistatic data; default monostatic.
    chirp_rate : float, Hz/s, optional
        ``K_r``; default ``bandwidth / pulse_length`` (up-chirp). A negative value gives
        a down-chirp.
    anti_alias : bool, default False
        Raw chirps only. False: the chirp formula above sampled as is. Its rect envelope
        makes the spectrum extend beyond ``+-fs/2``, so the samples are aliased: the
        in-band spectrum differs from the continuous chirp's by about
        ``1 / (2 pi sqrt(B T_p) (fs / B - 1))`` (-27 dB for ``B T_p = 300``,
        ``fs = 1.2 B``), which bounds how closely any range compression can reproduce
        ``p_r``. True: the echo as received through an ideal anti-aliasing filter, flat
        (unit gain, zero phase) over ``|f| <= B/2`` with a raised-cosine roll-off to zero
        at ``fs/2`` (:func:`sarmitsuba.signal.signal_model.receiver_response`); computed exactly from
        the chirp's closed-form spectrum
        (:func:`sarmitsuba.signal.signal_model.received_chirp_spectrum`). Its spectrum over the band is
        exactly the chirp's, so compressing it gives ``p_r`` (docs/design.md section 5).
    metadata : dict, optional
        Merged into the RawData metadata (after the generator's own keys).

    Returns
    -------
    RawData
        complex64 ``[n_pulses, n_samples]``; ``range_compressed = compressed``;
        ``metadata`` records the generator, the targets (positions, amplitudes),
        the range window, the beam and ``"units": "sqrt(m^2)"``.

    Raises
    ------
    ValueError
        On inconsistent shapes, non-positive scalars, a bad window or beam.

    Notes
    -----
    Cost: a few float64 passes over ``[n_pulses, n_samples]`` per target. Compressed
    echoes keep their sidelobe tails over the whole line (never truncated); the pulse is
    evaluated in closed form (not via an FFT), so it is exact at any sub-sample delay and
    has no periodic wrap. Raw chirps are zero outside ``|tau - L/c| <= T_p / 2``; a chirp
    cut by the window edge is stored cut (as a real receiver would).

    Examples
    --------
    >>> track = straight_track(201, 400.0, 100.0, center=(0.0, 4000.0, 3000.0))
    >>> raw = simulate_point_targets(PointTarget((0, 0, 0), 1.0), track.position, 9.6e9,  # doctest: +SKIP
    ...                              150e6, 180e6, 33.3e-6, 512, prf=track.prf,
    ...                              velocity=track.velocity, pulse_length=1e-6)
    """
    if isinstance(targets, PointTarget):
        targets = [targets]
    targets = list(targets)
    for k, t in enumerate(targets):
        if not isinstance(t, PointTarget):
            raise ValueError(f"targets[{k}] must be a PointTarget, got {type(t).__name__}")
    tx = np.asarray(tx_position, dtype=np.float64)
    if tx.ndim != 2 or tx.shape[1] != 3 or tx.shape[0] < 1 or not np.all(np.isfinite(tx)):
        raise ValueError(f"tx_position must be finite float64 [n_pulses >= 1, 3] metres, got shape {tx.shape}")
    n_pulses = tx.shape[0]
    rx = tx.copy() if rx_position is None else np.asarray(rx_position, dtype=np.float64)
    vel = np.asarray(velocity, dtype=np.float64)
    for name, arr in (("rx_position", rx), ("velocity", vel)):
        if arr.shape != (n_pulses, 3) or not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite float64 [{n_pulses}, 3], got shape {arr.shape}")
    fc = _positive("fc", fc, "Hz")
    bandwidth = _positive("bandwidth", bandwidth, "Hz")
    fs = _positive("fs", fs, "Hz")
    prf = _positive("prf", prf, "Hz")
    pulse_length = _positive("pulse_length", pulse_length, "s")
    kr = bandwidth / pulse_length if chirp_rate is None else float(chirp_rate)
    if not (np.isfinite(kr) and kr != 0):
        raise ValueError(f"chirp_rate must be finite and non-zero [Hz/s], got {chirp_rate!r}")
    t0 = float(fast_time0)
    if not np.isfinite(t0):
        raise ValueError(f"fast_time0 must be a finite number of seconds, got {fast_time0!r}")
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or n_samples < 2:
        raise ValueError(f"n_samples must be an integer >= 2, got {n_samples!r}")
    win_params = dict(range_window_params or {})
    win_name, win_full = check_window(range_window, **win_params)
    if beam is not None and not isinstance(beam, AzimuthBeam):
        raise ValueError(f"beam must be an AzimuthBeam or None, got {type(beam).__name__}")
    if pulse_time is None:
        pulse_time = np.arange(n_pulses, dtype=np.float64) / prf
    pulse_time = np.asarray(pulse_time, dtype=np.float64)
    if pulse_time.shape != (n_pulses,):
        raise ValueError(f"pulse_time must be float64 [{n_pulses}], got shape {pulse_time.shape}")

    fast_time = t0 + np.arange(n_samples, dtype=np.float64) / fs
    data = np.zeros((n_pulses, n_samples), dtype=np.complex128)
    for target in targets:
        seen = illuminated(beam, tx, vel, target.position)
        if not np.any(seen):
            continue
        length = two_way_length(tx[seen], target.position, rx[seen])  # float64 [P'], m
        delay = length / C
        cycles = np.mod(fc * delay, 1.0)  # carrier phase in cycles, reduced in float64
        carrier = target.amplitude * np.exp(-2j * np.pi * cycles)
        rel = fast_time[None, :] - delay[:, None]  # float64 [P', N], s
        if compressed:
            echo = compressed_pulse(rel, bandwidth, win_name, **win_full).astype(np.complex128)
        elif anti_alias:
            echo = _received_chirps(t0 - delay, n_samples, fs, bandwidth, pulse_length, kr)
        else:
            inside = np.abs(rel) <= pulse_length / 2.0
            # chirp phase pi K_r t^2 in cycles, reduced before exp
            echo = np.where(inside, np.exp(2j * np.pi * np.mod(0.5 * kr * rel ** 2, 1.0)), 0.0)
        data[seen] += carrier[:, None] * echo
    meta: dict[str, Any] = {
        "scene": "analytic point targets",
        "generator": "sarmitsuba.analysis.synthetic.simulate_point_targets",
        "units": "sqrt(m^2)",
        "targets": [{"position": t.position.tolist(), "amplitude": [t.amplitude.real, t.amplitude.imag]}
                    for t in targets],
        "range_window": {"name": win_name, **win_full} if compressed else {"name": "none (raw chirp)"},
        "anti_alias": bool(anti_alias and not compressed),
        "beam": None if beam is None else {"mode": beam.mode, "width_deg": beam.width, "squint_deg": beam.squint,
                                           "center": None if beam.center is None else beam.center.tolist()},
    }
    meta.update(metadata or {})
    return RawData(data=data.astype(np.complex64), fast_time=fast_time, pulse_time=pulse_time,
                   tx_position=tx.copy(), rx_position=rx.copy(), velocity=vel.copy(), fc=fc,
                   bandwidth=bandwidth, chirp_rate=kr, pulse_length=pulse_length, fs=fs, prf=prf,
                   range_compressed=bool(compressed), metadata=meta)


# ============================================================================ chirp spectrum
def _received_chirps(offset: np.ndarray, n: int, fs: float, bandwidth: float, pulse_length: float,
                     chirp_rate: float) -> np.ndarray:
    """Anti-aliased chirp samples: ``x_p[i] = int H(f) S(f) exp(j 2 pi f (offset_p + i / fs)) df``.

    ``offset_p = t0 - tau_p`` [s]. The integral is a Riemann sum on ``N`` frequencies
    ``f_k = k fs / N`` (an inverse FFT): by Poisson summation that equals the exact signal
    folded with period ``N / fs``, and ``N`` covers the window, the chirp and a guard of
    64 roll-off time constants, beyond which the folded signal has decayed. complex128
    [len(offset), n].
    """
    guard = 64.0 / max(fs - bandwidth, fs / 64.0)
    n_fft = int(2 ** np.ceil(np.log2(n + (pulse_length + 2 * guard) * fs + 1)))
    k = np.fft.fftfreq(n_fft) * n_fft
    f = k * fs / n_fft
    spectrum = received_chirp_spectrum(f, fs, bandwidth, pulse_length, chirp_rate)
    out = np.empty((offset.size, n), np.complex128)
    for p0 in range(0, offset.size, 128):
        off = offset[p0:p0 + 128]
        # exp(j 2 pi f_k offset): offset * fs in samples, phase in cycles reduced in float64
        cycles = np.mod(np.outer(off * fs, k / n_fft), 1.0)
        lines = np.fft.ifft(spectrum[None, :] * np.exp(2j * np.pi * cycles), axis=1)
        out[p0:p0 + 128] = lines[:, :n]
    return out


# ============================================================================ convenience
@dataclass(frozen=True)
class _Window:
    start: float
    n: int


def _fast_time_window(tx: np.ndarray, rx: np.ndarray, points: list[np.ndarray], fs: float,
                      margin: float) -> _Window:
    lengths = np.concatenate([two_way_length(tx, p, rx) for p in points])
    t_first = lengths.min() / C - margin
    t_last = lengths.max() / C + margin
    return _Window(t_first, int(np.ceil((t_last - t_first) * fs)) + 1)


def stripmap(targets: Iterable[PointTarget] | PointTarget, *, fc: float, bandwidth: float, fs: float,
             prf: float, speed: float, n_pulses: int, center: Sequence[float],
             direction: Sequence[float] = (1.0, 0.0, 0.0), beamwidth: float | None = None,
             squint: float = 0.0, pulse_length: float = 1e-6, compressed: bool = True,
             range_window: str = "rect", range_window_params: dict[str, Any] | None = None,
             margin: float | None = None, **kwargs: Any) -> RawData:
    """Stripmap point-target data on a straight track, with a fast-time window that fits.

    Parameters
    ----------
    targets : PointTarget or iterable of PointTarget
    fc, bandwidth, fs, prf : float, Hz
    speed : float, m/s
    n_pulses : int
    center : sequence of 3 floats, m
        Antenna position at the middle of the track.
    direction : sequence of 3 floats, default +x
    beamwidth : float, deg, optional
        Full azimuth beamwidth; None: every pulse sees every target.
    squint : float, deg, default 0
        Beam squint (positive forward); used only with ``beamwidth``.
    pulse_length : float, s, default 1 us
    compressed, range_window, range_window_params
        As in :func:`simulate_point_targets`.
    margin : float, s, optional
        Extra fast time before the earliest and after the latest echo centre; default
        ``pulse_length / 2 + 64 / bandwidth`` (the full chirp plus sidelobes).
    **kwargs
        Passed to :func:`simulate_point_targets` (``metadata``, ``chirp_rate``).

    Returns
    -------
    RawData
        With ``fast_time0`` and ``n_samples`` chosen to hold every target's echo over the
        whole track (illuminated or not).
    """
    targets = [targets] if isinstance(targets, PointTarget) else list(targets)
    track = straight_track(n_pulses, prf, speed, center=center, direction=direction)
    beam = None if beamwidth is None else AzimuthBeam(beamwidth, squint)
    margin = pulse_length / 2 + 64.0 / bandwidth if margin is None else float(margin)
    win = _fast_time_window(track.position, track.position, [t.position for t in targets] or
                            [np.zeros(3)], fs, margin)
    return simulate_point_targets(targets, track.position, fc, bandwidth, fs, win.start, win.n, prf=prf,
                                  velocity=track.velocity, pulse_length=pulse_length, compressed=compressed,
                                  range_window=range_window, range_window_params=range_window_params,
                                  beam=beam, pulse_time=track.pulse_time, **kwargs)


def spotlight(targets: Iterable[PointTarget] | PointTarget, *, fc: float, bandwidth: float, fs: float,
              prf: float, speed: float, n_pulses: int, center: Sequence[float], spot: Sequence[float],
              beamwidth: float, direction: Sequence[float] = (1.0, 0.0, 0.0), pulse_length: float = 1e-6,
              compressed: bool = True, range_window: str = "rect",
              range_window_params: dict[str, Any] | None = None, margin: float | None = None,
              **kwargs: Any) -> RawData:
    """Spotlight point-target data: the beam (full width ``beamwidth`` deg) tracks ``spot``.

    Parameters as in :func:`stripmap`; ``spot`` (3 floats, m) is the fixed point the beam
    centre follows. Returns RawData whose fast-time window holds every target's echo.
    """
    targets = [targets] if isinstance(targets, PointTarget) else list(targets)
    track = straight_track(n_pulses, prf, speed, center=center, direction=direction)
    beam = AzimuthBeam(beamwidth, center=spot)
    margin = pulse_length / 2 + 64.0 / bandwidth if margin is None else float(margin)
    win = _fast_time_window(track.position, track.position, [t.position for t in targets] or
                            [np.asarray(spot, float)], fs, margin)
    return simulate_point_targets(targets, track.position, fc, bandwidth, fs, win.start, win.n, prf=prf,
                                  velocity=track.velocity, pulse_length=pulse_length, compressed=compressed,
                                  range_window=range_window, range_window_params=range_window_params,
                                  beam=beam, pulse_time=track.pulse_time, **kwargs)
