"""``max_depth = auto``: the bounce orders a scene calls for, chosen before the trace by a probe
(docs/physics.md (DEP1)-(DEP3)).

The probe measures each order's energy as the render measures it ((D6)), not guessed from the
order before. Ray tubes (``lit_regions = tiles``, a coarse cast, one tube per resolution cell)
trace the whole track, every :data:`PROBE_STRIDE`-th pulse, to ``depth_cap``, every order
deposited apart, so that every part of the scene, and the aspects the track sees it from, are
probed. The depth is the smallest whose orders beyond hold at most ``depth_tolerance_db`` of the
probe's energy (:func:`decide`, (DEP2)). An order that holds little does not stop it while a
later one holds much (a chain that needs two more mirrors to return). For ``info``, the render's
own tracer then traces the middle sub-aperture to that depth, and its seconds per order predict
the render's. ``render``, ``simulate`` and ``info`` call the same :func:`choose_depth`, so
``info`` predicts the depth the render takes.

A fixed ``max_depth`` is traced as given; :func:`choose_depth` then returns it unchanged.
"""
from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from ...core.radar import ParameterError
from ...scene.loader import LoadedScene
from .trace import plan_trace, prepare_trace, trace

__all__ = ["PROBE_STRIDE", "DepthChoice", "probe_scene", "choose_depth", "decide", "depth_summary", "probe_settings", "REASONS"]

