"""The valid range of every radar and platform parameter with a unit, and the check that names
the unit when a value lies outside it: :data:`VALID_RANGES` (VHF to sub-THz radars, drones to
LEO / MEO platforms), :class:`ValidRange`, :class:`ParameterError` and :func:`check_ranges`,
which :class:`sarmitsuba.core.radar.RadarParameters` runs first on construction (docs/design.md
section 4); a value that looks written in another unit (9.6 for 9.6 GHz) gets the value meant.
"""
from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ParameterError", "ValidRange", "VALID_RANGES", "check_ranges", "unknown_name"]


class ParameterError(ValueError):
    """A radar, platform or tracer parameter is outside its valid range."""


@dataclass(frozen=True)
class ValidRange:
    """The valid range ``[lo, hi]`` of one :class:`~sarmitsuba.core.radar.RadarParameters` field, in ``unit``.

    ``note`` says what typical values look like; ``hints`` are the ``(power of ten, unit)``
    a value outside the range may have been written in (9.6 for 9.6 GHz): the first whose
    rescaled value lies in ``typical`` is suggested. ``zero`` marks a field where 0 means
    "off" (antenna dimensions); ``optional`` one that may be None.
    """

    unit: str
    lo: float
    hi: float
    note: str = ""
    hints: tuple[tuple[int, str], ...] = ()
    typical: tuple[float, float] = (0.0, 0.0)
    zero: bool = False
    optional: bool = False


_HZ_BAND = ((6, "MHz"), (9, "GHz"))
_ANTENNA = ValidRange("m", 0.0, 100.0, "0 = no pattern, else metres (airborne ~0.3-2 m, spaceborne ~5-15 m)",
                      ((-2, "cm"), (-3, "mm")), (0.1, 20.0), zero=True)

#: Valid range of every :class:`~sarmitsuba.core.radar.RadarParameters` field with a physical unit
#: (VHF to sub-THz radars, drones to LEO / MEO platforms), checked in the order given.
#: ``antenna_length`` and ``antenna_height`` must moreover exceed the wavelength (checked by
#: ``RadarParameters``); ``scene_center`` is checked per coordinate.
VALID_RANGES: dict[str, ValidRange] = {
    "frequency": ValidRange("Hz", 1e6, 1e12, "P band ~0.4e9, L 1.3e9, C 5.4e9, X 9.6e9, Ka 35e9",
                            ((9, "GHz"), (6, "MHz")), (1e8, 1e11)),
    "bandwidth": ValidRange("Hz", 1e5, 1e11, "typically 10e6 to 1e9", _HZ_BAND, (1e7, 1e10)),
    "sampling_rate": ValidRange("Hz", 1e5, 1e12, "at least the bandwidth; 0 = 1.2 x bandwidth", _HZ_BAND,
                                (1e7, 1e10)),
    "prf": ValidRange("Hz", 1.0, 1e7, "airborne ~100-2000, spaceborne ~1000-10000", ((3, "kHz"),), (10.0, 1e5)),
    "pulse_length": ValidRange("s", 1e-9, 0.1, "typically 1e-6 to 1e-4", ((-6, "us"), (-3, "ms"), (-9, "ns")),
                               (1e-7, 1e-3)),
    "velocity": ValidRange("m/s", 0.01, 1.2e4, "drones ~10, aircraft ~100-250, LEO satellites ~7600"),
    "altitude": ValidRange("m", 1.0, 4e7, "above the scene centre: drones ~100, aircraft 1e3-1.2e4, LEO ~7e5",
                           ((3, "km"),), (10.0, 4e7)),
    "antenna_length": _ANTENNA,
    "antenna_height": _ANTENNA,
    "scene_center": ValidRange("m", -1e8, 1e8, "three world coordinates x, y, z"),
    "track_offset": ValidRange("m", -1e5, 1e5, "a shift of the whole track: dx, dy, dz"),
    "heading": ValidRange("deg", -360.0, 360.0, "counter-clockwise from +x"),
    "transmit_power": ValidRange("W", 1e-6, 1e9, "peak power: drones ~1, aircraft ~100-1e4", optional=True),
    "noise_temperature": ValidRange("K", 1.0, 1e5, "290 K is room temperature", optional=True),
    "antenna_gain_db": ValidRange("dBi", -30.0, 80.0, "in dB: a linear gain G is 10 log10(G) dBi", optional=True),
    "losses_db": ValidRange("dB", 0.0, 100.0, "0 = lossless"),
    "noise_figure_db": ValidRange("dB", 0.0, 50.0, "typically 2-5 dB", optional=True),
}


