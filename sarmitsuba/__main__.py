"""``python -m sarmitsuba``: see :mod:`sarmitsuba.cli`."""
import sys

from .cli import main

sys.exit(main())
