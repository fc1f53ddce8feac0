"""Where a trace's time goes: the mesh tracer's stages, timed per launch and summed over the
render (``summary.json``'s ``trace_stages``; docs/design.md section 10).

A section's time is exclusive: a section opened inside another pauses the outer one, so the
stages add up to the time the launches took.
"""
from __future__ import annotations

import contextlib
import time

import numpy as np

__all__ = ["STAGES", "StageClock", "by_order"]

#: The stages, in the order a launch runs them:
#: ``first bounce`` the first bounce's pieces and their visibility (M2)-(M4); ``visibility`` the
#: later orders' regions, pieces and visibility; ``clipping`` mixed pieces cut against their
#: occluders, with the recheck (M4); ``rates`` the boundaries' motion (M8); ``lanes`` the term lanes
#: and the rest of the piece geometry (M5); ``terms`` recording the per-pulse terms and scatterers
#: and reading the order's histogram back (its energy, docs/physics.md (D6));
#: ``energy`` the energy check; ``discovery`` the next order's chains (M6); ``casts`` the ray casts
#: of all of these (the kernels that cast and read their hits back,
#: :func:`sarmitsuba.tracing.timing.section`), taken out of the stage they serve; ``moving shapes``
#: what moving shapes add (docs/physics.md (V1)-(V2): the shapes moved and their geometry rebuilt,
#: traced again at the neighbouring times, the recorded lanes deposited); ``deposit`` the device
#: evaluating every pulse's terms and the host reading the histogram back.
STAGES = ("first bounce", "visibility", "clipping", "rates", "lanes", "terms", "energy", "discovery", "casts",
          "moving shapes", "deposit")


class StageClock:
    """Exclusive wall time per stage of :data:`STAGES` and per bounce order: ``clock.order = d``
    (0-based; 0 by default), then ``with clock("rates"): ...``.

    Parameters
    ----------
    orders : int
        Rows of :attr:`seconds`: the bounce orders traced, and one more for what belongs to no
        single order (the launch's ``deposit``).

    Attributes
    ----------
    seconds : float64 [orders, len(STAGES)]
        Row ``d``: the stages' seconds while :attr:`order` was ``d``.
    """

    def __init__(self, orders: int = 1):
        self.seconds = np.zeros((orders, len(STAGES)))
        self.order = 0
        self._open: list[tuple[int, int]] = []
        self._since = 0.0

    @contextlib.contextmanager
    def __call__(self, stage: str):
        index = STAGES.index(stage)
        now = time.perf_counter()
        if self._open:
            self.seconds[self._open[-1]] += now - self._since
        self._open.append((self.order, index))
        self._since = now
        try:
            yield
        finally:
            now = time.perf_counter()
            self.seconds[self._open.pop()] += now - self._since
            self._since = now


def by_order(seconds: np.ndarray) -> dict:
    """``{order: {stage: seconds}}`` (orders from 1) of the rows of ``seconds`` float64
    [n_rows, len(STAGES)] but the last (what belongs to no single order), stages above 0 only."""
    return {d + 1: {name: float(t) for name, t in zip(STAGES, row) if t > 0}
            for d, row in enumerate(np.asarray(seconds)[:-1]) if np.any(row > 0)}
