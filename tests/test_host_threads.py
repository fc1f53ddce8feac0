"""Launches traced on several host threads at once (:func:`sarmitsuba.tracing.driver.threads.host_threads`):
the same result as one after the other, the variable that sets the count, and one thread where
threads cannot help or would be wrong (the tube preview, the derivatives' traces).

Deliberate bugs these tests were run against: the variable's value 0 accepted and threads used
inside ``evaluated_loops`` (each fails every run); the cast counters shared between threads instead
of per thread (a race: failed one run of two); the histogram's deposit left in
``ReduceMode.Expand`` with two threads (``Accumulator.shared_by`` a no-op: two host threads that
wait on Dr.Jit both run deposit blocks as pool worker 0 and add into one copy without atomics; a
few pulses lost up to 4e-5 of their power in 10 of 31 runs, and in 6 of 6 with
:data:`sarmitsuba.tracing.loops.RECORDING` a no-op; with the fix none in 60 runs); the energy and
scatterer tallies left in ``ReduceMode.Auto`` (Expand for small arrays: the same race; it lost
1.6 % of order 1's energy in a fresh clone's test run, and failed
``test_range_kernels::test_exact_kernel_traces_the_same_paths`` in 2 of 5 runs beside a busy
core, none in 8 with the fix; the check below saw none of it in 12).
The pool's results taken in the order they finish is no bug (each result carries its pulses).
"""
from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.tracing.driver import threads
from sarmitsuba.tracing.driver import trace as tracing
from sarmitsuba.tracing.loops import evaluated_loops, float64_lanes


def _trace(loaded, threads: int, monkeypatch, per_batch: int = 2):
    """The urban scene's trace with ``threads`` launches at once, every launch ``per_batch``
    sub-apertures (the same grouping whatever the threads)."""
    setup = tracing.prepare_trace(loaded)
    monkeypatch.setattr(tracing, "host_threads", lambda kernel: threads)
    plan = tracing.plan_trace
    monkeypatch.setattr(tracing, "plan_trace",
                        lambda *a: dataclasses.replace(plan(*a), per_batch=per_batch * max(threads, 1)))
    return tracing.trace(loaded.scene, loaded.params, setup.geometry, setup.window, setup.footprint, loaded.settings,
                         setup.table, effects=setup.effects)


def test_two_threads_give_the_sequential_result(monkeypatch):
    """The same sub-apertures in the same launches, traced two at a time and one after the other:
    the spectra and the energy tallies are equal, every pulse in its place; the counters are
    equal. Relies on the bit-for-bit guarantee (docs/physics.md (D7)): the two traces differ only in
    how many host threads run the same launches, so any difference is the bug (a lost update)."""
    loaded = load_scene("urban", sensor_overrides={"n_pulses": 160})
    one = _trace(loaded, 1, monkeypatch)
    two = _trace(loaded, 2, monkeypatch)
    assert one.spectrum.shape == two.spectrum.shape
    power = np.abs(one.spectrum) ** 2
    per_pulse = power.sum(axis=1)
    assert np.count_nonzero(per_pulse) > 100                                # the premise: pulses see the scene
    np.testing.assert_array_equal(two.spectrum, one.spectrum)                # each pulse, not just the sum
    np.testing.assert_array_equal(one.rays_per_order, two.rays_per_order)
    # the energy tallies, added to as the histogram is (lost updates: 1.6 % of order 1's once)
    np.testing.assert_array_equal(two.energy_per_order, one.energy_per_order)
    np.testing.assert_array_equal(one.scatterers_per_order, two.scatterers_per_order)
    assert one.shadow_rays == two.shadow_rays and one.pulse_paths == two.pulse_paths
    assert set(two.stage_seconds) >= {"first bounce", "lanes", "terms"}


