"""Tracing on a Dask cluster: the pulse batches of :func:`sarmitsuba.tracing.driver.trace.trace` as Dask tasks.

``render --scheduler local`` starts a ``LocalCluster`` of worker processes (one thread each);
``--scheduler tcp://HOST:PORT`` uses a running cluster (``dask scheduler`` and its
``dask worker`` processes, docs/design.md section 11). The driver loads the scene as usual (it needs
the scene's box for the plan and the image grid) and sends each worker only the scene's
source and overrides; a worker loads the scene once, derives the same plan
(:func:`sarmitsuba.tracing.driver.trace.prepare_trace`, :func:`sarmitsuba.tracing.driver.trace.plan_trace`: the same
inputs give the same batches in every process) and traces the batches it is given
(:func:`sarmitsuba.tracing.driver.trace.trace_batch`). The driver merges the batches by pulse index (and sums
the diagnostic totals in pulse order). The kernels and seeds are the one-process run's, so the
raw data and their speckle agree with it to float32 rounding: Dr.Jit's multithreaded deposits
add in a varying order, so two one-process runs differ by about -160 dB NRMSE and a Dask run by
-140 to -155 dB.

A script that calls ``simulate(..., scheduler="local")`` must do so under
``if __name__ == "__main__":``: the LocalCluster's worker processes are spawned and import the
main module (:class:`ClusterError` otherwise).

Failures: Dask reschedules the tasks of a worker that dies (up to its ``allowed-failures``);
a batch that still fails, or raises, stops the run with :class:`ClusterError` (an OSError,
exit code 2 on the command line), and ``render``'s staged output directory is removed.
"""
from __future__ import annotations

import contextlib
import hashlib
import logging
import pickle
import re
from typing import Any, Iterator

from ...core.radar import ParameterError
from .trace import TraceResult, trace, trace_batch

__all__ = ["ClusterError", "check_scheduler", "connect", "trace_on_cluster", "trace_task", "worker_loads", "LOCAL_WORKERS"]

#: Worker processes of ``--scheduler local`` (one thread each).
LOCAL_WORKERS = 2
#: Seconds to wait for a ``tcp://`` scheduler to answer.
CONNECT_TIMEOUT_S = 10

_ADDRESS = re.compile(r"^(tcp|tls)://[A-Za-z0-9_.\-\[\]:]+:\d+$")
#: The worker's scene, setup, plan and kernel, for one scene key at a time (a live Mitsuba scene
#: slows the tracing of later ones, so an older entry is dropped when another scene arrives).
_WORKER_CACHE: dict[str, Any] = {}
#: Scenes this process has loaded as a worker (see :func:`worker_loads`).
_LOADS = [0]


class ClusterError(OSError):
    """The Dask cluster could not trace a batch (a task failed, or its workers kept dying)."""


def check_scheduler(scheduler: str) -> str:
    """``scheduler`` if it is ``"local"`` or ``tcp://HOST:PORT`` (``tls://`` too); ParameterError otherwise."""
    if scheduler == "local" or (isinstance(scheduler, str) and _ADDRESS.match(scheduler)):
        return scheduler
    raise ParameterError(f"scheduler = {scheduler!r}: use 'local' (a Dask LocalCluster of {LOCAL_WORKERS} worker "
                         "processes on this machine) or the address of a running Dask scheduler, "
                         "tcp://HOST:PORT (started with `dask scheduler`)")


