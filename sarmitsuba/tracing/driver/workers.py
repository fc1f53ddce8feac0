"""Tracing in worker processes: the batches of :func:`sarmitsuba.tracing.driver.trace.trace` on every core.

Why processes (docs/design.md section 11.1): the mesh tracer's host stages are NumPy and Python
between Dr.Jit kernels, and one interpreter lock serialises that Python however many host
threads trace. A worker process has its own interpreter, its own Dr.Jit and its own copy of the
scene, so ``n`` workers trace ``n`` batches truly at once.

How: each worker is ``python -m sarmitsuba.tracing.driver.workers``. It loads the scene from
the same spec the render loaded (source and overrides), derives the same plan
(:func:`~sarmitsuba.tracing.driver.trace.plan_trace`: the same inputs give the same batches in
every process) and checks that each batch it is handed covers the driver's pulses. The driver
hands out the batches as the workers free up, each a few sub-apertures, and merges the finished
spectra by pulse index (:func:`~sarmitsuba.tracing.driver.trace.trace`'s ``run_batches``). A
worker hands back only its batch's reduced spectra (complex64 [channels, pulses, n_pad]), never
its terms, so the traffic between processes is the raw data's size once.

Bits: every batch's deposit is fixed point (docs/physics.md (D7)) and its spectrum is reduced in
the worker by the same NumPy code as in one process, so the raw data are the same bit for bit
for any number of workers, any batch size and any load (``tests/test_workers.py``).

When: :func:`worker_plan` decides before the trace. Workers start only where the cost model's
trace time is at least :data:`MIN_TRACE_SECONDS` (a worker costs a few seconds to import the
runtime and load the scene) and where there are at least two batches; at most the cores this
process may run on (``os.sched_getaffinity``), at most :data:`WORKERS_VARIABLE`, and at most
what the memory available holds: the driver's own peak plus one runtime, scene and working set
per worker (:func:`memory_cap`). ``info`` prints the plan and its cap.

Failures: a worker that raises hands back the exception, which the driver raises; a worker that
dies ends the render with :class:`WorkerError` (an OSError: one message, exit code 2, and
``render``'s staged output removed) naming its exit code and the last lines of its error output.
"""
from __future__ import annotations

import os
import pickle
import queue
import struct
import subprocess
import sys
import tempfile
import threading
import traceback
import warnings
from dataclasses import dataclass
from typing import Any, BinaryIO

from ...core.radar import ParameterError
from .threads import count_variable, usable_cores

__all__ = ["WORKERS_VARIABLE", "MIN_TRACE_SECONDS", "WorkerError", "WorkerPlan", "worker_plan", "memory_cap",
           "usable_cores", "trace_in_workers", "plan_for", "can_use_workers", "load_batch_tracer", "KILL_AFTER_ENV"]

#: The environment variable that sets the most worker processes a render traces on (an integer
#: >= 1; 1 traces in the render's own process). Default: every core this process may run on.
WORKERS_VARIABLE = "SARMITSUBA_WORKERS"
#: A trace the cost model expects to take less than this [s] runs in the render's own process:
#: starting a worker (the runtime's import and the scene's load) costs 3-6 s of each core.
MIN_TRACE_SECONDS = 20.0
#: A worker that would hold more than this [bytes] (its runtime, scene and mesh tables, and a
#: launch's working set) is not started: the render traces in its own process on host threads. On
#: the 1.05 M-triangle footprint city (5.5 GiB a process) two processes traced in 893 s, against
#: 776 s on one process's two host threads, and peaked at 11.0 GiB against 5.0 GiB: the tables'
#: copies cost more than the interpreter lock did. Munich's workers hold 0.75 GiB.
MAX_WORKER_BYTES = 2 * 2**30
#: Batches per worker at least, for balance: the batches are cut smaller until there are this many
#: (a batch of one sub-aperture costs no more per sub-aperture than one of two, measured on Munich;
#: batches of 15 left one core idle for up to a batch's 17 s at the end).
BATCHES_PER_WORKER = 16
#: Fault injection for the tests: a worker whose environment holds ``N`` dies (the whole process,
#: exit code 17) as it starts its ``N``-th batch, as a crashed or killed process would; the driver
#: then leaves every batch to the workers, so that one is sure to die mid-render.
KILL_AFTER_ENV = "SARMITSUBA_WORKER_KILL_AFTER"