#: The probe traces every ``PROBE_STRIDE``-th pulse: the render measures each order's energy on
#: every 8th pulse too (:data:`~sarmitsuba.tracing.deposit.order_energy.ENERGY_STRIDE`), and
#: Munich's shares agree with the mesh tracer's within 0.4 % (docs/physics.md (DEP3)).
PROBE_STRIDE = 8
#: Why the choice stopped where it did (:attr:`DepthChoice.reason`).
REASONS = {"tolerance": "the orders beyond hold at most the tolerance",
           "nothing beyond": "no ray of the deepest order chosen meets more of the scene with power to return",
           "cap": "the orders up to the cap still change the image by more than the tolerance",
           "no returns": "the probe returns nothing"}


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
        Each order's energy in the probe ((D6), order ``k`` at index ``k - 1``).
    carried : float64 [cap], sr
        The power carried into each order's lit pieces there (``carried_power_per_order``): 0 from
        the first order no chain reaches.
    seconds : float64 [cap], s
        Each traced order's predicted seconds for the whole acquisition: the render's tracer on
        :attr:`timed`, times the sub-apertures over their number (host-thread seconds, as
        ``trace_stages_by_order``); NaN beyond ``depth`` and where not timed.
    probe_seconds : float, s
        Wall time of the probe (and of the timed sub-apertures).
    timed : tuple of int
        The sub-apertures the render's tracer timed (empty: not timed).
    n_subapertures : int
        The acquisition's sub-apertures (0: not timed).
    rays_beyond : int or None
        The probe's specular rays leaving order ``cap`` that meet more of the scene (None: not
        looked for: ray tubes, or a mesh probe whose order ``cap`` carried little).
    lit_regions : str
        What traced the energies: ``tiles`` (ray tubes).
    pulses : int
        The pulses the probe traced (every :data:`PROBE_STRIDE`-th).
    """

    depth: int
    reason: str
    tolerance_db: float
    cap: int
    energy: np.ndarray
    carried: np.ndarray
    seconds: np.ndarray
    probe_seconds: float
    timed: tuple
    n_subapertures: int
    rays_beyond: int | None = None
    lit_regions: str = "tiles"
    pulses: int = 0

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
                "probe": {"pulses": self.pulses, "timed_subapertures": list(self.timed), "of": self.n_subapertures,
                          "seconds": round(self.probe_seconds, 3),
                          "share": {str(k): float(s) for k, s in enumerate(self.share, start=1)},
                          "predicted_seconds": {str(k): round(float(s), 3) for k, s in enumerate(self.seconds, start=1)
                                                if np.isfinite(s)},
                          "rays_beyond_cap": self.rays_beyond, "lit_regions": self.lit_regions}}


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


def probe_settings(loaded: LoadedScene):
    """The probe's settings for ``loaded`` (``max_depth = auto``): ``max_depth = depth_cap``, the
    ray tubes (``lit_regions = tiles``; the mesh's lit regions for a bistatic receiver, which tubes
    do not trace), one per resolution cell (the scene's own ``ray_spacing`` where it renders with
    tubes), every order apart and
    measured on every pulse (``split_bounces``), deposited by the ``nearest`` kernel on the coarse
    samples (``oversample = 1``: an order's energy, not its waveform, (D6)). Tubes twice as wide
    missed the order-6 chain of a 4 m street canyon at 40 deg (``tests/scenes/street_canyon.xml``)."""
    st = loaded.settings
    tubes = "patches" if loaded.params.bistatic else "tiles"      # ray tubes are monostatic
    spacing = st.ray_spacing if st.lit_regions == "tiles" else 0.0  # the render's own tubes, or one per cell
    return dataclasses.replace(st, max_depth=st.depth_cap, split_bounces=True, lit_regions=tubes, scatterers=False,
                               ray_spacing=spacing, range_kernel="nearest", oversample=1)


def probe_scene(loaded: LoadedScene, stride: int | None = None) -> LoadedScene:
    """The scene the probe traces: ``loaded`` with :func:`probe_settings`, every ``stride``-th
    pulse (default :data:`PROBE_STRIDE`; the PRF divided by it, the same track; every pulse where
    fewer than two would remain), and moving shapes where they stand at mid-aperture (ray tubes
    do not move them)."""
    p, stride = loaded.params, PROBE_STRIDE if stride is None else stride
    if stride > 1 and p.n_pulses >= 2 * stride:
        p = dataclasses.replace(p, prf=p.prf / stride, n_pulses=p.n_pulses // stride)
    return dataclasses.replace(loaded, params=p, settings=probe_settings(loaded), motion=None)


def choose_depth(loaded: LoadedScene, timed: bool = False) -> tuple[LoadedScene, DepthChoice | None]:
    """``loaded`` with ``max_depth`` chosen, and the choice; ``loaded`` itself and None when its
    ``max_depth`` is a number.

    Ray tubes trace :func:`probe_scene` (every :data:`PROBE_STRIDE`-th pulse, to ``depth_cap``,
    every order apart); :func:`decide` chooses. With ``timed`` (``info``), the scene's own tracer
    then traces its middle sub-aperture alone to that depth, and its seconds per order, times the
    sub-apertures, predict the render's (:attr:`DepthChoice.seconds`; NaN
    without ``timed``).

    Raises
    ------
    ParameterError
        As :func:`~sarmitsuba.tracing.driver.trace.prepare_trace` (the acquisition's checks).
    """
    st = loaded.settings
    if not st.auto_depth:
        return loaded, None
    start = time.perf_counter()
    probe = probe_scene(loaded)
    with warnings.catch_warnings():          # the render that follows warns about the same scene once
        warnings.simplefilter("ignore")
        try:
            setup = prepare_trace(probe)
        except ParameterError:               # a check the thinned track fails (an ATI baseline): every pulse
            probe = probe_scene(loaded, stride=1)
            setup = prepare_trace(probe)
        result = trace(probe.scene, probe.params, setup.geometry, setup.window, setup.footprint, probe.settings,
                       setup.table, effects=dataclasses.replace(setup.effects, order_energy=True))
    energy = np.asarray(result.raw_energy_per_order, np.float64)
    carried = np.asarray(result.carried_power_per_order, np.float64)
    depth, reason = decide(energy, carried, st.depth_tolerance_db, result.rays_beyond)
    chosen = dataclasses.replace(loaded, settings=dataclasses.replace(st, max_depth=depth))
    seconds, n, middle = np.full(st.depth_cap, np.nan), 0, ()
    if timed:                                # the render's own tracer on the middle sub-aperture
        traced, n, middle = _timed_trace(chosen)
        for k, stages in traced.stage_seconds_by_order.items():
            if int(k) <= depth:
                seconds[int(k) - 1] = sum(stages.values()) * n / len(middle)
    choice = DepthChoice(depth=depth, reason=reason, tolerance_db=st.depth_tolerance_db, cap=st.depth_cap,
                         energy=energy, carried=carried, seconds=seconds, probe_seconds=time.perf_counter() - start,
                         timed=tuple(int(g) for g in middle), n_subapertures=n, rays_beyond=result.rays_beyond,
                         pulses=probe.params.n_pulses, lit_regions=probe.settings.lit_regions)
    return chosen, choice


def _timed_trace(loaded: LoadedScene):
    """The middle sub-aperture of ``loaded`` traced alone with its own settings, in this process
    and one launch: (TraceResult, the number of sub-apertures, (its index,))."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        setup = prepare_trace(loaded)
    plan = plan_trace(loaded.scene, loaded.params, setup.geometry, setup.window, setup.footprint, loaded.settings,
                      setup.effects)
    n = len(plan.subs.first)

    def one_kernel(plan, batches, here):     # this process, one launch
        for g0 in batches:
            yield here(g0)

    result = trace(loaded.scene, loaded.params, setup.geometry, setup.window, setup.footprint, loaded.settings,
                   setup.table, effects=setup.effects, sample=[n // 2], run_batches=one_kernel, trace_here=True)
    return result, n, (n // 2,)


def depth_summary(choice: "DepthChoice | None", result) -> dict:
    """``summary.json``'s ``depth``: ``{"mode": "fixed", "depth": N}`` or the choice's
    (:meth:`~sarmitsuba.tracing.driver.depth.DepthChoice.as_dict`), with the trace's seconds per
    order (host-thread seconds, as ``trace_stages_by_order``)."""
    seconds = {str(k): round(sum(stages.values()), 3) for k, stages in result.stage_seconds_by_order.items()}
    body = choice.as_dict() if choice is not None else {"mode": "fixed", "depth": len(result.energy_per_order)}
    return {**body, "seconds_by_order": seconds}

