"""Where a trace's time goes, by stage and by bounce order (``summary.json``'s ``trace_stages``
and ``trace_stages_by_order``; :mod:`sarmitsuba.tracing.driver.stages`).

Deliberate bugs these tests were run against: a nested section that does not pause the outer one
(the clock's test); and, each failing the render's test, the mesh tracer
not setting the clock's order (every stage in order 1); the stages' total taken from the first
order's row only (it falls short of the orders' sum); the launch's deposit charged to order 1
(it belongs to none); the tracer not handing its clock to the casts (no ``casts`` stage); a cast
charged to the clock of another thread (the threads' test).
"""
from __future__ import annotations

import threading
import time

import numpy as np

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.driver.stages import STAGES, StageClock, by_order
from sarmitsuba.tracing.timing import charged_to, section


def test_the_clock_charges_each_section_to_the_order_then_current():
    """Exclusive time, per order: an inner section pauses the outer one, and what runs after
    ``order`` changes goes to the new row (a clock of known sleeps, not of the tracer)."""
    clock = StageClock(3)
    with clock("lanes"):
        time.sleep(0.02)
        with clock("rates"):
            time.sleep(0.08)
    clock.order = 1
    with clock("discovery"):
        time.sleep(0.01)
    clock.order = 2
    with clock("deposit"):
        time.sleep(0.01)
    s = clock.seconds
    assert s.shape == (3, len(STAGES))
    lanes, rates, discovery = STAGES.index("lanes"), STAGES.index("rates"), STAGES.index("discovery")
    # exclusive: the outer section's 0.02 s alone (counting the inner one's time too gives 0.08 or more)
    assert 0.02 <= s[0, lanes] < 0.06 and 0.08 <= s[0, rates] < 0.12
    assert 0.01 <= s[1, discovery] and s[0, discovery] == 0.0 and s[1, lanes] == 0.0
    table = by_order(s)
    assert set(table) == {1, 2}                                    # the last row is no order's
    assert set(table[1]) == {"lanes", "rates"} and set(table[2]) == {"discovery"}


def test_a_render_reports_its_stages_by_bounce_order():
    """Urban at depth 3: the first bounce only in order 1, discovery only from order 2 on (it
    finds their chains), orders 1 and 2 with their lanes; the orders add up to the stage totals less
    the deposit, which no single order owns."""
    sim = simulate("urban", sensor_overrides={"n_pulses": 96}, integrator_overrides={"max_depth": 3})
    totals, orders = sim.trace.stage_seconds, sim.trace.stage_seconds_by_order
    assert set(orders) == {1, 2, 3}
    assert "first bounce" in orders[1] and all("first bounce" not in orders[d] for d in (2, 3))
    assert "discovery" not in orders[1] and all("discovery" in orders[d] for d in (2, 3))
    assert all(orders[d].get("casts", 0.0) > 0 for d in (1, 2, 3))          # every order casts rays
    assert all("lanes" in orders[d] and "terms" in orders[d] for d in (1, 2))   # (order 3 finds no chains
    # at 96 pulses: its discovery alone)
    for stage, seconds in totals.items():
        share = sum(orders[d].get(stage, 0.0) for d in orders)
        if stage == "deposit":
            assert share == 0.0 and seconds > 0
        else:
            np.testing.assert_allclose(share, seconds, rtol=1e-9)
    shallow = simulate("urban", sensor_overrides={"n_pulses": 96}, integrator_overrides={"max_depth": 1})
    assert set(shallow.trace.stage_seconds_by_order) == {1}


def test_casts_charge_the_clock_of_their_own_thread_only():
    """A section opened through :func:`section` pauses the stage around it on this thread's
    clock; outside :func:`charged_to` it times nothing, and a second thread charging its own
    clock at the same time leaves this one's untouched."""
    casts, lanes = STAGES.index("casts"), STAGES.index("lanes")
    with section("casts"):                                   # no clock: nothing to charge
        time.sleep(0.005)
    mine, theirs = StageClock(), StageClock()

    def other():
        with charged_to(theirs), theirs("lanes"), section("casts"):
            time.sleep(0.12)

    worker = threading.Thread(target=other)
    with charged_to(mine), mine("lanes"):
        worker.start()
        time.sleep(0.02)
        with section("casts"):
            time.sleep(0.04)
        worker.join()
    assert 0.04 <= mine.seconds[0, casts] < 0.1            # not the other thread's 0.12 s
    assert mine.seconds[0, lanes] >= 0.02 + 0.05            # before its cast, and waiting for the other
    assert theirs.seconds[0, casts] >= 0.12 and theirs.seconds[0, lanes] < 0.04
    with section("casts"):                                   # the clock is gone again
        time.sleep(0.005)
    assert mine.seconds[0, casts] < 0.1
