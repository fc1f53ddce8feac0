"""Launches traced at once on host threads (:func:`sarmitsuba.tracing.driver.trace.trace`).

The mesh tracer's host geometry is NumPy, which releases the GIL in its array operations, so
launches traced on two threads keep both cores of a 2-core machine busy; each then holds half the
sub-apertures, so the peak memory stays that of one launch. Measured on Munich's default render
(2 cores, one run each): trace 110.3 s on one thread, 85.1 s on two (peak RSS 1.14 GB against
1.08 GB). The raw data are the same bit for bit, on Munich and ``urban``, as with launches of any
other size: a sub-aperture's terms depend on it alone, not on the others in its launch (once
within -53.3 dB on Munich, when :func:`~sarmitsuba.tracing.visibility.occlusion.lit_boundary`
offset each edge's intervals by the edge's index in the launch).

With several threads the histogram's deposit adds atomically
(:meth:`sarmitsuba.tracing.deposit.accumulate.Accumulator.shared_by`): with Dr.Jit's
``ReduceMode.Expand`` two host threads that wait on Dr.Jit at once both run deposit blocks as
pool worker 0 and add into the same copy without atomics (before that was found, a few pulses of
a threaded trace lost up to 4e-5 of their power). Set :data:`HOST_THREADS_VARIABLE` to 1 to
trace one launch at a time.

While several host threads trace, Dr.Jit's pool keeps workers only on the cores they leave free
(:func:`kernel_workers`, :func:`kernel_pool`): a host thread that waits on Dr.Jit runs the blocks
itself. Munich, 512 pulses, fused geometry, 2 cores, runs alternated: trace 29.4 s (mean of three)
with the default pool against 26.9 s with no workers; on a quieter machine 25.3 s against 24.4 s,
and 25.8 s on one host thread. Without workers a kernel runs inside the evaluation that launched
it, under Dr.Jit's lock, so another host thread's Dr.Jit call waits for it, holding the GIL
(py-spy: 3.3 s of that trace in :func:`~sarmitsuba.tracing.device.device_array`): on two cores
two host threads gain little on the fused path, whose kernels already use both cores. The raw
data do not change: blocks are the same whichever thread runs them.
"""
from __future__ import annotations

import contextlib
import os

import drjit as dr
import numpy as np

from ...core.radar import ParameterError
from ..loops import lane_float, loop_mode

__all__ = ["HOST_THREADS", "HOST_THREADS_VARIABLE", "host_threads", "launches_at_once", "usable_cores", "count_variable", "kernel_workers",
           "kernel_pool", "caused_by_interrupt"]

#: The environment variable that sets how many launches the mesh tracer traces at once, each on
#: its own host thread (an integer >= 1; default :data:`HOST_THREADS`, at most the machine's cores).
HOST_THREADS_VARIABLE = "SARMITSUBA_HOST_THREADS"
#: Launches traced at once by default (at most the machine's cores).
HOST_THREADS = 2


def host_threads(kernel) -> int:
    """Launches :func:`~sarmitsuba.tracing.driver.trace.trace` runs at once on host threads: 1 for the tube
    preview, for batches traced elsewhere (``kernel`` None), inside the derivatives' traces (their
    loop mode and lane precision are per thread, and a kernel with ``serial`` set, the geometric
    derivatives', keeps per-launch state) and on one core; else :data:`HOST_THREADS_VARIABLE`
    or :data:`HOST_THREADS`, at most the cores. Raises ParameterError for a variable that is not
    an integer >= 1."""
    if kernel is None or kernel.mesh is None or loop_mode() is not None or lane_float() is not np.float32 \
            or getattr(kernel, "serial", False):
        return 1
    return launches_at_once()


def launches_at_once() -> int:
    """The mesh tracer's launches at once (:data:`HOST_THREADS_VARIABLE`, or :data:`HOST_THREADS`; at
    most the cores this process may run on), as :func:`host_threads` gives them to a render and the cost model counts them.
    Raises ParameterError for a variable that is not an integer >= 1."""
    wanted = count_variable(HOST_THREADS_VARIABLE, f"launches traced at once); unset it for the default, {HOST_THREADS}")
    return max(1, min(HOST_THREADS if wanted is None else wanted, usable_cores()))


def count_variable(name: str, meaning: str) -> int | None:
    """The environment variable ``name`` as an integer >= 1, None when unset or empty. Raises
    ParameterError naming it, with ``meaning`` (what the count is, and the fix), otherwise."""
    text = os.environ.get(name, "")
    if not text:
        return None
    try:
        wanted = int(text)
    except ValueError:
        wanted = 0
    if wanted < 1:
        raise ParameterError(f"{name}={text!r}: expected an integer >= 1 ({meaning}")
    return wanted


def usable_cores() -> int:
    """Cores this process may run on: its affinity mask (``taskset``), which ``os.cpu_count`` ignores."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def kernel_workers(threads: int, cores: int | None = None) -> int | None:
    """Dr.Jit's thread count (``dr.set_thread_count``: its pool workers plus the calling thread)
    while ``threads`` host threads trace on ``cores`` cores (default the machine's): workers on the
    cores the host threads leave free (1: none, each host thread runs its kernels' blocks itself),
    or None to keep the pool as it is (one host thread)."""
    if threads <= 1:
        return None
    return max((os.cpu_count() or 1) if cores is None else cores, threads) - threads + 1


@contextlib.contextmanager
def kernel_pool(threads: int):
    """Within it, Dr.Jit's thread count is :func:`kernel_workers` for ``threads`` host threads;
    it is restored on leaving, also after an error."""
    workers = kernel_workers(threads)
    if workers is None:
        yield
        return
    before = dr.thread_count()
    dr.set_thread_count(workers)
    try:
        yield
    finally:
        dr.set_thread_count(before)


def caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in the exception's cause/context chain."""
    seen = set()
    while exc is not None and id(exc) not in seen and not isinstance(exc, KeyboardInterrupt):
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return isinstance(exc, KeyboardInterrupt)
