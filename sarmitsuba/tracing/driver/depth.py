"""``max_depth = auto``: the bounce orders a scene calls for, chosen before the trace by a probe
(docs/physics.md (DEP1)-(DEP3)).

The probe is the tracer itself, on a few of the acquisition's sub-apertures spread evenly along
it, traced to ``depth_cap`` with every order deposited apart: each order's energy there is
measured as the render measures it ((D6)), not guessed from the order before. The depth is the
smallest whose orders beyond hold at most ``depth_tolerance_db`` of the probe's energy (DEP2),
so an order that holds little does not stop it while a later one holds much (a chain that needs
two more mirrors to return). ``render``, ``simulate`` and ``info`` call the same
:func:`choose_depth` on the same sub-apertures, so ``info`` predicts the depth the render takes.

A fixed ``max_depth`` is traced as given; :func:`choose_depth` then returns it unchanged.
"""
from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from ...scene.loader import LoadedScene
from .trace import plan_trace, prepare_trace, trace

__all__ = ["PROBE_SHARE", "PROBE_MIN", "DepthChoice", "choose_depth", "decide", "probe_sample", "REASONS"]

#: Share of the acquisition's sub-apertures the probe traces (at least :data:`PROBE_MIN`): on
#: Munich's 512 central pulses 2 of 27, on its full default acquisition 4 of 123.
PROBE_SHARE = 1 / 32
#: Fewest sub-apertures the probe traces (all of them where the acquisition has fewer).
PROBE_MIN = 2
#: Why the choice stopped where it did (:attr:`DepthChoice.reason`).
REASONS = {"tolerance": "the orders beyond hold at most the tolerance",
           "nothing beyond": "no ray of the deepest order chosen meets more of the scene with power to return",
           "cap": "the orders up to the cap still change the image by more than the tolerance",
           "no returns": "the probe's sub-apertures return nothing"}


@dataclass(frozen=True)
class DepthChoice:
    """The depth ``max_depth = auto`` chose, and the probe's evidence.

    Attributes
    ----------
    depth : int
        Bounce orders the render traces.
    reason : str
        A key of :data:`REASONS`.
    tolerance_db : float, dB
    cap : int
    energy : float64 [cap], m^2
        Each order's energy over the probe's sub-apertures ((D6), order ``k`` at index ``k - 1``).
    carried : float64 [cap], sr
        The power carried into each order's lit pieces there (``carried_power_per_order``): 0 from
        the first order no chain reaches.
    seconds : float64 [cap], s
        Each order's predicted trace seconds for the whole acquisition: the probe's, times the
        sub-apertures over those probed (host-thread seconds, as ``trace_stages_by_order``).
    probe_seconds : float, s
        Wall time of the probe.
    sampled : tuple of int
        The sub-apertures probed.
    n_subapertures : int
        The acquisition's sub-apertures.
    rays_beyond : int or None
        The probe's specular rays leaving order ``cap`` that meet more of the scene (None: not
        looked for, its order ``cap`` carried little).
    """

    depth: int
    reason: str
    tolerance_db: float
    cap: int
    energy: np.ndarray
    carried: np.ndarray
    seconds: np.ndarray
    probe_seconds: float
    sampled: tuple
    n_subapertures: int
    rays_beyond: int | None = None

    @property
    def share(self) -> np.ndarray:
        """float64 [cap]: each order's share of the probe's energy (0 where it holds none)."""
        total = float(np.sum(self.energy))
        return self.energy / total if total > 0 else np.zeros_like(self.energy)

    def beyond(self, depth: int | None = None) -> float:
        """The share of the probe's energy in the orders beyond ``depth`` (default: the chosen one)."""
        return float(np.sum(self.share[self.depth if depth is None else depth:]))

    def beyond_db(self, depth: int | None = None) -> float:
        """:meth:`beyond` in dB (-inf when 0)."""
        tail = self.beyond(depth)
        return 10 * math.log10(tail) if tail > 0 else -math.inf

    def as_dict(self) -> dict:
        """``summary.json``'s ``depth`` (plain JSON types)."""
        tail = self.beyond_db()
        return {"mode": "auto", "depth": self.depth, "reason": self.reason, "why": REASONS[self.reason],
                "tolerance_db": self.tolerance_db, "cap": self.cap,
                "beyond_db": None if math.isinf(tail) else round(tail, 2),
                "probe": {"subapertures": list(self.sampled), "of": self.n_subapertures,
                          "seconds": round(self.probe_seconds, 3),
                          "share": {str(k): float(s) for k, s in enumerate(self.share, start=1)},
                          "predicted_seconds": {str(k): round(float(s), 3) for k, s in enumerate(self.seconds, start=1)},
                          "rays_beyond_cap": self.rays_beyond}}

    def lines(self) -> list[str]:
        """Text lines: the depth, why, and each order's share and predicted seconds."""
        tail = self.beyond_db()
        out = [f"max_depth auto: depth {self.depth} ({self.reason}: {REASONS[self.reason]}; tolerance "
               f"{self.tolerance_db:g} dB, cap {self.cap}); "
               + ("the orders beyond the cap were not probed" if self.reason == "cap" else "orders beyond it hold "
                  + ("nothing" if math.isinf(tail) else f"{tail:.1f} dB") + " of the probe's energy"),
               f"  probe: {len(self.sampled)} of {self.n_subapertures} sub-apertures traced to order {self.cap} "
               f"in {self.probe_seconds:.1f} s"]
        last = int(np.flatnonzero(self.carried > 0).max(initial=0)) + 1
        for k in range(1, max(last, self.depth) + 1):
            mark = " (traced)" if k <= self.depth else ""
            out.append(f"  order {k:>2}: {100 * self.share[k - 1]:8.4f} % of the energy, "
                       f"{self.seconds[k - 1]:7.1f} s predicted{mark}")
        return out


