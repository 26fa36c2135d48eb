"""Sweeps on Dask distributed, and Ctrl-C on them.

``workers=N`` starts a ``LocalCluster`` of N single-threaded worker processes
(:func:`local_cluster`), ``scheduler=ADDRESS`` joins a running one (checked first:
:func:`check_scheduler`). Each worker imports mimarble once, as it starts, and keeps its
loaded scenes and compiled kernels between frames (mimarble/sweeps/frames.py,
``render_frame``); images come back to the sweep's process, which writes them, so no
shared file system is needed. Ctrl-C stops the workers with the sweep: they never see
it themselves, and it is raised here only between Dask's calls (:class:`_Interrupts`).
"""

from __future__ import annotations

import contextlib
import os

import numpy as np

from mimarble.runtime.extras import missing_extra
from mimarble.sweeps.frames import error_text, render_frame
from mimarble.sweeps.settings import SweepError


#: LocalCluster workers per core of this machine at most. Each worker is a process with
#: Mitsuba and Dr.Jit loaded (~160 MB before its first frame), and the frames already
#: use every core (Dr.Jit's threads are shared out among the workers), so more workers
#: add memory, not speed; 4 per core leaves room for one worker's Python work
#: (translating a scene, encoding a PNG) to overlap another's render.
WORKERS_PER_CORE = 4
#: A Dask scheduler must accept the connection, answer Dask's handshake and say it is a
#: scheduler within this (seconds). Dask's own connect timeout does not cover the
#: handshake: a server that accepts and says nothing would keep the sweep waiting forever.
SCHEDULER_TIMEOUT_S = 10


def check_workers(workers) -> int:
    """``workers``, if a LocalCluster of that many can be started here: an integer from 1
    to :data:`WORKERS_PER_CORE` × this machine's cores (SweepError otherwise)."""
    cores = os.cpu_count() or 1
    most = WORKERS_PER_CORE * cores
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise SweepError(f"--workers {workers!r}: must be a whole number, at least 1")
    if workers > most:
        raise SweepError(f"--workers {workers}: at most {most} here ({WORKERS_PER_CORE} per "
                         f"core, {cores} cores): each worker is a process with Mitsuba "
                         f"loaded, and the frames already share every core")
    problem = missing_extra("sweep --workers")
    if problem:
        raise SweepError(problem)
    return int(workers)


