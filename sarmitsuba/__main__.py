"""``python -m sarmitsuba``: see :mod:`sarmitsuba.cli`."""
import sys

from .cli import run

if __name__ == "__main__":          # importing the module (autodoc) runs nothing
    sys.exit(run())
