"""``python -m sarmitsuba``: see :mod:`sarmitsuba.cli`."""
import sys

from .cli import run

sys.exit(run())
