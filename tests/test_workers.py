"""The trace on worker processes (:mod:`sarmitsuba.tracing.driver.workers`): the same bits as one
process for any number of workers, one clear message when a worker dies (and nothing written),
the memory's cap on the workers, and small scenes kept in one process.

Deliberate bugs these tests were run against, each caught: the driver's spectra placed in
arrival order instead of by pulse index, and the workers left with the plan's batch size instead
of the driver's (the bits, at 2 processes); a worker's death read as the end of its batches
(the death's message: the driver would otherwise wait for ever, and now says the workers
stopped); the memory cap computed without the render's own peak (the cap); the small-scene rule
and the large-copy rule skipped (their tests); the cores counted by ``os.cpu_count`` instead of
the affinity (the pinned process).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.tracing.driver import trace as tracing
from sarmitsuba.tracing.driver import workers

GIB = 2**30
#: urban, long enough that each process traces several batches of one sub-aperture.
SPEC = ("urban", {"n_pulses": 360}, None, None)


@pytest.fixture(scope="module")
def one_process():
    """The urban trace in this process alone (the reference), and its scene."""
    loaded = load_scene(*SPEC)
    setup = tracing.prepare_trace(loaded)
    result = tracing.trace(loaded.scene, loaded.params, setup.geometry, setup.window, setup.footprint,
                           loaded.settings, setup.table, effects=setup.effects)
    return loaded, setup, result


@pytest.mark.parametrize("n", [2, 4])
def test_workers_give_the_one_process_bits(one_process, n):
    """Traced on this process and ``n - 1`` worker processes, batches handed out as they free up:
    every pulse's spectrum equal bit for bit to the one-process trace (the fixed-point deposit,
    docs/physics.md (D7), makes the sum independent of who traced what and when), and the
    counters equal. The premise: more than one process traced batches."""
    loaded, setup, reference = one_process
    result = workers.trace_in_workers(SPEC, loaded, setup, n)
    assert result.workers >= 2, "the premise: worker processes traced some of the batches"
    power = np.abs(reference.spectrum) ** 2
    assert np.count_nonzero(power.sum(axis=1)) > 300                # the premise: pulses see the scene
    np.testing.assert_array_equal(result.spectrum, reference.spectrum)
    np.testing.assert_array_equal(result.rays_per_order, reference.rays_per_order)
    assert result.shadow_rays == reference.shadow_rays
    np.testing.assert_array_equal(result.energy_per_order, reference.energy_per_order)


def test_a_worker_that_dies_ends_the_render_with_one_message(tmp_path):
    """A worker process that dies mid-render (exit code 17, as a killed process): the render
    stops with exit code 2 and one message naming the worker, its exit code, the pulses it was
    tracing and the fix; no traceback, no output folder, no worker left running."""
    out = tmp_path / "render"
    env = {**os.environ, workers.WORKERS_VARIABLE: "2", workers.KILL_AFTER_ENV: "2"}
    done = subprocess.run([sys.executable, "-m", "sarmitsuba", "render", "urban", "--pulses", "200", "--out", str(out),
                           "--no-progress"], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 2, done.stderr[-2000:]
    message = [line for line in done.stderr.splitlines() if line.startswith("error")]
    assert len(message) == 1, done.stderr[-2000:]
    assert "trace worker 1" in message[0] and "exit code 17" in message[0] and "tracing pulses" in message[0]
    assert workers.WORKERS_VARIABLE + "=1" in message[0]
    assert "Traceback" not in done.stderr
    assert not out.exists()
    mine = subprocess.run(["pgrep", "-f", "sarmitsuba.tracing.driver.workers"], capture_output=True, text=True)
    assert mine.stdout.strip() == ""


def _cost(trace_s=100.0, peak=1.0 * GIB, runtime=0.5 * GIB, working=0.5 * GIB):
    """A cost estimate with only the fields :func:`workers.worker_plan` reads."""
    return SimpleNamespace(trace_time_s=trace_s, peak_memory_bytes=peak, runtime_bytes=runtime,
                           trace_working_bytes=working)


def test_memory_caps_the_workers_and_says_so(monkeypatch):
    """8 cores, 3.5 GiB free: the render's own 1 GiB leaves 2.5 GiB, and a worker needs 1 GiB
    (runtime 0.5 + working set 0.5), so two workers fit: the count is 2 and the reason names the
    memory. With 64 GiB the cores decide (8); with 1.5 GiB none fits beside the render: it traces
    alone and says why."""
    monkeypatch.delenv(workers.WORKERS_VARIABLE, raising=False)
    plan = workers.worker_plan(_cost(), batches=100, mesh=True, available=int(3.5 * GIB), cores=8)
    assert (plan.workers, plan.memory_cap, plan.per_worker_bytes) == (2, 2, GIB)
    assert "capped by memory" in plan.reason
    roomy = workers.worker_plan(_cost(), batches=100, mesh=True, available=64 * GIB, cores=8)
    assert roomy.workers == 8 and "memory" not in roomy.reason
    tight = workers.worker_plan(_cost(), batches=100, mesh=True, available=int(1.5 * GIB), cores=8)
    assert tight.workers == 1 and "memory holds one" in tight.reason
    # the render and its workers together: 1 GiB + (8 - 1) x 1 GiB
    assert roomy.peak_memory_bytes == 8 * GIB and plan.peak_memory_bytes == 2 * GIB


def test_workers_that_would_copy_a_large_scene_are_not_started(monkeypatch):
    """A worker that would hold over :data:`workers.MAX_WORKER_BYTES` (the 1 M-triangle city's
    5.5 GiB of scene and tables) is not started: the render traces on its own host threads; a
    count you set still starts them."""
    monkeypatch.delenv(workers.WORKERS_VARIABLE, raising=False)
    big = _cost(runtime=4.5 * GIB, working=1.0 * GIB)
    plan = workers.worker_plan(big, batches=100, mesh=True, available=64 * GIB, cores=8)
    assert plan.workers == 1 and "5.5 GiB" in plan.reason
    just = _cost(runtime=1.5 * GIB, working=0.5 * GIB)          # exactly the bound: started
    assert workers.worker_plan(just, batches=100, mesh=True, available=64 * GIB, cores=8).workers == 8
    monkeypatch.setenv(workers.WORKERS_VARIABLE, "2")
    assert workers.worker_plan(big, batches=100, mesh=True, available=64 * GIB, cores=8).workers == 2


def test_small_scenes_and_requests(monkeypatch):
    """A trace the model puts under :data:`workers.MIN_TRACE_SECONDS` stays in this process (no
    worker start-up to pay), unless workers are asked for; at most the batches; the tube
    preview never; a bad count is refused naming the variable."""
    monkeypatch.delenv(workers.WORKERS_VARIABLE, raising=False)
    small = workers.worker_plan(_cost(trace_s=5.0), batches=100, mesh=True, available=64 * GIB, cores=8)
    assert small.workers == 1 and "pay off" in small.reason
    assert workers.worker_plan(_cost(), batches=3, mesh=True, available=64 * GIB, cores=8).workers == 3
    assert workers.worker_plan(_cost(), batches=100, mesh=False, available=64 * GIB, cores=8).workers == 1
    monkeypatch.setenv(workers.WORKERS_VARIABLE, "3")
    asked = workers.worker_plan(_cost(trace_s=5.0), batches=100, mesh=True, available=64 * GIB, cores=8)
    assert asked.workers == 3
    monkeypatch.setenv(workers.WORKERS_VARIABLE, "0")
    with pytest.raises(ParameterError, match=workers.WORKERS_VARIABLE):
        workers.worker_plan(_cost(), batches=100, mesh=True, available=64 * GIB, cores=8)


def test_batches_are_cut_for_balance():
    """Enough batches for every worker to take several (the last ones balance the load), never
    larger than the plan's, never empty."""
    assert workers.batch_size(8, 123, 2) == 3                 # 123 // (16 * 2)
    assert workers.batch_size(2, 123, 2) == 2                 # the plan's is smaller
    assert workers.batch_size(8, 5, 4) == 1


