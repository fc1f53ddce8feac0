"""State vectors: the sampled antenna states of a flight, their clock and frame, and the files they
come in (docs/physics.md (J2), (J5), (J6)).

- :class:`StateVectors`: times, positions and optionally velocities, with an absolute clock
  (:attr:`~StateVectors.epoch`) and a frame (the scene's, or WGS84 ECEF) when the file says so;
- :func:`read_state_vectors`: a CSV file (``time_s,x_m,y_m,z_m[,vx_mps,vy_mps,vz_mps]``, or
  ``utc`` in place of ``time_s``; ``# frame``, ``# epoch``, ``# time_scale`` header lines) or a
  Sentinel-1 orbit file (:func:`read_eof`);
- GPS time to UTC with the leap seconds of :data:`LEAP_SECONDS` (J5).

:mod:`sarmitsuba.core.trajectory` interpolates them and re-exports these names.
"""
from __future__ import annotations

import csv
import datetime
import math
import os
import re
from decimal import Decimal
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from .valid_ranges import ParameterError

__all__ = ["StateVectors", "TrajectoryError", "read_state_vectors", "read_eof", "utc_instant", "gps_minus_utc",
           "CSV_COLUMNS", "CSV_KEYS", "FRAMES", "MAX_GAP_RATIO", "HERMITE_WINDOW", "GPS_EPOCH", "LEAP_SECONDS",
           "GPS_TABLE_VALID_UNTIL", "GPS_TABLE_GRACE", "MAX_ABS_SECONDS", "LeapSecondWarning", "check_no_leap_second"]


class TrajectoryError(ParameterError):
    """State vectors or a trajectory setting that cannot describe a flight (names the row and column)."""


class LeapSecondWarning(UserWarning):
    """GPS times past the leap-second table's last bulletin, converted with its last value."""


