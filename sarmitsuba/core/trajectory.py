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

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .constants import SPEED_OF_LIGHT
from .valid_ranges import ParameterError

__all__ = ["StateVectors", "TrajectoryError", "read_state_vectors", "Trajectory", "straight", "circular",
           "from_state_vectors", "MotionError", "with_motion_error", "receive_time", "echo_length",
           "CSV_COLUMNS", "MAX_GAP_RATIO", "RECEIVE_ITERATIONS"]


class TrajectoryError(ParameterError):
    """State vectors or a trajectory setting that cannot describe a flight (names the row and column)."""


#: Header of a state-vector CSV: time and position, then optionally velocity (docs/physics.md (J2)).
CSV_COLUMNS = ("time_s", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
#: A gap between consecutive state vectors longer than this many times their median spacing is refused:
#: the spline would invent the motion in between.
MAX_GAP_RATIO = 5.0
#: Fixed-point iterations of the receive time (J3): each multiplies the error by about ``v / c``
#: (2.5e-5 at 7.6 km/s), so three take a 32 m receive offset below a picometre.
RECEIVE_ITERATIONS = 3


# ============================================================================ state vectors
@dataclass(frozen=True)
class StateVectors:
    """Sampled antenna states: the navigation data of a flight (docs/physics.md (J2)).

    Attributes
    ----------
    time : float64 [n], s
        Strictly increasing sample times.
    position : float64 [n, 3], m
        Antenna phase centre in the scene frame (z up).
    velocity : float64 [n, 3], m/s, or None
        Velocity at each sample; with it the interpolant is a cubic Hermite spline.
    source : str
        Where they came from, for messages and metadata: a CSV file's name, or ``"python"``.

    Raises
    ------
    TrajectoryError
        Fewer rows than the interpolant needs (2 with velocities, 4 without), a non-finite
        value, times that do not increase, or a gap longer than :data:`MAX_GAP_RATIO` median
        spacings; each names the row (line of the file) and column.
    """

    time: np.ndarray
    position: np.ndarray
    velocity: np.ndarray | None = None
    source: str = "python"
    first_line: int = 0

    def __post_init__(self) -> None:
        for name in ("time", "position", "velocity"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.array(value, dtype=np.float64))
        _check_states(self)

    def row(self, i: int) -> str:
        """How messages name sample ``i``: ``FILE, line N`` for a file, else ``SOURCE, row i``."""
        if self.first_line:
            return f"{self.source}, line {self.first_line + i}"
        return f"{self.source}, row {i}"

    def shifted(self, offset: np.ndarray) -> "StateVectors":
        """The same states with ``offset`` [m] subtracted from every position (a local frame)."""
        return StateVectors(self.time, self.position - np.asarray(offset, float), self.velocity, self.source,
                            self.first_line)

    def __str__(self) -> str:
        return f"{self.source} ({self.time.size} state vectors)"


def _check_states(sv: StateVectors) -> None:
    """The checks of :class:`StateVectors` (see its Raises)."""
    t, p, v = sv.time, sv.position, sv.velocity
    if t.ndim != 1 or p.shape != (t.size, 3) or (v is not None and v.shape != (t.size, 3)):
        raise TrajectoryError(f"state vectors {sv.source}: time must be [n], position and velocity [n, 3]; got "
                              f"{list(t.shape)}, {list(p.shape)}, {None if v is None else list(v.shape)}")
    need = 2 if v is not None else 4
    if t.size < need:
        kind = "a cubic Hermite spline (with velocities)" if v is not None else "a cubic spline (no velocities)"
        raise TrajectoryError(f"state vectors {sv.source}: {t.size} row{'s' if t.size != 1 else ''}, but {kind} "
                              f"needs at least {need}: give more samples of the flight"
                              + ("" if v is not None else ", or velocities (vx_mps, vy_mps, vz_mps)"))
    columns = [("time_s", t[:, None])] + [(n, p[:, i:i + 1]) for i, n in enumerate(CSV_COLUMNS[1:4])]
    if v is not None:
        columns += [(n, v[:, i:i + 1]) for i, n in enumerate(CSV_COLUMNS[4:])]
    for name, values in columns:
        bad = ~np.isfinite(values[:, 0])
        if bad.any():
            i = int(np.argmax(bad))
            raise TrajectoryError(f"state vectors {sv.row(i)}, column {name}: {float(values[i, 0])!r} is not a finite "
                                  "number; every time, position and velocity must be finite")
    step = np.diff(t)
    if np.any(step <= 0):
        i = int(np.argmax(step <= 0)) + 1
        raise TrajectoryError(f"state vectors {sv.row(i)}, column time_s: {float(t[i])!r} s is not after the previous "
                              f"row's {float(t[i - 1])!r} s; times must increase strictly (sort the rows, drop duplicates)")
    median = float(np.median(step))
    if np.any(step > MAX_GAP_RATIO * median):
        i = int(np.argmax(step > MAX_GAP_RATIO * median)) + 1
        raise TrajectoryError(f"state vectors {sv.row(i)}, column time_s: a gap of {step[i - 1]:.6g} s after "
                              f"{float(t[i - 1])!r} s, more than {MAX_GAP_RATIO:g} times the median spacing {median:.6g} s: "
                              "the interpolant cannot bridge it (it would invent the motion in between); fill the "
                              "gap from the navigation data, or split the flight into two files")


def read_state_vectors(path: str | os.PathLike) -> StateVectors:
    """State vectors from a CSV file with the header ``time_s,x_m,y_m,z_m`` and optionally
    ``vx_mps,vy_mps,vz_mps`` (any column order; :data:`CSV_COLUMNS`), one row per sample.

    Raises
    ------
    TrajectoryError
        A missing or unreadable file, a header with unknown or missing columns, a row with the
        wrong number of fields or a field that is not a number, and the checks of
        :class:`StateVectors`; each names the file, the line and the column.
    """
    path = Path(path)
    name = path.name
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(f"trajectory = {str(path)!r}: cannot read the state vectors "
                              f"({getattr(exc, 'strerror', None) or exc}); give a CSV file with the header "
                              f"{','.join(CSV_COLUMNS[:4])}[,{','.join(CSV_COLUMNS[4:])}], or 'straight' or "
                              "'circular'") from None
    if not rows:
        raise TrajectoryError(f"state vectors {name}: the file is empty; line 1 must be the header "
                              f"{','.join(CSV_COLUMNS[:4])}[,{','.join(CSV_COLUMNS[4:])}]")
    header = [h.strip() for h in rows[0]]
    unknown = [h for h in header if h not in CSV_COLUMNS]
    missing = [c for c in CSV_COLUMNS[:4] if c not in header]
    some_velocity = [c for c in CSV_COLUMNS[4:] if c in header]
    if unknown or missing or len(set(header)) != len(header) or 0 < len(some_velocity) < 3:
        problem = (f"unknown column {unknown[0]!r}" if unknown else f"missing column {missing[0]!r}" if missing
                   else "a column named twice" if len(set(header)) != len(header) else
                   "velocity needs all of vx_mps, vy_mps, vz_mps")
        raise TrajectoryError(f"state vectors {name}, line 1 (header): {problem}; the header is "
                              f"{','.join(CSV_COLUMNS[:4])} and optionally {','.join(CSV_COLUMNS[4:])} (metres, "
                              "seconds, the scene frame)")
    values = np.empty((len(rows) - 1, len(header)))
    body = [(k, r) for k, r in enumerate(rows[1:], start=2) if any(field.strip() for field in r)]
    values = values[:len(body)]
    for i, (line, row) in enumerate(body):
        if len(row) != len(header):
            raise TrajectoryError(f"state vectors {name}, line {line}: {len(row)} fields, the header has "
                                  f"{len(header)}")
        for j, field in enumerate(row):
            try:
                values[i, j] = float(field)
            except ValueError:
                raise TrajectoryError(f"state vectors {name}, line {line}, column {header[j]}: {field.strip()!r} "
                                      "is not a number") from None
    col = {h: values[:, j] for j, h in enumerate(header)}
    velocity = np.stack([col[c] for c in CSV_COLUMNS[4:]], axis=1) if some_velocity else None
    lines = [line for line, _ in body]
    first = lines[0] if lines else 2
    if lines and lines != list(range(first, first + len(lines))):       # blank lines inside: name rows by index
        first = 0
    return StateVectors(col["time_s"], np.stack([col[c] for c in CSV_COLUMNS[1:4]], axis=1), velocity, name, first)


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
    """

    kind: str
    evaluate: Callable[[np.ndarray, int], np.ndarray]
    span: tuple[float, float] = (-math.inf, math.inf)
    nominal: "Trajectory | None" = None

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


def from_state_vectors(states: StateVectors) -> Trajectory:
    """The smooth interpolant of ``states``, eq. (J2): ``scipy.interpolate.CubicHermiteSpline``
    through positions and velocities, or ``CubicSpline`` (not-a-knot) through positions alone.
    Outside the samples it extrapolates its end polynomials (the echoes of the last pulses arrive
    a few milliseconds after it)."""
    from scipy.interpolate import CubicHermiteSpline, CubicSpline
    if states.velocity is not None:
        spline = CubicHermiteSpline(states.time, states.position, states.velocity, axis=0)
    else:
        spline = CubicSpline(states.time, states.position, axis=0)

    def evaluate(t: np.ndarray, k: int) -> np.ndarray:
        return np.asarray(spline(t, k), np.float64)
    return Trajectory("state vectors", evaluate, (float(states.time[0]), float(states.time[-1])))


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
    return Trajectory(nominal.kind + " + motion error", evaluate, nominal.span, nominal)


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