def test_urban_render_stays_in_one_process(tmp_path, monkeypatch):
    """The default render of urban (a few seconds of tracing) starts no worker, and its
    summary says so; ``info`` names the plan and the memory's cap."""
    monkeypatch.delenv(workers.WORKERS_VARIABLE, raising=False)
    from sarmitsuba.cli import main
    assert main(["render", "urban", "--pulses", "64", "--out", str(tmp_path / "r"), "--no-progress"]) == 0
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["workers"] == 1 and "this process" in summary["workers_note"]
    from sarmitsuba.info import format_text, scene_info
    text = format_text(scene_info("urban"))
    assert "processes: 1" in text and "memory holds" in text


def test_a_pinned_process_counts_the_cores_it_is_given():
    """Pinned to one core with ``taskset``, the package counts one core (``os.cpu_count`` would
    say the machine's), traces one launch at a time and runs Dr.Jit on one thread."""
    import shutil
    if shutil.which("taskset") is None or len(os.sched_getaffinity(0)) < 2:
        pytest.skip("needs taskset and two cores")
    code = ("import drjit as dr, sarmitsuba; from sarmitsuba.tracing.driver import threads; "
            "print(threads.usable_cores(), threads.launches_at_once(), dr.thread_count())")
    env = {k: v for k, v in os.environ.items() if k != "SARMITSUBA_HOST_THREADS"}
    done = subprocess.run(["taskset", "-c", "0", sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, check=True)
    assert done.stdout.split() == ["1", "1", "1"]


@pytest.mark.parametrize("sensor, integrator", [({"n_pulses": 160, "polarization": "quad"},
                                                 {"split_bounces": True, "max_depth": 3}),
                                                ({"n_pulses": 120}, {"range_kernel": "exact"})],
                         ids=["quad-split", "exact"])
def test_every_channel_order_and_kernel_the_same_on_three_processes(monkeypatch, sensor, integrator):
    """Quad polarisation with each bounce order apart, and the ``exact`` range kernel (whose terms
    come back as path lists, in another order): each raw data set of a render on three processes
    equals the one-process render's bit for bit."""
    import warnings
    from sarmitsuba.pipeline import simulate
    sims = {}
    for n in ("1", "3"):
        monkeypatch.setenv(workers.WORKERS_VARIABLE, n)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sims[n] = simulate("urban", sensor_overrides=sensor, integrator_overrides=integrator)
    assert sims["3"].trace.workers >= 2, "the premise: worker processes traced some batches"
    one, three = sims["1"], sims["3"]
    pairs = [(one.raw, three.raw), *zip(one.raw_per_order, three.raw_per_order)]
    pairs += [(one.channels[c].raw, three.channels[c].raw) for c in one.channels]
    assert len(pairs) == (1 + 3 + 4 if "polarization" in sensor else 1)
    lit = sum(bool(np.any(a.data != 0)) for a, _ in pairs)       # (urban's single-bounce HV, VH are nil)
    assert lit >= (5 if "polarization" in sensor else 1)
    for a, b in pairs:
        np.testing.assert_array_equal(b.data, a.data)