def decide(energy: np.ndarray, carried: np.ndarray, tolerance_db: float,
           rays_beyond: int | None = None) -> tuple[int, str]:
    """The depth and its reason from the probe's per-order energies ``energy`` float64 [cap] [m^2]
    and carried powers ``carried`` float64 [cap] [sr] (docs/physics.md (DEP2)): the smallest
    ``d`` with ``sum_{k > d} E_k <= 10^(tolerance_db / 10) sum_k E_k``. At ``d = cap`` the reason
    is ``cap`` unless nothing goes on past it (the deepest order carries nothing, or none of its
    rays meets more: ``rays_beyond == 0``); below it, ``nothing beyond`` where no deeper order
    carries power, else ``tolerance``. No energy at all: depth 1, ``no returns``."""
    energy, carried = np.asarray(energy, np.float64), np.asarray(carried, np.float64)
    cap = len(energy)
    total = float(energy.sum())
    if not total > 0:
        return 1, "no returns"
    tol = 10.0 ** (tolerance_db / 10.0)
    tails = np.array([energy[d:].sum() for d in range(1, cap + 1)]) / total     # beyond order d = 1..cap
    depth = int(np.flatnonzero(tails <= tol)[0]) + 1
    if depth == cap and cap > 1:
        goes_on = carried[-1] > 0 and rays_beyond != 0
        return depth, "cap" if goes_on else "nothing beyond"
    return depth, "tolerance" if np.any(carried[depth:] > 0) else "nothing beyond"


def probe_sample(n: int) -> np.ndarray:
    """int64 [K]: the sub-apertures the probe traces out of ``n``, ``K = min(n, max(PROBE_MIN,
    ceil(n PROBE_SHARE)))``, the centres of ``K`` equal runs along the acquisition."""
    k = min(n, max(PROBE_MIN, math.ceil(n * PROBE_SHARE)))
    return np.unique(np.floor((np.arange(k) + 0.5) * n / max(k, 1)).astype(np.int64))


def choose_depth(loaded: LoadedScene) -> tuple[LoadedScene, DepthChoice | None]:
    """``loaded`` with ``max_depth`` chosen, and the choice; ``loaded`` itself and None when its
    ``max_depth`` is a number.

    The probe traces :func:`probe_sample`'s sub-apertures to ``depth_cap`` with the scene's own
    settings and effects, the first alone (it compiles the kernels) and then the others, whose
    seconds per order, times the sub-apertures over theirs, predict the render's (every order deposited apart; the ``exact`` range kernel probes with
    ``linear``, whose energies are the same (D6)), then :func:`decide`.

    Raises
    ------
    ParameterError
        As :func:`~sarmitsuba.tracing.driver.trace.prepare_trace` (the acquisition's checks).
    """
    st = loaded.settings
    if not st.auto_depth:
        return loaded, None
    start = time.perf_counter()
    probe = dataclasses.replace(loaded, settings=dataclasses.replace(
        st, max_depth=st.depth_cap, split_bounces=False,
        range_kernel="linear" if st.range_kernel == "exact" else st.range_kernel))
    with warnings.catch_warnings():          # the render that follows warns about the same scene once
        warnings.simplefilter("ignore")
        setup = prepare_trace(probe)
    effects = dataclasses.replace(setup.effects, order_energy=True)
    plan = plan_trace(probe.scene, probe.params, setup.geometry, setup.window, setup.footprint, probe.settings, effects)
    n = len(plan.subs.first)
    sample = probe_sample(n)
    # the first sub-aperture compiles the kernels; the others time the orders (the first's seconds
    # where it is the only one)
    results = [trace(probe.scene, probe.params, setup.geometry, setup.window, setup.footprint, probe.settings,
                     setup.table, effects=effects, sample=part) for part in (sample[:1], sample[1:]) if len(part)]
    energy = sum(np.asarray(r.raw_energy_per_order, np.float64) for r in results)
    carried = sum(np.asarray(r.carried_power_per_order, np.float64) for r in results)
    beyond = [r.rays_beyond for r in results]
    depth, reason = decide(energy, carried, st.depth_tolerance_db, None if None in beyond else sum(beyond))
    timed = results[-1]
    per_order = np.zeros(st.depth_cap)
    for k, stages in timed.stage_seconds_by_order.items():
        per_order[int(k) - 1] = sum(stages.values())
    timed_subs = len(sample) - 1 if len(results) > 1 else len(sample)
    choice = DepthChoice(depth=depth, reason=reason, tolerance_db=st.depth_tolerance_db, cap=st.depth_cap,
                         energy=energy, carried=carried, seconds=per_order * n / timed_subs,
                         probe_seconds=time.perf_counter() - start, sampled=tuple(int(g) for g in sample),
                         n_subapertures=n, rays_beyond=None if None in beyond else sum(beyond))
    return dataclasses.replace(loaded, settings=dataclasses.replace(st, max_depth=depth)), choice