def test_the_variable_sets_the_threads_and_bad_values_are_refused(monkeypatch):
    kernel = type("K", (), {"mesh": object()})()
    monkeypatch.setattr(threads, "usable_cores", lambda: 8)        # the cores it may run on
    monkeypatch.delenv(threads.HOST_THREADS_VARIABLE, raising=False)
    assert threads.host_threads(kernel) == threads.HOST_THREADS == 2          # two by default
    monkeypatch.setenv(threads.HOST_THREADS_VARIABLE, "3")
    assert threads.host_threads(kernel) == 3
    monkeypatch.setattr(threads, "usable_cores", lambda: 2)        # the cores it may run on
    assert threads.host_threads(kernel) == 2                                # at most the cores
    monkeypatch.delenv(threads.HOST_THREADS_VARIABLE)
    monkeypatch.setattr(threads, "usable_cores", lambda: 1)        # the cores it may run on
    assert threads.host_threads(kernel) == 1                                # the default too
    for bad in ("0", "-1", "two", "1.5"):
        monkeypatch.setenv(threads.HOST_THREADS_VARIABLE, bad)
        with pytest.raises(ParameterError, match=threads.HOST_THREADS_VARIABLE):
            threads.host_threads(kernel)


def test_one_thread_for_the_preview_and_inside_the_derivatives(monkeypatch):
    monkeypatch.setenv(threads.HOST_THREADS_VARIABLE, "2")
    monkeypatch.setattr(threads, "usable_cores", lambda: 4)        # the cores it may run on
    mesh = type("K", (), {"mesh": object()})()
    assert threads.host_threads(mesh) == 2
    assert threads.host_threads(type("K", (), {"mesh": None})()) == 1       # the tube preview
    assert threads.host_threads(None) == 1                                  # batches traced elsewhere (Dask)
    with evaluated_loops():                                                 # loop mode is per thread
        assert threads.host_threads(mesh) == 1
    with float64_lanes():                                                   # so is the lanes' precision
        assert threads.host_threads(mesh) == 1


def test_launches_at_once_build_the_shared_pieces_once(monkeypatch):
    """Two host threads that start their launches together wait for one build of the mesh's
    pieces (a 1 M-triangle city's are 0.6 GB): ``pieces_of`` runs once, slowed here so that both
    threads ask while it runs, and both get the same arrays. Without the lock it ran twice."""
    import dataclasses
    import threading
    import time as _time

    from sarmitsuba.tracing.driver import kernel as kernel_module

    loaded = load_scene("urban", sensor_overrides={"n_pulses": 64})
    setup = tracing.prepare_trace(loaded)
    kernel = kernel_module.Kernel(loaded.scene, loaded.params, setup.window, setup.footprint, loaded.settings,
                                  setup.table, setup.effects)
    tracer = kernel.mesh
    calls = []
    build = tracer.kernels.pieces_of

    def slow(*args, **kwargs):
        calls.append(threading.get_ident())
        _time.sleep(0.3)
        return build(*args, **kwargs)

    monkeypatch.setattr(tracer, "kernels", dataclasses.replace(tracer.kernels, pieces_of=slow))
    got = []
    workers = [threading.Thread(target=lambda: got.append(tracer._first_pieces())) for _ in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert len(calls) == 1
    assert got[0] is got[1]


def test_host_threads_that_fill_the_cores_leave_no_pool_and_the_pool_comes_back(monkeypatch):
    """Two host threads on 2 cores: no pool workers (Dr.Jit's thread count 1, which counts the
    calling thread: each host thread runs its own blocks); on 16 cores the 14 workers the threads
    leave (count 15); one thread keeps the pool. The pool's size is restored after a threaded
    trace and after an error inside it."""
    import drjit as dr
    assert threads.kernel_workers(2, cores=2) == 1
    assert threads.kernel_workers(2, cores=16) == 15
    assert threads.kernel_workers(3, cores=2) == 1
    assert threads.kernel_workers(1, cores=2) is None
    before = dr.thread_count()
    seen = []
    with threads.kernel_pool(2):
        seen.append(dr.thread_count())
    assert dr.thread_count() == before
    assert seen == [max(os.cpu_count() or 1, 2) - 1]
    with pytest.raises(RuntimeError):
        with threads.kernel_pool(2):
            raise RuntimeError("inside")
    assert dr.thread_count() == before
    loaded = load_scene("urban")
    _trace(loaded, 2, monkeypatch)
    assert dr.thread_count() == before