def _number(x: float) -> str:
    """``x`` in short form, powers of ten as Python writes them: 1e6, 9.6e9, 1.2e4, 1e-5, 0.1, 250."""
    if x == 0 or 1e-3 <= abs(x) < 1e4:
        return f"{x:g}"
    mantissa, exponent = f"{x:.5e}".split("e")
    return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"


def _range_error(name: str, value: Any, spec: ValidRange) -> str:
    """The message for ``name = value`` outside ``spec``: range, unit, note and a unit hint."""
    span = f"[{_number(spec.lo)}, {_number(spec.hi)}] {spec.unit}"
    if not (isinstance(value, (int, float)) and math.isfinite(value)) or (value <= 0 < spec.lo):
        shown = _number(value) if isinstance(value, float) and math.isfinite(value) and abs(value) >= 1e4 else repr(value)
        return (f"{name} = {shown} must be a finite number > 0; valid range {span} "
                f"({name} is in {spec.unit}: {spec.note})")
    text = f"{name} = {_number(value)} {spec.unit} is outside the valid range {span}: {name} is in {spec.unit}"
    for power, unit in spec.hints:
        if spec.typical[0] <= value * 10.0 ** power <= spec.typical[1]:
            return f"{text}; did you mean {_number(value)}e{power} ({_number(value)} {unit})?"
    if name == "antenna_gain_db" and value > spec.hi:
        return f"{text}; a linear gain of {_number(value)} is {10.0 * math.log10(value):.1f} dBi"
    return f"{text} ({spec.note})"


def check_ranges(params: Any) -> None:
    """Check every field of :data:`VALID_RANGES` of ``params`` (a :class:`~sarmitsuba.core.radar.RadarParameters`);
    raises ParameterError with :func:`_range_error`'s message."""
    for name, spec in VALID_RANGES.items():
        value = getattr(params, name)
        if value is None and (spec.optional or name == "scene_center"):
            continue
        if name in ("scene_center", "track_offset"):
            if not (isinstance(value, (tuple, list, np.ndarray)) and len(value) == 3):
                raise ParameterError(f"{name} = {value!r} must be three finite numbers x, y, z [m]")
            for axis, coordinate in zip("xyz", value):
                if not (isinstance(coordinate, (int, float, np.floating)) and spec.lo <= coordinate <= spec.hi):
                    raise ParameterError(f"{name} = {tuple(value)}: {axis} = {coordinate!r} m is outside "
                                         f"the valid range [{_number(spec.lo)}, {_number(spec.hi)}] m ({spec.note})")
            continue
        if spec.zero and value == 0:
            continue
        if not (isinstance(value, (int, float)) and math.isfinite(value) and spec.lo <= value <= spec.hi):
            raise ParameterError(_range_error(name, value, spec))


def unknown_name(kind: str, name: str, valid: Iterable[str]) -> str:
    """The message for an unknown name: ``unknown KIND 'bandwith'; did you mean 'bandwidth'?
    valid: ...``, the closest valid names first (``difflib.get_close_matches``, ratio >= 0.6,
    at most three), then all of them. Without a close match the question is left out.

    Parameters
    ----------
    kind : str
        What the name names, e.g. ``"sar sensor parameter"``.
    name : str
        The name given.
    valid : iterable of str
        Every valid name, listed in the given order.
    """
    valid = [str(v) for v in valid]
    close = difflib.get_close_matches(str(name), valid, n=3)
    if not close:
        close = difflib.get_close_matches(str(name).lower(), [v.lower() for v in valid], n=3)
        close = [v for v in valid if v.lower() in close]
    question = f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ""
    return f"unknown {kind} {name!r}; {question}valid: {', '.join(valid)}"

