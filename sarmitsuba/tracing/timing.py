"""The stage clock of the launch a thread is tracing, for the code below the driver: a ray cast
charges its time to the ``casts`` section of the mesh tracer's clock
(:class:`sarmitsuba.tracing.driver.stages.StageClock`), wherever in the stages it runs, so that
``trace_stages`` tells the casts from the geometry around them (docs/design.md section 10).

The clock is kept per thread: launches traced on several host threads
(:mod:`sarmitsuba.tracing.driver.threads`) each charge their own. Outside :func:`charged_to`
(a cast outside a mesh trace: the tube preview, the ground truth) :func:`section` times nothing.
"""
from __future__ import annotations

import contextlib
import threading

__all__ = ["charged_to", "section"]

_LOCAL = threading.local()


@contextlib.contextmanager
def charged_to(clock):
    """Within it, :func:`section` on this thread opens sections of ``clock`` (a callable
    ``clock(name)`` giving a context manager, as a StageClock is); the thread's previous clock
    comes back on leaving."""
    before = getattr(_LOCAL, "clock", None)
    _LOCAL.clock = clock
    try:
        yield
    finally:
        _LOCAL.clock = before


def section(name: str):
    """A context manager that times its body as section ``name`` of this thread's clock
    (:func:`charged_to`), or does nothing where the thread has none."""
    clock = getattr(_LOCAL, "clock", None)
    return contextlib.nullcontext() if clock is None else clock(name)
