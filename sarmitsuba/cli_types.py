"""The command line's argument types: each parses one option's text for argparse, whose error
names the option (exit code 2, no traceback)."""
from __future__ import annotations

import argparse
import math

__all__ = ["assignment", "resolution", "positive_int", "depth", "looks", "point", "numbers", "vectors", "index_range"]


def assignment(text: str) -> tuple[str, str]:
    """``NAME=VALUE`` (``--set``, ``--integrator-set``, ``--material-set``): the stripped (name,
    value) pair."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), value.strip()


def resolution(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels (``preview --resolution``), at least the preview's minimum."""
    from .products.preview import MIN_RESOLUTION
    width, sep, height = text.lower().partition("x")
    try:
        size = (int(width), int(height))
    except ValueError:
        size = (0, 0)
    if not sep or size[0] < MIN_RESOLUTION[0] or size[1] < MIN_RESOLUTION[1]:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, at least {MIN_RESOLUTION[0]}x"
                                         f"{MIN_RESOLUTION[1]} (two panels and a header), e.g. 960x720, got {text!r}")
    return size


def positive_int(text: str) -> int:
    """A whole number >= 1 (``preview --spp``)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def depth(text: str) -> "int | str":
    """``--max-depth``: ``auto`` or a whole number in [1, 64]."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= 64:
        raise argparse.ArgumentTypeError(f"expected auto (the depth the scene calls for) or a whole number of "
                                         f"bounce orders in [1, 64], got {text!r}")
    return value


def looks(text: str) -> tuple[int, int]:
    """``AZ,RG``: two whole numbers >= 1 (``interferogram --looks``)."""
    parts = text.split(",")
    try:
        looks = tuple(int(p) for p in parts)
    except ValueError:
        looks = ()
    if len(looks) != 2 or min(looks) < 1:
        raise argparse.ArgumentTypeError(f"expected AZ,RG: two whole numbers >= 1, e.g. 4,4, got {text!r}")
    return looks


def point(text: str) -> tuple[float, float, float]:
    """``X,Y,Z`` [m] as three floats, for argparse (its error names the option)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z in metres, got {text!r}")
    return values



def numbers(text: str) -> tuple[float, ...]:
    """``B1,B2,...``: finite floats (``stack --baselines``, metres)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if not values or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected finite numbers separated by commas, e.g. -6,-2,2,6, got {text!r}")
    return values


def vectors(text: str) -> tuple[tuple[float, float, float], ...]:
    """``X,Y,Z;X,Y,Z;...``: three finite floats each (``stack --track-offsets``, metres)."""
    try:
        return tuple(point(part) for part in text.split(";"))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z;X,Y,Z;... (three finite numbers in metres a pass, "
                                         f"passes separated by ';'), got {text!r}") from None


def index_range(text: str) -> slice:
    """``A:B``: whole numbers 0 <= A < B, either left out (``tomography --rows``, ``--cols``)."""
    first, sep, last = text.partition(":")
    try:
        start = int(first) if first.strip() else None
        stop = int(last) if last.strip() else None
    except ValueError:
        sep = ""
    if not sep or (start is not None and start < 0) or (start is not None and stop is not None and stop <= start):
        raise argparse.ArgumentTypeError(f"expected A:B with whole numbers 0 <= A < B (either may be left out), "
                                         f"got {text!r}")
    return slice(start, stop)