def check_scheduler(address) -> None:
    """Refuse ``address`` (SweepError, one sentence) unless a Dask scheduler answers there
    within :data:`SCHEDULER_TIMEOUT_S`: connected to, it must answer Dask's handshake and
    say it is a scheduler. Something else listening there (a web server, a Dask worker)
    is told apart from nothing listening."""
    import asyncio
    import gc
    import logging
    problem = missing_extra("sweep --scheduler")
    if problem:
        raise SweepError(problem)
    from distributed.comm import connect
    from distributed.comm.addressing import parse_address
    from distributed.comm.registry import get_backend
    from distributed.security import Security
    if not isinstance(address, str):
        raise SweepError(f"--scheduler {address!r}: give an address, e.g. tcp://host:8786")
    try:
        get_backend(parse_address(address)[0])
    except ValueError as e:
        raise SweepError(f"--scheduler {address}: not an address Dask knows ({e})") from None

    async def identity():             # with the client's security (tls://), as Client connects
        comm = await connect(address, timeout=SCHEDULER_TIMEOUT_S,
                             **Security().get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    # What Dask logs of a garbled answer (a traceback at CRITICAL) is not for the user:
    # the sentence below says it.
    logger = logging.getLogger("distributed")
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    # On a thread of its own, with its own event loop: the caller may be running one (Jupyter).
    from concurrent.futures import ThreadPoolExecutor
    try:
        with ThreadPoolExecutor(max_workers=1) as thread:
            answer = thread.submit(asyncio.run, asyncio.wait_for(
                identity(), SCHEDULER_TIMEOUT_S + 2)).result()
    except (TimeoutError, asyncio.TimeoutError):
        raise SweepError(f"--scheduler {address}: no Dask scheduler answered there within "
                         f"{SCHEDULER_TIMEOUT_S} s (something accepted the connection and "
                         f"said nothing Dask understands)") from None
    except OSError as e:                 # refused, unreachable, closed: Dask's own timeout
        raise SweepError(f"cannot start or reach the scheduler at {address}: {e}") from None
    except Exception:                    # bytes that are not Dask's ("Unable to allocate 3 EiB")
        answer = None
    finally:
        gc.collect()                     # its unclosed streams are logged when collected
        logger.setLevel(level)
    if not (isinstance(answer, dict) and answer.get("type") == "Scheduler"):
        what = (f"a Dask {answer['type'].lower()}" if isinstance(answer, dict)
                and isinstance(answer.get("type"), str) and len(answer["type"]) < 40
                else "something that is not Dask")
        raise SweepError(f"--scheduler {address}: is not a Dask scheduler ({what} answered "
                         f"there); give a running scheduler's address, e.g. tcp://host:8786")


def dask_results(jobs, workers, scheduler):
    """Each job's result (:func:`~mimarble.sweeps.frames.render_frame` on Dask) as it
    completes: on a :func:`local_cluster` of ``workers`` processes, or on the scheduler at
    ``scheduler``; a task that fails there — a worker lost, say — is that frame's error,
    not the sweep's."""
    from dask.distributed import Client, as_completed
    cluster = client = None
    # Ctrl-C (SIGINT) on Dask is held and raised only while waiting for the next frame
    # and after each: raised inside Dask's own calls (starting the cluster, fetching a
    # result), it leaves a cluster half-made or a callback that logs a traceback. A
    # terminal sends it to the whole process group: the workers never see it (below);
    # they are this process's to stop.
    with _Interrupts() as interrupts:
        try:
            if scheduler is None:
                # Multiprocessing's resource tracker is started first, here: the thread
                # that starts it has SIGINT unblocked afterwards (resource_tracker.py).
                from multiprocessing import resource_tracker
                resource_tracker.ensure_running()
            try:
                with interrupts.blocked_in_new_threads():   # and in the workers they spawn
                    if scheduler is None:
                        cluster = local_cluster(int(workers), jobs[0].get("variant"))
                    client = Client(cluster if cluster is not None else scheduler,
                                    timeout=f"{SCHEDULER_TIMEOUT_S}s")
            except (OSError, ValueError, TimeoutError, RuntimeError) as e:
                # RuntimeError: Dask's "Nanny failed to start." (a worker that could not)
                where = f"the scheduler at {scheduler}" if scheduler else "a LocalCluster"
                raise SweepError(f"cannot start or reach {where}: {e}") from None
            futures = {client.submit(render_frame, job, pure=False): job["index"]
                       for job in jobs}
            completed = as_completed(futures)
            while True:
                with interrupts.raised():
                    future = next(completed, None)
                if future is None:
                    break
                index = futures.pop(future)
                try:
                    result = dict(future.result(), index=index)   # the frame asked for, by this side
                except Exception as e:
                    result = {"index": index, "image": None, "render_s": None,
                              "error": f"on Dask: {error_text(e)}"}
                future.release()                 # the worker can drop the image now
                interrupts.check()
                yield result
                interrupts.check()
        finally:
            _stop_dask(client, cluster)          # a second Ctrl-C is held till it is done


#: LocalCluster workers log at this level and above. Dask's default, WARNING, prints
#: "Event loop was unresponsive" while a frame holds the interpreter; at ERROR a worker
#: whose heartbeat outlives the scheduler by a beat at Ctrl-C prints a traceback ("Failed
#: to communicate with scheduler during heartbeat"). Neither is the user's: a frame's
#: failure is in the index, the sweep's in its own error.
WORKER_LOG_LEVEL = "CRITICAL"


def local_cluster(workers: int, variant: str | None = None):
    """A Dask ``LocalCluster`` of ``workers`` single-threaded worker processes (Dr.Jit runs
    its own threads), no dashboard. Each worker preloads this module (Dask's preload):
    mimarble and Mitsuba start in ``variant`` as the worker starts, not at its first
    frame, SIGINT is ignored there (:func:`dask_setup`), and a worker asked to close
    skips Dr.Jit's and Mitsuba's teardown (:func:`dask_teardown`)."""
    import logging
    from dask.distributed import LocalCluster
    from mimarble.runtime.environment import VARIANT_ENV
    env = {VARIANT_ENV: variant} if variant else {}
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None, silence_logs=getattr(logging, WORKER_LOG_LEVEL),
                        preload=[__name__], env=env)