class WorkerError(OSError):
    """A trace worker process died (or could not start) before handing back its batch."""


@dataclass(frozen=True)
class WorkerPlan:
    """How many worker processes a trace uses, and why.

    Attributes
    ----------
    workers : int
        Worker processes (1: the render traces in its own process).
    cores : int
        Cores this process may run on.
    memory_cap : int
        Workers the memory available holds (:func:`memory_cap`).
    per_worker_bytes : int
        Estimated peak memory of one worker [bytes].
    reason : str
        Why the count is what it is, for ``info`` and the summary.
    peak_memory_bytes : int
        Estimated peak of the render and its workers together [bytes]: the render's own peak
        plus ``per_worker_bytes`` for each worker besides it.
    """

    workers: int
    cores: int
    memory_cap: int
    per_worker_bytes: int
    reason: str
    peak_memory_bytes: int = 0


def requested_workers() -> int | None:
    """:data:`WORKERS_VARIABLE` as an integer, None when unset. Raises ParameterError otherwise."""
    return count_variable(WORKERS_VARIABLE, "worker processes that trace; 1 traces in the render's own process); "
                                            "unset it to use every core")


def memory_cap(cost: Any, available: int) -> tuple[int, int]:
    """(workers the memory holds, one worker's bytes): the driver keeps its own estimated peak
    (``cost.peak_memory_bytes``), and each worker holds a runtime with the scene and one launch's
    working set (``cost.runtime_bytes + cost.trace_working_bytes``). At least 1 (the driver
    itself traces then)."""
    per_worker = int(cost.runtime_bytes + cost.trace_working_bytes)
    free = available - int(cost.peak_memory_bytes)
    return max(1, free // max(per_worker, 1)), per_worker


def worker_plan(cost: Any, batches: int, mesh: bool, available: int, cores: int | None = None) -> WorkerPlan:
    """The :class:`WorkerPlan` of a render with estimated ``cost``
    (:class:`~sarmitsuba.analysis.cost.CostEstimate`) and ``batches`` trace batches; ``mesh``:
    the mesh tracer traces it (the tube preview and moving shapes stay in one process).
    ``available``: the memory the render may use [bytes]
    (:func:`sarmitsuba.analysis.memory.available_memory`); ``cores``: default :func:`usable_cores`.
    Raises ParameterError for a bad :data:`WORKERS_VARIABLE`."""
    wanted = requested_workers()
    cores = usable_cores() if cores is None else cores
    cap, per_worker = memory_cap(cost, available)
    n, why = _count(cost, batches, mesh, wanted, cores, cap, per_worker, available)
    return WorkerPlan(n, cores, cap, per_worker, why, int(cost.peak_memory_bytes) + (n - 1) * per_worker)


def _count(cost: Any, batches: int, mesh: bool, wanted: int | None, cores: int, cap: int, per_worker: int,
           available: int) -> tuple[int, str]:
    """(processes, why) of :func:`worker_plan`."""
    here = "traced in this process"
    if not mesh:
        return 1, f"{here} (tube preview, moving shapes or derivatives)"
    if wanted == 1:
        return 1, f"{here} ({WORKERS_VARIABLE}=1)"
    if wanted is None and cost.trace_time_s < MIN_TRACE_SECONDS:
        return 1, f"{here} (about {cost.trace_time_s:.0f} s of tracing: workers pay off from {MIN_TRACE_SECONDS:.0f} s)"
    if wanted is None and per_worker > MAX_WORKER_BYTES:
        return 1, (f"{here} (a worker would hold {_gib(per_worker)} of its own scene and tables, over "
                   f"{_gib(MAX_WORKER_BYTES)}: the copies cost more than they gain)")
    limit = min(cores if wanted is None else wanted, cap)
    n = max(1, min(limit, batches))
    if n == 1:
        why = "one core" if limit == cores == 1 else (f"memory holds one ({_gib(available)} available, "
                                                         f"{_gib(per_worker)} per worker)" if cap == 1 else "one batch")
        return 1, f"{here} ({why})"
    why = f"{n} processes on {cores} cores"
    if cap < min(cores if wanted is None else wanted, batches):
        why += f", capped by memory ({_gib(available)} available, {_gib(per_worker)} per worker)"
    elif wanted is not None:
        why += f" ({WORKERS_VARIABLE}={wanted})"
    return n, why


def _gib(n: int) -> str:
    return f"{n / 2**30:.1f} GiB"


# ============================================================================ the worker's side
def load_batch_tracer(spec: tuple, per_batch: int | None = None) -> tuple:
    """(loaded scene, setup, plan, kernel) of the scene ``spec`` = ``(source, sensor, integrator,
    material overrides)`` as :func:`sarmitsuba.scene.loader.load_scene` takes them: what a process
    needs to trace any batch of the render (:func:`~sarmitsuba.tracing.driver.trace.trace_batch`);
    ``per_batch``: the driver's sub-apertures per batch (default the plan's)."""
    import dataclasses
    from .kernel import Kernel
    from .trace import plan_trace, prepare_trace
    from ...scene.loader import load_scene
    loaded = load_scene(*spec)
    setup = prepare_trace(loaded)
    plan = plan_trace(loaded.scene, loaded.params, setup.geometry, setup.window, setup.footprint, loaded.settings,
                      setup.effects)
    if per_batch is not None:
        plan = dataclasses.replace(plan, per_batch=per_batch)
    kernel = Kernel(loaded.scene, loaded.params, setup.window, setup.footprint, loaded.settings, setup.table,
                    setup.effects)
    return loaded, setup, plan, kernel


def _send(stream: BinaryIO, message: Any) -> None:
    blob = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(struct.pack("<Q", len(blob)))
    stream.write(blob)
    stream.flush()


def _receive(stream: BinaryIO) -> Any:
    """The next message, or None at the end of the stream (the other side is gone)."""
    head = stream.read(8)
    if len(head) < 8:
        return None
    size = struct.unpack("<Q", head)[0]
    blob = stream.read(size)
    if len(blob) < size:
        return None
    return pickle.loads(blob)


def _picklable(exc: BaseException) -> BaseException:
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:                    # noqa: BLE001 - any exception that does not survive the trip
        return RuntimeError(f"{type(exc).__name__}: {exc}")


def worker_main() -> int:
    """The worker process: messages on stdin, replies on the original stdout (fd 1 is pointed at
    stderr, so that nothing the runtime prints reaches the replies)."""
    replies = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    requests = sys.stdin.buffer
    start = _receive(requests)
    if start is None:
        return 0
    spec, per_batch, dr_threads = start
    kill_after = int(os.environ.get(KILL_AFTER_ENV, "0") or 0)
    try:
        import drjit as dr                # (`-m` imported the package first: the variant and plugins are set)
        from .trace import trace_batch
        if dr_threads:
            dr.set_thread_count(dr_threads)
        loaded, setup, plan, kernel = load_batch_tracer(spec, per_batch)
    except BaseException as exc:          # noqa: BLE001 - handed to the driver, which raises it
        _send(replies, ("error", _picklable(exc), traceback.format_exc()))
        return 1
    _send(replies, ("ready", os.getpid()))
    done = 0
    while True:
        message = _receive(requests)
        if message is None or message[0] == "stop":
            return 0
        _, g0, pulses = message
        done += 1
        if kill_after and done >= kill_after:
            os._exit(17)
        try:
            if plan.pulses(g0) != tuple(pulses):
                raise RuntimeError(f"worker plan differs from the driver's: batch {g0} covers pulses "
                                   f"{plan.pulses(g0)}, expected {tuple(pulses)}")
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                out = trace_batch(kernel, plan, g0, setup.geometry, setup.window, setup.footprint, loaded.settings,
                                  loaded.params.frequency)
            said = [(str(w.message), w.category) for w in caught]
            _send(replies, ("done", out, said))
        except BaseException as exc:      # noqa: BLE001
            _send(replies, ("error", _picklable(exc), traceback.format_exc()))
            return 1


# ============================================================================ the driver's side
class _Worker:
    """One worker process and the thread that feeds it batches from a shared queue."""

    def __init__(self, index: int, start: tuple, env: dict):
        self.index = index
        self.log = tempfile.TemporaryFile()
        self.process = subprocess.Popen([sys.executable, "-m", "sarmitsuba.tracing.driver.workers"],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log, env=env)
        self.start = start

    def error_tail(self, lines: int = 6) -> str:
        self.log.seek(0)
        text = self.log.read().decode(errors="replace").strip().splitlines()
        return " | ".join(text[-lines:]) if text else "(no error output)"

    def died(self, doing: str) -> WorkerError:
        code = self.process.wait()
        return WorkerError(f"trace worker {self.index} (pid {self.process.pid}) ended with exit code {code} while "
                           f"{doing}; its last output: {self.error_tail()}. Rerun with {WORKERS_VARIABLE}=1 to "
                           "trace in one process, or with fewer workers if memory ran out")

    def run(self, tasks: queue.Queue, results: queue.Queue, plan: Any, compiled: threading.Event) -> None:
        """Feed batches until the queue is empty, the first once ``compiled`` is set (the render's
        first batch has filled Dr.Jit's kernel cache); every outcome goes to ``results``."""
        try:
            _send(self.process.stdin, self.start)
            reply = _receive(self.process.stdout)
            if reply is None:
                raise self.died("loading the scene")
            if reply[0] == "error":
                results.put(("error", reply[1], reply[2]))
                return
            compiled.wait()
            while True:
                try:
                    g0 = tasks.get_nowait()
                except queue.Empty:
                    _send(self.process.stdin, ("stop",))
                    return
                p0, p1 = plan.pulses(g0)
                _send(self.process.stdin, ("batch", g0, (p0, p1)))
                reply = _receive(self.process.stdout)
                if reply is None:
                    raise self.died(f"tracing pulses {p0}-{p1 - 1}")
                results.put((*reply, self.index) if reply[0] == "done" else reply)
                if reply[0] == "error":
                    return
        except (BrokenPipeError, ConnectionError):
            results.put(("error", self.died("reading its batch"), ""))
        except WorkerError as exc:
            results.put(("error", exc, ""))
        except BaseException as exc:      # noqa: BLE001 - reported by the driver
            results.put(("error", exc, traceback.format_exc()))

    def close(self) -> None:
        for stream in (self.process.stdin, self.process.stdout):
            try:
                stream.close()
            except OSError:
                pass
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.log.close()


def batch_size(per_batch: int, n_subapertures: int, workers: int) -> int:
    """Sub-apertures per batch with ``workers`` workers: the plan's, cut until there are at least
    :data:`BATCHES_PER_WORKER` batches per worker (the last batches then balance the load)."""
    return max(1, min(per_batch, n_subapertures // (BATCHES_PER_WORKER * workers)))


def trace_in_workers(spec: tuple, loaded: Any, setup: Any, workers: int, progress: bool = False,
                     dr_threads: int | None = 1) -> Any:
    """:func:`sarmitsuba.tracing.driver.trace.trace` of ``loaded`` on ``workers`` processes: this
    one and ``workers - 1`` worker processes, each loading the scene ``spec`` = ``(source, sensor,
    integrator, material overrides)`` as :func:`~sarmitsuba.scene.loader.load_scene` takes them.
    This process traces from the start, while the workers load. ``dr_threads``: Dr.Jit's threads
    in each process while they trace (None: Dr.Jit's default, every core).

    Returns the :class:`~sarmitsuba.tracing.driver.trace.TraceResult`, the same bits as one process's.

    Raises
    ------
    WorkerError
        A worker died (its exit code and last output are in the message).
    Exception
        Whatever a worker raised while loading the scene or tracing (re-raised here).
    """
    from .trace import trace
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.pop(WORKERS_VARIABLE, None)

    traced_by = set()                      # the processes that traced a batch (0: this one)

    def run_batches(plan, batches, here):
        tasks, results = queue.Queue(), queue.Queue()
        if os.environ.get(KILL_AFTER_ENV):   # fault injection: every batch to the worker that will die
            here = None
        for g0 in batches:
            tasks.put(g0)
        pool = [_Worker(i, (spec, plan.per_batch, dr_threads), env) for i in range(1, min(workers, len(batches)))]
        compiled = threading.Event()         # set once this process's first batch has compiled the kernels
        if here is None:
            compiled.set()
        else:
            here = _first_sets(here, compiled)
        feeders = [threading.Thread(target=w.run, args=(tasks, results, plan, compiled), daemon=True) for w in pool]
        for t in feeders:
            t.start()
        finished = False
        try:
            with _dr_threads(dr_threads):
                for _ in batches:
                    out, who = _next_result(tasks, results, here, feeders)
                    traced_by.add(who)
                    yield out
            finished = True
        finally:
            _drain(tasks)                  # an error: the other workers stop after their batch
            compiled.set()                   # a feeder still waiting goes on, finds no batch and stops
            for w in pool:
                if not finished and w.process.poll() is None:
                    w.process.kill()
            for t in feeders:
                t.join(timeout=60)
            for w in pool:
                w.close()

    import dataclasses
    result = trace(loaded.scene, loaded.params, setup.geometry, setup.window, setup.footprint, loaded.settings,
                   setup.table, progress=progress, effects=setup.effects, run_batches=run_batches, trace_here=True,
                   batch_size=lambda per_batch, n_subs: batch_size(per_batch, n_subs, workers))
    return dataclasses.replace(result, workers=len(traced_by))


def _first_sets(here, compiled: threading.Event):
    """``here``, setting ``compiled`` after its first batch (or its error). The workers wait for it:
    with an empty kernel cache every process would compile the same kernels at once (Munich's
    first run took 1.23 times the warm one so), where after the render's first batch they load
    them from the cache."""
    def first(g0):
        try:
            return here(g0)
        finally:
            compiled.set()
    return first


def _next_result(tasks: queue.Queue, results: queue.Queue, here, feeders: list) -> tuple[dict, int]:
    """The next finished batch and the process that traced it (0: this one): a worker's, if one
    is waiting; else one traced here (``here`` None: never); else the next a worker hands back.
    A worker's error is raised here; WorkerError if every worker has stopped with batches unreturned."""
    try:
        reply = results.get_nowait()
    except queue.Empty:
        try:
            if here is not None:
                return here(tasks.get_nowait()), 0
        except queue.Empty:
            pass
        reply = None
        while reply is None:
            try:
                reply = results.get(timeout=1.0)
            except queue.Empty:
                if not any(t.is_alive() for t in feeders) and results.empty():
                    raise WorkerError("the trace workers stopped without handing back every batch; rerun with "
                                      f"{WORKERS_VARIABLE}=1 to trace in one process") from None
    kind, *rest = reply
    if kind == "error":
        raise rest[0]
    out, said, who = rest
    for text, category in said:
        warnings.warn(text, category, stacklevel=3)
    return out, who


def _drain(tasks: queue.Queue) -> None:
    while True:
        try:
            tasks.get_nowait()
        except queue.Empty:
            return


class _dr_threads:
    """Within it, Dr.Jit runs ``n`` threads (None: as it is); restored on leaving."""

    def __init__(self, n: int | None):
        self.n, self.before = n, None

    def __enter__(self):
        if self.n:
            import drjit as dr
            self.before = dr.thread_count()
            dr.set_thread_count(self.n)

    def __exit__(self, *exc):
        if self.before is not None:
            import drjit as dr
            dr.set_thread_count(self.before)


def can_use_workers(spec: tuple, loaded: Any, effects: Any) -> bool:
    """Whether worker processes can trace this render: the mesh tracer, no moving shapes, the
    float32 lanes and compiled loops a worker starts with (the derivatives' traces set others in
    this process alone), and a scene spec that can be sent to another process."""
    import numpy as np
    from ..loops import lane_float, loop_mode
    if loaded.settings.lit_regions != "patches" or effects.moving_shapes is not None:
        return False
    if loop_mode() is not None or lane_float() is not np.float32:
        return False
    try:
        pickle.dumps(spec)
    except Exception:                    # noqa: BLE001 - a scene built in Python with parts that do not pickle
        return False
    return True


def plan_for(spec: tuple, loaded: Any, effects: Any, cost: Any, available: int) -> WorkerPlan:
    """The :class:`WorkerPlan` of a render: :func:`worker_plan` for its estimated ``cost`` and
    ``available`` memory [bytes], with workers only where :func:`can_use_workers`. ``spec``:
    ``(source, sensor, integrator, material overrides)`` as :func:`~sarmitsuba.scene.loader.load_scene`
    took them. Raises ParameterError (a bad :data:`WORKERS_VARIABLE`)."""
    import mitsuba as mi
    plan = worker_plan(cost, cost.subapertures, can_use_workers(spec, loaded, effects), available)
    if plan.workers > 1 and mi.variant().startswith("cuda") and requested_workers() is None:
        import dataclasses
        return dataclasses.replace(plan, workers=1, peak_memory_bytes=int(cost.peak_memory_bytes),
                                   reason="traced in this process (cuda: worker processes sharing the GPU are not yet "
                                          f"measured; {WORKERS_VARIABLE}=N starts them)")
    return plan


if __name__ == "__main__":
    sys.exit(worker_main())
