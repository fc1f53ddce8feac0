"""How the kernels run their loops over pulses, terms and scatterers: Dr.Jit's symbolic loops (one
kernel, the default), or evaluated loops while derivatives are taken.

The loops deposit into the launch's histogram from inside their bodies (a scatter, a side effect).
Dr.Jit propagates derivatives through such a body only when the loop is *evaluated* (every
iteration its own kernel launch, the derivative graph explicit); a symbolic loop records the
scatter with symbolic indices that forward propagation cannot replay afterwards. So
:mod:`sarmitsuba.derivatives` runs its forward-mode traces inside :func:`evaluated_loops`, and every
``dr.while_loop`` of the kernels passes ``mode=loop_mode()``. Reverse mode keeps the symbolic
loops and differentiates inside them (:mod:`sarmitsuba.tracing.deposit.replay`).
"""
from __future__ import annotations

import contextlib
import gc
import threading

import numpy as np

__all__ = ["loop_mode", "evaluated_loops", "lane_float", "float64_lanes", "RECORDING"]

_STATE = threading.local()

#: Held while a symbolic loop (``dr.while_loop``) is recorded, and by the kernels that hold one while
#: they run: the per-pulse terms and scatterers with their deposits, the geometry kernels. Launches
#: traced on several host threads (:mod:`sarmitsuba.tracing.driver.threads`) interleave their NumPy
#: and their ray casts freely. The race that first made threaded renders differ was the deposit's
#: ``ReduceMode.Expand`` (:meth:`sarmitsuba.tracing.deposit.accumulate.Accumulator.shared_by`), not
#: the recording: threaded traces of ``urban`` matched the sequential one in 20 runs of 20 without
#: this lock. It is kept because it costs little (the terms stage, which it serialises, is about 6 %
#: of Munich's trace) and recording on two threads at once has been tried on that one scene only.
RECORDING = threading.RLock()


def loop_mode() -> str | None:
    """The ``mode`` for ``dr.while_loop``: None (Dr.Jit's default, symbolic) or ``"evaluated"``
    inside :func:`evaluated_loops` (this thread only)."""
    return getattr(_STATE, "mode", None)


@contextlib.contextmanager
def evaluated_loops(evaluated: bool = True):
    """Within the block, the kernels' loops run evaluated (differentiable through their deposits;
    with ``evaluated`` false they stay as they are: a replayed reverse pass,
    :mod:`sarmitsuba.tracing.deposit.replay`, differentiates inside its symbolic loops), and
    Python's cyclic garbage collector is paused (collected once on entry).

    Why the collector: at each evaluated loop's boundary, Dr.Jit's reverse traversal evaluates the
    gradients pending there in the iteration order of a hash set of their AD variable indices
    (``ad_traverse`` in Dr.Jit 1.5), and a new AD variable takes the lowest free index. Variables
    freed by the cyclic collector, at moments that depend on the process's history, therefore
    changed the indices, the order of the backward kernels' instructions and so their cache key:
    the same gradient compiled again for 20-60 s at random evaluations. With only reference
    counts freeing variables inside the block, the indices, and the kernels, repeat."""
    previous = loop_mode()
    collecting = gc.isenabled()
    if collecting:
        gc.collect()
        gc.disable()
    _STATE.mode = "evaluated" if evaluated else previous
    try:
        yield
    finally:
        _STATE.mode = previous
        if collecting:
            gc.enable()


def lane_float() -> type:
    """The floating-point type of the host's lane arrays that the kernels read in float32
    (:mod:`sarmitsuba.tracing.integration.term_lanes`): ``np.float32``, or ``np.float64`` inside
    :func:`float64_lanes` (this thread only), where the geometric derivatives difference them
    (docs/physics.md (AD4)); the upload rounds them to float32 either way."""
    return getattr(_STATE, "lane_float", np.float32)


@contextlib.contextmanager
def float64_lanes():
    """Within the block, the host keeps its lane arrays in float64 (:func:`lane_float`)."""
    previous = lane_float()
    _STATE.lane_float = np.float64
    try:
        yield
    finally:
        _STATE.lane_float = previous