@contextlib.contextmanager
def connect(scheduler: str) -> Iterator[Any]:
    """A ``distributed.Client`` for ``scheduler``, closed (with its LocalCluster) on exit.

    Raises ParameterError naming ``scheduler`` when a ``tcp://`` scheduler does not answer
    within :data:`CONNECT_TIMEOUT_S`, ClusterError when the LocalCluster does not start.
    """
    from distributed import Client, LocalCluster
    check_scheduler(scheduler)
    cluster = None
    if scheduler == "local":
        try:
            cluster = LocalCluster(n_workers=LOCAL_WORKERS, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
        except RuntimeError as exc:          # "Nanny failed to start": usually a script without a main guard
            raise ClusterError(f"scheduler = 'local': the Dask LocalCluster did not start ({exc}); its worker "
                               "processes import the main module, so a script that renders with "
                               "scheduler='local' must do so under `if __name__ == \"__main__\":`") from None
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise ParameterError(f"scheduler = {scheduler!r} did not answer within {CONNECT_TIMEOUT_S} s ({exc}): "
                                 "start it with `dask scheduler` and at least one `dask worker ADDRESS`, or use "
                                 "--scheduler local") from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def scene_key(spec: tuple) -> str:
    """A digest of the scene spec ``(source, sensor, integrator, material overrides)``; ParameterError
    naming the scene when it cannot be sent to workers (pickled)."""
    try:
        blob = pickle.dumps(spec)
    except (pickle.PicklingError, TypeError, AttributeError) as exc:
        raise ParameterError(f"scheduler: the scene {spec[0]!r} cannot be sent to Dask workers ({exc}); save it as "
                             "XML, or render without --scheduler") from None
    return hashlib.sha256(blob).hexdigest()[:16]


def _worker_state(spec: tuple, key: str) -> tuple:
    """(loaded scene, setup, plan, kernel) for ``spec``, loaded once per worker process."""
    if key not in _WORKER_CACHE:
        from .workers import load_batch_tracer
        _WORKER_CACHE.clear()
        loaded, setup, plan, kernel = load_batch_tracer(spec)
        _LOADS[0] += 1
        # a worker with several threads runs several tasks at once on this kernel: atomic deposits
        kernel.returns.sums.shared_by(_worker_threads())
        _WORKER_CACHE[key] = (loaded, setup, plan, kernel)
    return _WORKER_CACHE[key]


def _worker_threads() -> int:
    """The threads of the Dask worker running this task (1 outside a worker)."""
    try:
        from distributed import get_worker
        return int(get_worker().state.nthreads)
    except (ImportError, ValueError, AttributeError):
        return 1


#: Fault injection for the tests: a worker whose environment names a file here that does not
#: exist yet creates it and dies (the whole process) in its first task, as a crashed node would.
KILL_ONCE_ENV = "SARMITSUBA_DASK_KILL_ONCE"


def _fault_injection() -> None:
    """Die once if :data:`KILL_ONCE_ENV` names a missing file (tests of worker loss only)."""
    import os
    marker = os.environ.get(KILL_ONCE_ENV)
    if marker and not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(17)


def worker_loads() -> int:
    """How many times this (worker) process has loaded a scene for :func:`trace_task`."""
    return _LOADS[0]


def trace_task(spec: tuple, key: str, g0: int, pulses: tuple[int, int]) -> dict:
    """Dask task: trace the batch at sub-aperture ``g0`` of the scene ``spec`` on this worker
    (:func:`sarmitsuba.tracing.driver.trace.trace_batch`'s result). Raises RuntimeError if this worker's plan
    gives the batch other pulses than the driver's (a different scene or package version)."""
    _fault_injection()
    loaded, setup, plan, kernel = _worker_state(spec, key)
    if plan.pulses(g0) != tuple(pulses):
        raise RuntimeError(f"worker plan differs from the driver's: batch {g0} covers pulses {plan.pulses(g0)}, "
                           f"expected {tuple(pulses)} (same sarmitsuba version and scene files on every worker?)")
    return trace_batch(kernel, plan, g0, setup.geometry, setup.window, setup.footprint, loaded.settings,
                       loaded.params.frequency)


def trace_on_cluster(scheduler: str, spec: tuple, loaded: Any, setup: Any, progress: bool = False) -> TraceResult:
    """:func:`sarmitsuba.tracing.driver.trace.trace` of ``loaded`` with its batches traced on the Dask cluster
    ``scheduler``; ``spec`` = ``(source, sensor, integrator, material overrides)`` as given to
    :func:`sarmitsuba.scene.loader.load_scene`, from which workers load the same scene.

    Raises ParameterError (bad or silent scheduler, a scene that cannot be pickled) and
    ClusterError (a batch failed on the cluster).
    """
    check_scheduler(scheduler)
    key = scene_key(spec)

    def run_batches(plan, batches):
        from distributed import as_completed
        futures = [client.submit(trace_task, spec, key, g0, plan.pulses(g0), pure=False) for g0 in batches]
        try:
            for future in as_completed(futures):
                yield future.result()
        except Exception as exc:             # a task's own error, or KilledWorker after repeated deaths
            raise ClusterError(f"scheduler {scheduler}: a trace batch failed on the cluster: "
                               f"{type(exc).__name__}: {exc}") from None
        finally:
            client.cancel(futures)

    with connect(scheduler) as client:
        return trace(loaded.scene, loaded.params, setup.geometry, setup.window, setup.footprint, loaded.settings,
                     setup.table, progress=progress, effects=setup.effects, run_batches=run_batches)