#: Header of a state-vector CSV: time and position, then optionally velocity (docs/physics.md (J2)).
CSV_COLUMNS = ("time_s", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
#: Frames state vectors may be given in: the scene's own, or WGS84 ECEF (EPSG:4978).
FRAMES = ("scene", "ecef")
#: A gap between consecutive state vectors longer than this many times their median spacing is refused:
#: the spline would invent the motion in between.
MAX_GAP_RATIO = 5.0
#: Samples in the local Hermite interpolation of ECEF state vectors (J6): the two on each side.
HERMITE_WINDOW = 4


# ============================================================================ state vectors
@dataclass(frozen=True)
class StateVectors:
    """Sampled antenna states: the navigation data of a flight (docs/physics.md (J2)).

    Attributes
    ----------
    time : float64 [n], s
        Strictly increasing sample times.
    position : float64 [n, 3], m
        Antenna phase centre in the scene frame (z up), or WGS84 ECEF when ``frame`` is ``"ecef"``.
    velocity : float64 [n, 3], m/s, or None
        Velocity at each sample; with it the interpolant is a cubic Hermite spline.
    source : str
        Where they came from, for messages and metadata: a CSV file's name, or ``"python"``.
    first_line : int
        The file line of sample 0 (0: name samples by row index in messages).
    epoch : str or None
        Absolute time (docs/physics.md (J5)): the UTC instant of ``time = 0``, ISO 8601
        (``"2026-11-24T10:00:00.000000+00:00"``); None: the clock is relative (the default).
    frame : str
        ``"scene"`` (the scene's local frame, z up) or ``"ecef"`` (WGS84 Earth-centred
        Earth-fixed, EPSG:4978); :func:`sarmitsuba.core.orbit.in_scene_frame` carries ECEF states
        into the scene's east-north-up frame at ``geo_origin``.
    window : int
        0: the spline of :func:`from_state_vectors` through all samples; ``m >= 2``: the local
        Hermite interpolation of precise orbits over ``m`` neighbouring samples (needs velocities;
        :func:`sarmitsuba.core.trajectory.hermite_window`, (J6)).
    closest_approach : bool
        Whether the pulses are centred on the closest approach to the scene centre (an orbit,
        whose span is far longer than the aperture) rather than on the middle of the span.

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
    epoch: str | None = None
    frame: str = "scene"
    window: int = 0
    closest_approach: bool = False

    def __post_init__(self) -> None:
        for name in ("time", "position", "velocity"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.array(value, dtype=np.float64))
        if self.frame not in FRAMES:
            raise TrajectoryError(f"state vectors {self.source}: frame = {self.frame!r}; valid frames are "
                                  f"{', '.join(repr(f) for f in FRAMES)}")
        if self.epoch is not None:
            object.__setattr__(self, "epoch", utc_instant(self.epoch, f"state vectors {self.source}: epoch").isoformat())
        if self.window and (self.velocity is None or self.window < 2):
            raise TrajectoryError(f"state vectors {self.source}: a Hermite window of {self.window} samples needs "
                                  "velocities and at least 2 samples (window = 0 for the spline)")
        _check_states(self)

    def utc(self, t: Any) -> "datetime.datetime":
        """The UTC instant (aware datetime, microseconds) of time ``t`` [s] of this clock, eq. (J5).
        Raises TrajectoryError when the states have no :attr:`epoch` (a relative clock)."""
        if self.epoch is None:
            raise TrajectoryError(f"state vectors {self.source}: the times are relative (no epoch), so they name no "
                                  "UTC instant; give a utc column or an '# epoch = ...' header line")
        return datetime.datetime.fromisoformat(self.epoch) + datetime.timedelta(seconds=float(t))

    def row(self, i: int) -> str:
        """How messages name sample ``i``: ``FILE, line N`` for a file, else ``SOURCE, row i``."""
        if self.first_line:
            return f"{self.source}, line {self.first_line + i}"
        return f"{self.source}, row {i}"

    def shifted(self, offset: np.ndarray) -> "StateVectors":
        """The same states with ``offset`` [m] subtracted from every position (a local frame)."""
        return replace(self, position=self.position - np.asarray(offset, float))

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


#: The GPS time scale's origin, 1980-01-06T00:00:00 UTC (GPS and UTC agreed then).
GPS_EPOCH = datetime.datetime(1980, 1, 6, tzinfo=datetime.timezone.utc)
#: The UTC days that began after a leap second since GPS_EPOCH (IERS Bulletin C; TAI - UTC rose by
#: 1 s at each): GPS - UTC is the number of them at or before a time, 18 s since 2017-01-01.
LEAP_SECONDS = tuple(datetime.datetime(y, m, 1, tzinfo=datetime.timezone.utc) for y, m in (
    (1981, 7), (1982, 7), (1983, 7), (1985, 7), (1988, 1), (1990, 1), (1991, 1), (1992, 7), (1993, 7), (1994, 7),
    (1996, 1), (1997, 7), (1999, 1), (2006, 1), (2009, 1), (2012, 7), (2015, 7), (2017, 1)))
#: The table is known up to this UTC instant: IERS Bulletin C 70 (July 2025) announced no leap
#: second at the end of December 2025, and no later bulletin is in :data:`LEAP_SECONDS`. Later GPS
#: times are converted with the table's last value and a :class:`LeapSecondWarning` says so.
GPS_TABLE_VALID_UNTIL = datetime.datetime(2026, 1, 1, tzinfo=datetime.timezone.utc)
#: GPS times up to this long past :data:`GPS_TABLE_VALID_UNTIL` are converted with a warning (a leap
#: second is announced six months ahead, and none has been since 2017); later ones are refused.
GPS_TABLE_GRACE = datetime.timedelta(days=366)
#: Absolute times (seconds from an epoch, GPS seconds) must lie within this many seconds (317 years):
#: beyond it no date is meant, and Python's datetime overflows.
MAX_ABS_SECONDS = 1e10
#: Header keys of a state-vector CSV (``# key = value`` lines before the column header).
CSV_KEYS = ("frame", "epoch", "time_scale")
_CSV_FORM = (f"the header {','.join(CSV_COLUMNS[:4])}[,{','.join(CSV_COLUMNS[4:])}] (or utc in place of time_s), "
             "after optional lines '# frame = scene|ecef', '# epoch = ISO 8601 UTC', '# time_scale = gps'")


def utc_instant(text: Any, where: str, advice: str = "give a UTC time as ISO 8601 with an offset, e.g. "
                "2026-11-24T10:00:00.250Z") -> datetime.datetime:
    """An ISO 8601 time with a UTC offset (``Z`` or ``+hh:mm``) as an aware UTC datetime (microseconds).
    Raises TrajectoryError naming ``where``, followed by ``advice``, for anything else, a time
    without an offset included (it would be read in the machine's own zone)."""
    if isinstance(text, datetime.datetime):
        when, extra = text, 0
    else:
        # digits beyond the microsecond (GNSS logs give nanoseconds) are rounded, not cut as
        # datetime.fromisoformat cuts them
        given = str(text).strip()
        match = re.search(r"T\d\d:?\d\d:?\d\d[.,](\d{7,})", given)
        extra = 0
        if match:
            micro = int((Decimal("0." + match.group(1)) * 10 ** 6).to_integral_value(rounding="ROUND_HALF_EVEN"))
            extra = micro - int(match.group(1)[:6])
            given = given[:match.start(1)] + match.group(1)[:6] + given[match.end(1):]
        try:
            when = datetime.datetime.fromisoformat(given)
        except ValueError:
            when = None
    if when is None or when.tzinfo is None:
        leap = re.search(r"T\d\d:?\d\d:?60", str(text))
        problem = ("is a leap second (hh:mm:60), which no interpolant over UTC can hold" if leap and when is None else
                   "has no UTC offset" if when is not None else "is not an ISO 8601 time")
        raise TrajectoryError(f"{where}: {str(text).strip()!r} {problem}; {advice}")
    return when.astimezone(datetime.timezone.utc) + datetime.timedelta(microseconds=extra)


def check_no_leap_second(first: datetime.datetime, last: datetime.datetime, where: str) -> None:
    """Refuse UTC times ``first`` .. ``last`` that span a leap second (:data:`LEAP_SECONDS`): UTC
    differences there count one physical second too few, and an interpolant over them would put
    the platform kilometres off. Raises TrajectoryError naming ``where`` and the leap second."""
    for day in LEAP_SECONDS:
        if first < day <= last:
            raise TrajectoryError(f"{where}: the times {first.isoformat()} .. {last.isoformat()} span the leap second "
                                  f"before {day.isoformat()}, where UTC differences miss one second; split the file "
                                  "there (one part on each side)")


def gps_minus_utc(utc: datetime.datetime) -> int:
    """GPS - UTC [s] at the UTC instant ``utc``: the leap seconds of :data:`LEAP_SECONDS` up to it."""
    return sum(1 for day in LEAP_SECONDS if utc >= day)


def _gps_epoch(first: float, last: float, where: str) -> tuple[datetime.datetime, int]:
    """(UTC instant of GPS second 0 for this span, leap seconds) for GPS seconds ``first``..``last``
    since :data:`GPS_EPOCH`, eq. (J5): ``UTC = GPS_EPOCH + t - (GPS - UTC)``. Refuses a span that
    crosses a leap second or lies outside :data:`GPS_EPOCH` .. :data:`GPS_TABLE_VALID_UNTIL`."""
    def utc_of(t: float) -> tuple[datetime.datetime, int]:
        guess = GPS_EPOCH + datetime.timedelta(seconds=t)
        leap = gps_minus_utc(guess - datetime.timedelta(seconds=gps_minus_utc(guess)))
        return guess - datetime.timedelta(seconds=leap), leap
    if first < 0:
        raise TrajectoryError(f"{where}: GPS seconds {first:.6f} .. {last:.6f} begin before the GPS epoch "
                              "1980-01-06T00:00:00Z; give GPS seconds since it, or the times as UTC (a utc column, "
                              "or '# epoch = ...' with time_s)")
    lo, leap = utc_of(first)
    hi, leap_hi = utc_of(last)
    if hi >= GPS_TABLE_VALID_UNTIL + GPS_TABLE_GRACE:
        raise TrajectoryError(f"{where}: GPS seconds {first:.6f} .. {last:.6f} reach {hi.date()}, more than a year "
                              f"past the leap-second table's last bulletin ({GPS_TABLE_VALID_UNTIL.date()}, GPS - UTC "
                              "= 18 s since 2017-01-01); give the times as UTC instead (a utc column, or "
                              "'# epoch = ...' with time_s)")
    if hi >= GPS_TABLE_VALID_UNTIL:
        import warnings
        warnings.warn(f"{where}: GPS times up to {hi.isoformat()} lie past the leap-second table's last bulletin "
                      f"({GPS_TABLE_VALID_UNTIL.date()}); converted with GPS - UTC = {leap_hi} s, which holds unless "
                      "IERS Bulletin C has announced a leap second since: check it, or give UTC times",
                      LeapSecondWarning, stacklevel=2)
    if leap_hi != leap:
        raise TrajectoryError(f"{where}: the GPS times cross a leap second ({lo.isoformat()} .. {hi.isoformat()}), "
                              "where UTC repeats a second; split the file at the leap second, or give UTC times")
    return GPS_EPOCH - datetime.timedelta(seconds=leap), leap


def _header_lines(rows: list[list[str]], name: str) -> tuple[dict[str, str], int]:
    """The ``# key = value`` (or ``# key: value``) lines before a CSV's column header, checked
    (:data:`CSV_KEYS`, their values): (keys, number of lines)."""
    keys: dict[str, str] = {}
    skip = 0
    while skip < len(rows) and rows[skip] and rows[skip][0].lstrip().startswith("#"):
        line = ",".join(rows[skip]).lstrip()[1:].strip()
        skip += 1
        if not line:
            continue
        key, sep, value = line.partition("=") if "=" in line else line.partition(":")
        key, value = key.strip().lower(), value.strip()
        if not sep or key not in CSV_KEYS or key in keys:
            raise TrajectoryError(f"state vectors {name}, line {skip}: {line!r} is "
                                  + ("a key given twice" if key in keys else "no known header line")
                                  + f"; give {_CSV_FORM}")
        keys[key] = value
    frame, scale = keys.get("frame", "scene").lower(), keys.get("time_scale", "utc").lower()
    if frame not in FRAMES or scale not in ("utc", "gps") or (scale == "gps" and "epoch" in keys):
        bad = ("frame", frame) if frame not in FRAMES else ("time_scale", scale)
        fix = ("GPS seconds count from 1980-01-06T00:00:00Z: remove '# epoch'" if scale == "gps" and "epoch" in keys
               else f"valid values are {', '.join(FRAMES) if bad[0] == 'frame' else 'utc, gps'}")
        raise TrajectoryError(f"state vectors {name}: header line {bad[0]} = {bad[1]!r}; {fix}")
    return keys, skip


def _check_header(header: list[str], name: str, line: int) -> None:
    """Refuse a column header with unknown, missing or repeated columns, part of a velocity, or two clocks."""
    unknown = [h for h in header if h not in ("utc",) + CSV_COLUMNS]
    missing = ([] if "time_s" in header or "utc" in header else ["time_s"]) + [c for c in CSV_COLUMNS[1:4]
                                                                               if c not in header]
    some_velocity = [c for c in CSV_COLUMNS[4:] if c in header]
    if unknown or missing or len(set(header)) != len(header) or 0 < len(some_velocity) < 3 or \
            ("utc" in header and "time_s" in header):
        problem = (f"unknown column {unknown[0]!r}" if unknown else f"missing column {missing[0]!r}" if missing
                   else "a column named twice" if len(set(header)) != len(header) else
                   "both utc and time_s (give one clock)" if "utc" in header and "time_s" in header else
                   "velocity needs all of vx_mps, vy_mps, vz_mps")
        raise TrajectoryError(f"state vectors {name}, line {line} (header): {problem}; the header is "
                              f"{','.join(CSV_COLUMNS[:4])} and optionally {','.join(CSV_COLUMNS[4:])} (metres, "
                              "seconds, the scene frame unless '# frame = ecef'), utc in place of time_s for "
                              "ISO 8601 UTC times")


def _absolute_times(stamps: list[Any], clock: str, scale: str, epoch: datetime.datetime | None,
                    name: str) -> tuple[np.ndarray, datetime.datetime]:
    """(float64 seconds from the epoch, the epoch) of a file's absolute times, re-based exactly: the
    whole seconds move into the epoch, the rest stays in float64 seconds (docs/physics.md (J5))."""
    if clock == "utc":
        check_no_leap_second(min(stamps), max(stamps), f"state vectors {name}, column utc")
        epoch = stamps[0].replace(microsecond=0)
        return np.array([(s - epoch) / datetime.timedelta(microseconds=1) * 1e-6 for s in stamps]), epoch
    if scale == "gps":
        epoch, _ = _gps_epoch(float(stamps[0]), float(stamps[-1]), f"state vectors {name}, column time_s")
    whole = int(stamps[0].to_integral_value(rounding="ROUND_FLOOR"))
    return np.array([float(s - whole) for s in stamps]), epoch + datetime.timedelta(seconds=whole)


def read_state_vectors(path: str | os.PathLike) -> StateVectors:
    """State vectors from a CSV file with the header ``time_s,x_m,y_m,z_m`` and optionally
    ``vx_mps,vy_mps,vz_mps`` (any column order; :data:`CSV_COLUMNS`), one row per sample, or
    a Sentinel-1 orbit file (XML; :func:`sarmitsuba.core.orbit.read_eof`).

    Lines before the column header that start with ``#`` may say (``# key = value``, :data:`CSV_KEYS`):

    - ``# frame = ecef``: positions and velocities are WGS84 ECEF (EPSG:4978), not the scene's
      frame (default ``scene``); with velocities they are interpolated as precise orbits are (J6),
      without them by the cubic spline of (J2);
    - ``# epoch = 2026-11-24T10:00:00Z``: ``time_s`` counts seconds from this UTC instant (J5);
    - ``# time_scale = gps``: ``time_s`` counts GPS seconds since 1980-01-06T00:00:00Z, turned into
      UTC with the leap seconds of :data:`LEAP_SECONDS` (J5).

    A column ``utc`` of ISO 8601 times with an offset may replace ``time_s`` (absolute times). With
    absolute times the clock is re-based to a whole second of the given clock at or before the first
    row (with ``# epoch``, whole seconds from that epoch, which may have a fraction; the
    :attr:`StateVectors.epoch` records the instant of time 0, to the microsecond; (J5)).

    Raises
    ------
    TrajectoryError
        A missing or unreadable file, an unknown or malformed header line, a header with unknown
        or missing columns, a row with the wrong number of fields or a field that is not a number
        (or no ISO 8601 UTC time), and the checks of :class:`StateVectors`; each names the file,
        the line and the column.
    """
    from decimal import InvalidOperation
    path = Path(path)
    name = path.name
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:       # -sig: a spreadsheet's byte-order mark
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(f"trajectory = {str(path)!r}: cannot read the state vectors "
                              f"({getattr(exc, 'strerror', None) or exc}); give a CSV file with {_CSV_FORM}, a "
                              "Sentinel-1 orbit file (EOF), or 'straight', 'circular' or 'orbit'") from None
    if text.lstrip().startswith("<"):
        return read_eof(path)
    rows = list(csv.reader(text.splitlines()))
    keys, skip = _header_lines(rows, name)
    frame = keys.get("frame", "scene").lower()
    scale = keys.get("time_scale", "utc").lower()
    epoch = utc_instant(keys["epoch"], f"state vectors {name}, header line epoch") if "epoch" in keys else None
    rows = rows[skip:]
    if not rows:
        raise TrajectoryError(f"state vectors {name}: the file has no column header; line {skip + 1} must be "
                              f"{_CSV_FORM}")
    header = [h.strip() for h in rows[0]]
    _check_header(header, name, skip + 1)
    some_velocity = [c for c in CSV_COLUMNS[4:] if c in header]
    if "utc" in header and (epoch is not None or scale == "gps"):
        raise TrajectoryError(f"state vectors {name}: a utc column and an '# epoch' or '# time_scale' line both set the "
                              "clock; remove the header line")
    clock = "utc" if "utc" in header else "time_s"
    absolute = clock == "utc" or epoch is not None or scale == "gps"
    body = [(k, r) for k, r in enumerate(rows[1:], start=skip + 2) if any(field.strip() for field in r)]
    values = np.empty((len(body), len(header)))
    stamps: list[Any] = []
    for i, (line, row) in enumerate(body):
        if len(row) != len(header):
            raise TrajectoryError(f"state vectors {name}, line {line}: {len(row)} fields, the header has "
                                  f"{len(header)}")
        for j, field in enumerate(row):
            if header[j] == clock and absolute:
                where = f"state vectors {name}, line {line}, column {clock}"
                if clock == "utc":
                    stamps.append(utc_instant(field, where))
                    values[i, j] = 0.0
                    continue
                try:
                    stamp = Decimal(field.strip())
                except InvalidOperation:
                    raise TrajectoryError(f"{where}: {field.strip()!r} is not a number") from None
                try:
                    bounded = stamp.is_finite() and stamp.copy_abs() < Decimal(MAX_ABS_SECONDS)
                except ArithmeticError:                 # decimal.Overflow of an exponent like 1e999999999
                    bounded = False
                if not bounded:
                    raise TrajectoryError(f"{where}: {field.strip()!r} is not a finite time within +-{MAX_ABS_SECONDS:g} "
                                          "s of the epoch; give seconds from the '# epoch' (or GPS seconds)")
                stamps.append(stamp)
            try:
                values[i, j] = float(field)
            except ValueError:
                raise TrajectoryError(f"state vectors {name}, line {line}, column {header[j]}: {field.strip()!r} "
                                      "is not a number") from None
    col = {h: values[:, j] for j, h in enumerate(header)}
    time = col.get("time_s")
    if absolute and stamps:
        time, epoch = _absolute_times(stamps, clock, scale, epoch, name)
    velocity = np.stack([col[c] for c in CSV_COLUMNS[4:]], axis=1) if some_velocity else None
    lines = [line for line, _ in body]
    first = lines[0] if lines else skip + 2
    if lines and lines != list(range(first, first + len(lines))):       # blank lines inside: name rows by index
        first = 0
    if time is None:
        time = np.zeros(0)
    return StateVectors(time, np.stack([col[c] for c in CSV_COLUMNS[1:4]], axis=1), velocity, name, first,
                        epoch=None if epoch is None else epoch.isoformat(), frame=frame,
                        window=HERMITE_WINDOW if frame == "ecef" and velocity is not None else 0,
                        closest_approach=frame == "ecef")


_EOF_FIX = ("a Sentinel-1 orbit file holds Earth_Explorer_File/Data_Block/List_of_OSVs/OSV elements, each with "
            "UTC=YYYY-MM-DDThh:mm:ss.ffffff, X, Y, Z [m] and VX, VY, VZ [m/s] in the Earth-fixed frame")


# ============================================================================ orbit files
def read_eof(path: Any) -> StateVectors:
    """The orbit state vectors of a Sentinel-1 orbit file (ESA Earth Explorer XML; the EOF files
    ``S1?_OPER_AUX_POEORB_*`` and ``AUX_RESORB``), in ECEF with their UTC clock (eq. (J5)):
    ``time`` seconds from :attr:`~StateVectors.epoch` (the first OSV's whole second), positions
    [m], velocities [m/s]; interpolated by :func:`~sarmitsuba.core.trajectory.hermite_window`, pulses centred on the closest
    approach. ``Variable_Header/Ref_Frame`` must be ``EARTH_FIXED`` when present.

    Raises
    ------
    TrajectoryError
        Not XML, not this layout, a frame other than EARTH_FIXED, an OSV without a UTC time or a
        coordinate, a unit other than m and m/s, or a value that is not a finite number: names
        the file, the line and the element, and the layout expected.
    """
    import lxml.etree
    path = Path(path)
    name = path.name
    try:
        root = lxml.etree.parse(str(path), lxml.etree.XMLParser(resolve_entities=False, no_network=True)).getroot()
    except (OSError, lxml.etree.XMLSyntaxError) as exc:
        raise TrajectoryError(f"orbit file {name}: not readable as XML ({exc}); {_EOF_FIX}") from None
    if lxml.etree.QName(root).localname != "Earth_Explorer_File":
        raise TrajectoryError(f"orbit file {name}, line {root.sourceline}: the root element is "
                              f"<{lxml.etree.QName(root).localname}>, not <Earth_Explorer_File>; {_EOF_FIX}")
    frame = root.find(".//{*}Variable_Header/{*}Ref_Frame")
    if frame is None:
        frame = root.find(".//Variable_Header/Ref_Frame")
    if frame is not None and (frame.text or "").strip().upper() != "EARTH_FIXED":
        raise TrajectoryError(f"orbit file {name}, line {frame.sourceline}: Ref_Frame {(frame.text or '').strip()!r}; "
                              "only EARTH_FIXED (ECEF) state vectors are read: convert the orbit to the Earth-fixed frame")
    osvs = [e for e in root.iter() if isinstance(e.tag, str) and lxml.etree.QName(e).localname == "OSV"]
    if not osvs:
        raise TrajectoryError(f"orbit file {name}: no <OSV> element; {_EOF_FIX}")
    stamps, values = [], np.empty((len(osvs), 6))
    units = {"X": "m", "Y": "m", "Z": "m", "VX": "m/s", "VY": "m/s", "VZ": "m/s"}
    for i, osv in enumerate(osvs):
        child = {lxml.etree.QName(c).localname: c for c in osv if isinstance(c.tag, str)}
        if "UTC" not in child:
            raise TrajectoryError(f"orbit file {name}, line {osv.sourceline}: this OSV has no <UTC>; {_EOF_FIX}")
        text = (child["UTC"].text or "").strip()
        text = text[4:] if text.upper().startswith("UTC=") else text
        stamps.append(utc_instant(text if text.endswith("Z") or "+" in text[10:] else text + "Z",
                                  f"orbit file {name}, line {child['UTC'].sourceline}, <UTC>"))
        for j, (tag, unit) in enumerate(units.items()):
            element = child.get(tag)
            where = f"orbit file {name}, line {osv.sourceline if element is None else element.sourceline}, <{tag}>"
            if element is None:
                raise TrajectoryError(f"{where}: missing in this OSV; {_EOF_FIX}")
            given = element.get("unit", unit)
            if given != unit:
                raise TrajectoryError(f"{where}: unit {given!r}, expected {unit!r}; convert the orbit to metres and "
                                      "metres per second")
            try:
                values[i, j] = float(element.text)
            except (TypeError, ValueError):
                values[i, j] = math.nan
            if not math.isfinite(values[i, j]):
                raise TrajectoryError(f"{where}: {element.text!r} is not a finite number")
    check_no_leap_second(min(stamps), max(stamps), f"orbit file {name}")
    epoch = stamps[0].replace(microsecond=0)
    time = np.array([(s - epoch) / datetime.timedelta(microseconds=1) * 1e-6 for s in stamps])
    return StateVectors(time, values[:, :3], values[:, 3:], name, 0, epoch=epoch.isoformat(), frame="ecef",
                        window=HERMITE_WINDOW, closest_approach=True)
