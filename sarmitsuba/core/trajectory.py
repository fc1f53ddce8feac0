"""The antenna's path in time: straight, circular or from state vectors, with motion errors, and
the moment each echo is received (docs/physics.md (J1)-(J4)).

A :class:`Trajectory` gives the antenna's position, velocity and acceleration at any time
(float64, metres and seconds, scene frame, z up). Three kinds:

- :func:`straight`: a uniform straight, level line, the default track (J1);
- :func:`circular`: a level circle at constant speed about a vertical axis (J1);
- :func:`from_state_vectors`: a smooth interpolant of :class:`StateVectors` (J2): a cubic Hermite
  spline when velocities are given (position and velocity match at every sample), else a cubic
  spline with not-a-knot ends (which reproduces straight lines and constant accelerations
  exactly). :func:`read_state_vectors` reads them from a CSV file.

:func:`with_motion_error` adds a horizontal deviation normal to the track (a sinusoid, or a
seeded random error of a Gaussian spectrum; :class:`MotionError`, (J4)). :func:`receive_time`
solves, per echo, when the antenna receives it (no stop-and-hop, (J3)), and :func:`echo_length`
is the two-way length a focuser needs for recorded transmit and receive positions.

This module knows nothing of :class:`~sarmitsuba.core.radar.RadarParameters`;
:mod:`sarmitsuba.core.geometry` composes the sensor's trajectory from it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .constants import SPEED_OF_LIGHT
from .state_vectors import (CSV_COLUMNS, FRAMES, HERMITE_WINDOW, MAX_GAP_RATIO, StateVectors, TrajectoryError,
                            read_state_vectors, utc_instant)

__all__ = ["StateVectors", "TrajectoryError", "read_state_vectors", "Trajectory", "straight", "circular",
           "from_state_vectors", "MotionError", "with_motion_error", "receive_time", "echo_length",
           "CSV_COLUMNS", "MAX_GAP_RATIO", "RECEIVE_ITERATIONS", "FRAMES", "utc_instant", "hermite_window",
           "HERMITE_WINDOW"]

#: Fixed-point iterations of the receive time (J3): each multiplies the error by about ``v / c``
#: (2.5e-5 at 7.6 km/s), so three take a 32 m receive offset below a picometre.
RECEIVE_ITERATIONS = 3


# ============================================================================ trajectories
@dataclass(frozen=True)
class Trajectory:
    """The antenna's path: ``evaluate(t, k)`` gives the ``k``-th time derivative (0 position [m],
    1 velocity [m/s], 2 acceleration [m/s^2]) at the float64 times ``t`` [s] as float64 [..., 3].

    Attributes
    ----------
    kind : str
        ``"straight"``, ``"circular"`` or ``"state vectors"`` (with ``" + motion error"``).
    evaluate : callable
        ``(t, k) -> float64 [..., 3]``.
    span : (float, float), s
        Times the path is known for (state vectors: first and last sample; else unbounded).
    nominal : Trajectory or None
        The path without motion errors, when they were added (:func:`with_motion_error`).
    states : StateVectors or None
        The state vectors it interpolates (their clock's :attr:`~StateVectors.epoch`, and whether
        the pulses centre on the closest approach).
    """

    kind: str
    evaluate: Callable[[np.ndarray, int], np.ndarray]
    span: tuple[float, float] = (-math.inf, math.inf)
    nominal: "Trajectory | None" = None
    states: "StateVectors | None" = None

    def position(self, t: Any) -> np.ndarray:
        """float64 [..., 3], m."""
        return self.evaluate(np.asarray(t, np.float64), 0)

    def velocity(self, t: Any) -> np.ndarray:
        """float64 [..., 3], m/s."""
        return self.evaluate(np.asarray(t, np.float64), 1)

    def acceleration(self, t: Any) -> np.ndarray:
        """float64 [..., 3], m/s^2."""
        return self.evaluate(np.asarray(t, np.float64), 2)

    @property
    def straight(self) -> bool:
        """Whether the path is a uniform straight line (no motion error)."""
        return self.kind == "straight"


def straight(mid: np.ndarray, velocity: np.ndarray) -> Trajectory:
    """A uniform straight line through ``mid`` [m] at ``t = 0`` with ``velocity`` [m/s], eq. (J1)."""
    mid, velocity = np.asarray(mid, np.float64), np.asarray(velocity, np.float64)

    def evaluate(t: np.ndarray, k: int) -> np.ndarray:
        if k == 0:
            return mid + t[..., None] * velocity
        return np.broadcast_to(velocity if k == 1 else np.zeros(3), t.shape + (3,)).copy()
    return Trajectory("straight", evaluate)


def circular(center: np.ndarray, radius: float, angle0: float, rate: float) -> Trajectory:
    """A level circle of ``radius`` [m] about the vertical through ``center`` [m] (at the height of
    ``center``), at angle ``angle0 + rate t`` [rad, counter-clockwise from +x], eq. (J1): speed
    ``|rate| radius``, clockwise seen from above for ``rate < 0``."""
    center = np.asarray(center, np.float64)

    def evaluate(t: np.ndarray, k: int) -> np.ndarray:
        phi = angle0 + rate * t
        c, s = np.cos(phi), np.sin(phi)
        # d^k/dt^k (cos, sin) = rate^k (cos, sin)(phi + k pi / 2)
        if k == 0:
            x, y = c, s
        elif k == 1:
            x, y = -s, c
        else:
            x, y = -c, -s
        scale = radius * rate ** k
        out = np.stack([scale * x, scale * y, np.zeros_like(phi)], axis=-1)
        return out + center if k == 0 else out
    return Trajectory("circular", evaluate)


def hermite_window(states: StateVectors) -> Callable[[np.ndarray, int], np.ndarray]:
    """``evaluate(t, k)``: the ``k``-th derivative (0..2) at times ``t`` [s] (float64 [...]) as
    float64 [..., 3], of the local Hermite interpolant of ``states`` (eq. (J6)): for ``t`` in
    ``[t_i, t_i+1]``, the polynomial of degree ``2 m - 1`` matching position and velocity at the
    ``m = states.window`` samples ``i - m/2 + 1 .. i + m/2`` (shifted inwards at the ends; the end
    polynomials extrapolate). Position and velocity are continuous at every sample (both
    neighbouring polynomials match them there); the acceleration may step by micro-g."""
    from scipy.interpolate import KroghInterpolator
    t_all, p_all, v_all = states.time, states.position, states.velocity
    n = t_all.size
    m = min(int(states.window or HERMITE_WINDOW), n)
    cache: dict[int, tuple[Any, float, np.ndarray]] = {}

    def polynomial(start: int) -> tuple[Any, float, np.ndarray]:
        if start not in cache:
            t = t_all[start:start + m]
            t0, p0 = float(t.mean()), p_all[start:start + m].mean(axis=0)
            y = np.empty((2 * m, 3))
            y[0::2], y[1::2] = p_all[start:start + m] - p0, v_all[start:start + m]
            cache[start] = (KroghInterpolator(np.repeat(t - t0, 2), y), t0, p0)
        return cache[start]

    def evaluate(t: np.ndarray, k: int) -> np.ndarray:
        t = np.asarray(t, np.float64)
        flat = t.reshape(-1)
        interval = np.clip(np.searchsorted(t_all, flat, side="right") - 1, 0, n - 2)
        start = np.clip(interval - (m // 2 - 1), 0, n - m)
        out = np.empty((flat.size, 3))
        for s in np.unique(start):
            pick = start == s
            poly, t0, p0 = polynomial(int(s))
            value = poly.derivative(flat[pick] - t0, der=k) if k else poly(flat[pick] - t0)
            out[pick] = value + p0 if k == 0 else value
        return out.reshape(t.shape + (3,))
    return evaluate


def from_state_vectors(states: StateVectors) -> Trajectory:
    """The smooth interpolant of ``states``, eq. (J2): ``scipy.interpolate.CubicHermiteSpline``
    through positions and velocities, or ``CubicSpline`` (not-a-knot) through positions alone;
    with a :attr:`~StateVectors.window` the local Hermite interpolation of precise orbits (J6,
    :func:`hermite_window`). Outside the samples it extrapolates its end
    polynomials (the echoes of the last pulses arrive a few milliseconds after it)."""
    from scipy.interpolate import CubicHermiteSpline, CubicSpline
    if states.window:
        return Trajectory("state vectors", hermite_window(states), (float(states.time[0]), float(states.time[-1])),
                          states=states)
    if states.velocity is not None:
        spline = CubicHermiteSpline(states.time, states.position, states.velocity, axis=0)
    else:
        spline = CubicSpline(states.time, states.position, axis=0)

    def evaluate(t: np.ndarray, k: int) -> np.ndarray:
        return np.asarray(spline(t, k), np.float64)
    return Trajectory("state vectors", evaluate, (float(states.time[0]), float(states.time[-1])), states=states)


# ============================================================================ motion errors
@dataclass(frozen=True)
class MotionError:
    """A horizontal deviation ``e(s)`` of the antenna normal to the nominal track, as a function of
    the distance ``s`` flown from mid-aperture (docs/physics.md (J4)).

    Attributes
    ----------
    kind : str
        ``"sinusoid"``: ``e = amplitude sin(2 pi s / length)``; ``"random"``: a stationary Gaussian
        process of standard deviation ``amplitude`` and correlation ``exp(-ds^2 / length^2)``,
        drawn with ``seed``.
    amplitude : float, m
    length : float, m
        Period (sinusoid) or correlation length (random).
    seed : int
    """

    kind: str
    amplitude: float
    length: float
    seed: int = 0

    @classmethod
    def parse(cls, text: Any) -> "MotionError | None":
        """From the sensor parameter ``motion_error``: ``"AMPLITUDE_M, PERIOD_M"`` (a sinusoid),
        ``"random, RMS_M, CORRELATION_M[, SEED]"``, or None / ``""`` / ``"none"`` for none.

        Raises TrajectoryError naming ``motion_error``, the form and the valid ranges."""
        if text is None or isinstance(text, MotionError):
            return text
        parts = [p.strip() for p in str(text).replace(";", ",").split(",") if p.strip()]
        if not parts or parts == ["none"]:
            return None
        kind = "random" if parts[0].lower() == "random" else "sinusoid"
        numbers = parts[1:] if kind == "random" else parts
        form = ("'AMPLITUDE_M, PERIOD_M' (a sinusoid, e.g. '0.02, 40') or 'random, RMS_M, CORRELATION_M[, SEED]' "
                "(e.g. 'random, 0.02, 50, 1')")
        try:
            values = [float(v) for v in numbers]
        except ValueError:
            values = []
        count = (2, 3) if kind == "random" else (2,)
        if len(values) not in count or not all(math.isfinite(v) for v in values):
            raise TrajectoryError(f"motion_error = {text!r}: give {form}")
        amplitude, length = values[0], values[1]
        seed = values[2] if len(values) == 3 else 0.0
        if not (0 < amplitude <= 100 and 0 < length <= 1e7 and seed == int(seed) and seed >= 0):
            raise TrajectoryError(f"motion_error = {text!r}: the amplitude must lie in (0, 100] m, the "
                                  f"{'period' if kind == 'sinusoid' else 'correlation length'} in (0, 1e7] m and the "
                                  f"seed be a whole number >= 0; give {form}")
        return cls(kind, amplitude, length, int(seed))

    def __str__(self) -> str:
        if self.kind == "sinusoid":
            return f"{self.amplitude:g}, {self.length:g}"
        return f"random, {self.amplitude:g}, {self.length:g}, {self.seed}"

    def function(self, s_lo: float, s_hi: float) -> Callable[[np.ndarray, int], np.ndarray]:
        """``e^(k)(s)``: the deviation [m] (``k = 0``) and its derivatives in ``s`` (1, 2), valid for
        distances flown in ``[s_lo, s_hi]`` (a random error is drawn over that interval plus four
        correlation lengths on each side)."""
        if self.kind == "sinusoid":
            w = 2.0 * math.pi / self.length
            return lambda s, k: self.amplitude * w ** k * np.sin(w * s + k * math.pi / 2.0)
        from scipy.interpolate import CubicSpline
        step = self.length / 16.0
        margin = 4.0 * self.length
        n = int(math.ceil((s_hi - s_lo + 2 * margin) / step)) + 1
        if n > 5_000_000:
            raise TrajectoryError(f"motion_error = '{self}': a correlation length of {self.length:g} m over a "
                                  f"{s_hi - s_lo:.4g} m track needs {n} samples; use a longer correlation length")
        grid = s_lo - margin + step * np.arange(n)
        # white noise convolved with exp(-2 x^2 / L^2) has the correlation exp(-x^2 / L^2)
        half = int(math.ceil(3.0 * self.length / step))
        x = step * np.arange(-half, half + 1)
        kernel = np.exp(-2.0 * (x / self.length) ** 2)
        kernel *= self.amplitude / math.sqrt(float(np.sum(kernel ** 2)))
        noise = np.random.default_rng(self.seed).standard_normal(n + 2 * half)
        spline = CubicSpline(grid, np.convolve(noise, kernel, mode="valid"))
        return lambda s, k: spline(s, k)


def with_motion_error(nominal: Trajectory, error: MotionError, t_lo: float, t_hi: float, look_sign: float) -> Trajectory:
    """``nominal`` plus ``error`` horizontally across the track, eq. (J4).

    The deviation is ``e(s(t)) n(t)``: ``s(t)`` the distance flown along ``nominal`` from
    mid-aperture (the middle of ``[t_lo, t_hi]``) and ``n(t)`` the horizontal unit normal to its velocity on the side the radar looks
    (``look_sign`` +1 right, -1 left). The derivatives add ``e' |v| n`` and ``e'' |v|^2 n``
    (the turn of ``n`` itself is neglected: ``e |dn/dt|``, under a millimetre per second for a
    2 cm error on a 1 km circle at 100 m/s). ``[t_lo, t_hi]`` are the times the acquisition
    spans (the distance table and a random error cover them and a margin)."""
    margin = 0.05 * (t_hi - t_lo) + 1e-3
    grid = np.linspace(t_lo - margin, t_hi + margin, 4097)          # symmetric: grid[2048] is mid-aperture
    speed = np.linalg.norm(nominal.velocity(grid), axis=-1)
    s_grid = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(grid))])
    from scipy.interpolate import CubicSpline
    distance = CubicSpline(grid, s_grid - s_grid[grid.size // 2])
    e = error.function(float(distance(grid[0])), float(distance(grid[-1])))

    def evaluate(t: np.ndarray, k: int) -> np.ndarray:
        base = nominal.evaluate(t, k)
        v = nominal.velocity(t)
        horizontal = np.stack([v[..., 1], -v[..., 0], np.zeros_like(v[..., 0])], axis=-1) * look_sign   # v x z
        speed = np.linalg.norm(horizontal, axis=-1)
        if np.any(speed == 0):
            raise TrajectoryError("motion_error: the nominal track is vertical or at rest somewhere, where no "
                                  "horizontal direction normal to it exists")
        normal = horizontal / speed[..., None]
        return base + (e(distance(t), k) * speed ** k)[..., None] * normal
    return Trajectory(nominal.kind + " + motion error", evaluate, nominal.span, nominal, nominal.states)


# ============================================================================ echo timing
def receive_time(trajectory: Trajectory, t_tx: np.ndarray, points: np.ndarray,
                 first_leg: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """When the antenna receives the echo of ``points`` of pulses sent at ``t_tx``: no
    stop-and-hop, eq. (J3).

    The delay ``tau`` solves ``c tau = s + |P(t_tx + tau) - X|``, with ``s`` the first leg
    (``|P(t_tx) - X|`` by default; longer for a multi-bounce path), by the fixed-point iteration
    ``tau <- (s + |P(t_tx + tau) - X|) / c`` from the stop-and-hop delay; each step multiplies the
    error by about ``v / c`` (:data:`RECEIVE_ITERATIONS` steps).

    Parameters
    ----------
    trajectory : Trajectory
    t_tx : float64 [n], s
        Transmit times.
    points : float64 [n, 3] or [3], m
        Where each echo comes from.
    first_leg : float64 [n], m, optional

    Returns
    -------
    (t_rx float64 [n] s, rx_position float64 [n, 3] m)
    """
    t_tx = np.asarray(t_tx, np.float64)
    points = np.asarray(points, np.float64)
    tx = trajectory.position(t_tx)
    s = np.linalg.norm(tx - points, axis=-1) if first_leg is None else np.asarray(first_leg, np.float64)
    tau = 2.0 * s / SPEED_OF_LIGHT
    for _ in range(RECEIVE_ITERATIONS + 1):
        rx = trajectory.position(t_tx + tau)
        tau = (s + np.linalg.norm(rx - points, axis=-1)) / SPEED_OF_LIGHT
    return t_tx + tau, trajectory.position(t_tx + tau)


def echo_length(tx: np.ndarray, rx: np.ndarray, velocity: np.ndarray, rx_delay: np.ndarray,
                points: np.ndarray) -> np.ndarray:
    """Two-way length [m] of the echo of ``points`` for recorded transmit and receive positions,
    eq. (J3): ``|tx - X| + |rx' - X|``, the receiver moved to the echo's own arrival,
    ``rx' = rx + v (L0 / c - rx_delay)``, ``L0 = |tx - X| + |rx - X|`` (one step of the
    iteration: the remaining error is ``(v / c)`` times the receiver's move, micrometres).

    Parameters
    ----------
    tx, rx, velocity : float64 [n, 3]
        Antenna at transmission and at ``rx_delay`` after it [m], and its velocity [m/s].
    rx_delay : float64 [n] or None, s
        ``rx_time - pulse_time``; None (stop-and-hop data): ``|tx - X| + |rx - X|``.
    points : float64 [..., n, 3] (broadcast against the pulses)

    Returns
    -------
    float64 [..., n]
    """
    first = np.linalg.norm(points - tx, axis=-1)
    second = np.linalg.norm(points - rx, axis=-1)
    if rx_delay is None:
        return first + second
    shift = (first + second) / SPEED_OF_LIGHT - rx_delay
    return first + np.linalg.norm(points - rx - shift[..., None] * velocity, axis=-1)