def dask_setup(worker=None) -> None:
    """Run in each :func:`local_cluster` worker as it starts (Dask calls a preloaded
    module's ``dask_setup``): SIGINT ignored (the sweep's process stops its workers), and
    mimarble started in the client's variant (``$MIMARBLE_VARIANT``, set by the cluster;
    importing mimarble started it already, unless that failed). A worker where
    mimarble cannot start still starts: its frames say why."""
    import signal
    with contextlib.suppress(ValueError):     # not the worker's main thread: leave it
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        import mimarble
        mimarble.start()
    except Exception:        # render_frame starts it again, and records the error
        pass


def dask_teardown(worker=None) -> None:
    """Run in each :func:`local_cluster` worker as it is closed: once Python's exit
    begins, the process ends at once, its output flushed. Dr.Jit's and Mitsuba's own
    teardown frees nothing a process that ends needs freed, and writes nothing (compiled
    kernels are cached as they are compiled), and it made the cluster's stop several times
    longer (docs/benchmarks.md, "Sweeps")."""
    import atexit
    atexit.register(_exit_now)


def _exit_now() -> None:
    import sys
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    os._exit(0)


def _stop_dask(client, cluster) -> None:
    """Close the client, then the cluster (its workers stopped, or killed if a frame keeps
    one past Dask's few seconds): quietly — what Dask logs of its own stop is not the
    user's."""
    import logging
    # Dask's logging configuration gives some of them levels and handlers of their own
    # (distributed.client, tornado.application): each is silenced, not only the roots.
    names = {"distributed", "tornado", "asyncio"}
    names.update(name for name in list(logging.root.manager.loggerDict)
                 if name.split(".")[0] in ("distributed", "tornado", "asyncio"))
    loggers = [logging.getLogger(name) for name in sorted(names)]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


class _Interrupts:
    """Within, SIGINT (Ctrl-C) is held: raised as KeyboardInterrupt only at
    :meth:`check`, inside :meth:`raised`, and when the block is left — never inside
    code that must not be cut short. :meth:`blocked_in_new_threads`: SIGINT is blocked
    in the threads started within too, and so in the processes they start (a
    LocalCluster's workers inherit the mask). Only in the main thread (where Python runs
    signal handlers) and where SIGINT raises KeyboardInterrupt or calls a Python
    handler; elsewhere it does nothing."""

    def __init__(self):
        self.previous = None
        self.held = self.raising = False

    def __enter__(self):
        import signal
        import threading
        if threading.current_thread() is threading.main_thread() and \
                callable(signal.getsignal(signal.SIGINT)):
            self.previous = signal.signal(signal.SIGINT, self._handle)
        return self

    def _handle(self, signum, frame):
        self.held = True
        if self.raising:
            self.check()

    def check(self) -> None:
        """Raise the interrupt held, if one is (as the previous handler would have)."""
        if self.held and self.previous is not None:
            import signal
            self.held = False
            self.previous(signal.SIGINT, None)

    @contextlib.contextmanager
    def raised(self):
        """Within, SIGINT is raised at once (a wait that can be cut short)."""
        self.raising = True       # first: an interrupt from here on is raised, not held
        try:
            self.check()
            yield
        finally:
            self.raising = False

    @contextlib.contextmanager
    def blocked_in_new_threads(self):
        import signal
        mask = None
        if self.previous is not None and hasattr(signal, "pthread_sigmask"):
            mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            yield
        finally:
            if mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)

    def __exit__(self, kind, value, traceback):
        import signal
        if self.previous is None:
            return False
        signal.signal(signal.SIGINT, self.previous)
        if kind is None or kind is GeneratorExit:   # closed early: still say it was asked
            self.check()
        return False
