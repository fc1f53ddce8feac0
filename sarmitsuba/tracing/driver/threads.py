"""Launches traced at once on host threads (:func:`sarmitsuba.tracing.driver.trace.trace`).

The mesh tracer's host geometry is NumPy, which releases the GIL in its array operations, so
launches traced on two threads keep both cores of a 2-core machine busy; each then holds half the
sub-apertures, so the peak memory stays that of one launch. Measured on Munich's default render
(2 cores): trace 89.0 s on one thread, 75.7 s on two (1.07 GB peak against 1.18 GB), 67.1 s with
launches of two sub-apertures each (1.36 GB).

It is off by default (one launch at a time): a race between the threads is not understood.
Without serialising Dr.Jit's symbolic loops, a threaded render of Munich differed from itself at
-53 to -70 dB. With every symbolic loop the mesh tracer records holding
:data:`sarmitsuba.tracing.loops.RECORDING` (the per-pulse terms with the rough surfaces'
scatterers, the geometry kernels), a threaded trace of ``urban`` matched the sequential one in 36
runs of 36 and the whole test suite passed with two threads; but with the scatterers' NumPy moved
out of the lock, a few pulses again differed (by up to 4e-5 of their power) in 8 runs of 10. So
the lock narrows a window rather than closing a known race. Set :data:`HOST_THREADS_VARIABLE` to 2
to try it (``tests/test_host_threads.py`` marks the comparison as an expected failure).
"""
from __future__ import annotations

import os

import numpy as np

from ...core.radar import ParameterError
from ..loops import lane_float, loop_mode

__all__ = ["HOST_THREADS", "HOST_THREADS_VARIABLE", "host_threads", "launches_at_once"]

#: The environment variable that sets how many launches the mesh tracer traces at once, each on
#: its own host thread (an integer >= 1; default :data:`HOST_THREADS`, at most the machine's cores).
HOST_THREADS_VARIABLE = "SARMITSUBA_HOST_THREADS"
#: Launches traced at once by default.
HOST_THREADS = 1


def host_threads(kernel) -> int:
    """Launches :func:`~sarmitsuba.tracing.driver.trace.trace` runs at once on host threads: 1 for the tube
    preview, for batches traced elsewhere (``kernel`` None), inside the derivatives' traces (their
    loop mode and lane precision are per thread) and on one core; else :data:`HOST_THREADS_VARIABLE`
    or :data:`HOST_THREADS`, at most the cores. Raises ParameterError for a variable that is not
    an integer >= 1."""
    if kernel is None or kernel.mesh is None or loop_mode() is not None or lane_float() is not np.float32:
        return 1
    return launches_at_once()


def launches_at_once() -> int:
    """The mesh tracer's launches at once (:data:`HOST_THREADS_VARIABLE`, or :data:`HOST_THREADS`; at
    most the cores), as :func:`host_threads` gives them to a render and the cost model counts them.
    Raises ParameterError for a variable that is not an integer >= 1."""
    text = os.environ.get(HOST_THREADS_VARIABLE, "")
    if text:
        try:
            wanted = int(text)
        except ValueError:
            wanted = 0
        if wanted < 1:
            raise ParameterError(f"{HOST_THREADS_VARIABLE}={text!r}: expected an integer >= 1 (launches traced at "
                                 f"once); unset it for the default, {HOST_THREADS}")
    else:
        wanted = HOST_THREADS
    return max(1, min(wanted, os.cpu_count() or 1))
