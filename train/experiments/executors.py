"""Where a sweep's jobs run: local worker processes (one job each at a time) or Ray tasks.

Both stop cleanly on Ctrl-C or SIGTERM: queued jobs do not start, running trainers stop at their epoch end with
a checkpoint, and a worker whose sweep process died exits instead of taking another job.
"""

from __future__ import annotations

import faulthandler
import os
import select
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager

from train.experiments.jobs import Job, JobResult, Pack, execute_unit
from train.loop.runlog import request_stop, stop_requested


def usable_cpus() -> int:
    """The CPUs this process may run on: its affinity set where the OS gives one (a cluster job or container
    pinned to 4 of a node's 64 cores gets 4), else the machine's count.
    """
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


_STOP = None
"""In a local worker process: the sweep's stop event (set when the user interrupts the sweep)."""


_SWEEP: int | None = None
"""In a local worker process: the pid of the sweep that started it."""

_SWEEP_FD: int | None = None
"""In a local worker process on Linux: a pidfd of the sweep, readable once the sweep has exited (immune to the
pid being reused); None where pidfds are unavailable (the pid is polled instead)."""

WORKER_PRELOAD = ("train.experiments.jobs", "train.loop.trainer", "train.storage.policy")
"""What the fork server imports once (torch, the trainer, every environment), so that a worker starts in a
fraction of a second instead of importing them again (about 4 s of a core each)."""


def worker_context():
    """The multiprocessing context of local workers: forked from a fork server that has imported
    `WORKER_PRELOAD` and run nothing, so no torch or OpenMP thread pool is copied into a worker.

    A worker's parent is that server, which outlives the sweep while any worker lives: a worker watches the
    sweep's own pid (`_follow_sweep`), not its parent.
    """
    import multiprocessing

    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(WORKER_PRELOAD))
    start_fork_server()
    return ctx


def start_fork_server() -> None:
    """Start the workers' fork server now (where it is not running yet), out of Ctrl-C's reach.

    The server imports `WORKER_PRELOAD` for seconds before it ignores SIGINT itself, and a Ctrl-C meanwhile
    killed it with a traceback. It is spawned with SIGINT blocked, which it inherits: a Ctrl-C stays pending
    there until it ignores SIGINT, and each worker unblocks it again (`_init_worker`). This process keeps its
    own handler meanwhile: ignoring SIGINT here too would drop a Ctrl-C that another of its threads (torch's,
    numba's) takes. Outside the main thread the server starts when the first worker does, as before.
    """
    from multiprocessing import forkserver, resource_tracker

    if threading.current_thread() is not threading.main_thread():
        return
    resource_tracker.ensure_running()  # first: starting it unblocks SIGINT (after blocking it for its own start)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        forkserver.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def end_fork_server() -> None:
    """End the workers' fork server (after an interrupted sweep), so that it starts no worker once the sweep
    has gone: one still importing `WORKER_PRELOAD` would otherwise go on to fork the workers asked of it.

    CPython's private attributes differ between versions: where they are missing, the server is left to exit
    by itself.
    """
    from multiprocessing import forkserver

    server = getattr(forkserver, "_forkserver", None)
    pid = getattr(server, "_forkserver_pid", None)
    if pid is None:
        return
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        pass
    stop = getattr(server, "_stop", None)
    if stop is not None:
        try:
            stop()  # closes its pipe, reaps it and removes its socket, so a later sweep starts a new one
        except OSError:
            pass


def _init_worker(stop, sweep: int) -> None:
    """Worker initializer: Ctrl-C reaches the trainer's own handler (a clean stop), not the pool loop; the
    worker gets SIGTERM (a clean stop too) when the sweep's process dies, and then takes no further job; a
    stop of the sweep alone (a signal to its pid only) stops the running trainer as a first signal would.
    """
    global _STOP
    _STOP = stop
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked in its fork server (start_fork_server)
    _follow_sweep(sweep)
    if _sweep_gone():  # it died before this worker started
        os._exit(1)
    threading.Thread(target=_watch_sweep, daemon=True, name="ecorl-sweep-watch").start()
    threading.Thread(target=_relay_stop, args=(stop,), daemon=True, name="ecorl-stop-relay").start()


def _relay_stop(stop) -> None:
    """In a worker: once the sweep's stop event is set, stop the running trainer at its epoch's end."""
    stop.wait()
    request_stop()


def _follow_sweep(pid: int) -> None:
    """Remember the sweep ``pid`` (and open a pidfd of it where the system has them) for `_sweep_gone`."""
    global _SWEEP, _SWEEP_FD
    _SWEEP, _SWEEP_FD = pid, None
    try:
        _SWEEP_FD = os.pidfd_open(pid)
    except (AttributeError, OSError):  # not Linux 5.3+, or the sweep is gone already: the pid is polled
        pass


SWEEP_POLL_S = 1.0
"""How often a local worker checks that its sweep still lives (where it has no pidfd to wait on)."""

ORPHAN_GRACE_S = 300.0
"""How long a worker whose sweep died may take to stop cleanly (finish its epoch, write its checkpoint); past
it, the worker prints every thread's stack to stderr and exits, and the run's last checkpoint stands."""


def _watch_sweep() -> None:
    """In a worker: once the sweep is gone, SIGTERM to itself (a clean stop), unless a stop is already under
    way (Ctrl-C or SIGTERM reached the worker too): a second SIGTERM would cut that stop short.

    A stop that hangs (a CI host once kept a worker waiting on a lock for minutes after its sweep was killed)
    ends at `ORPHAN_GRACE_S`: faulthandler's own thread, which needs no lock of the interpreter's, dumps the
    stacks and exits, so no orphan outlives its sweep for long.
    """
    while not _sweep_gone(SWEEP_POLL_S):
        pass
    faulthandler.dump_traceback_later(ORPHAN_GRACE_S, exit=True, file=sys.stderr)
    if not stop_requested():
        os.kill(os.getpid(), signal.SIGTERM)


def _sweep_gone(wait_s: float = 0.0) -> bool:
    """True in a worker whose sweep process has exited; waits up to ``wait_s`` seconds for that."""
    if _SWEEP is None:
        return False
    if _SWEEP_FD is not None:
        return bool(select.select([_SWEEP_FD], [], [], wait_s)[0])
    time.sleep(wait_s)
    try:
        os.kill(_SWEEP, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # it exists, owned by someone else
        pass
    return False


_INTERRUPTED = False
"""In a local worker process: a job of this worker was stopped by a signal, so it takes no further job."""


def _execute_unless_stopped(job: Job | Pack) -> list[JobResult]:
    """`execute_unit`, unless the sweep was interrupted before this job (or pack) started; a worker whose
    sweep died exits instead of taking (or reporting) a job.

    A worker whose job a signal stopped takes no further job either: the signal may come from a sweep that
    is stopping or dying (its SIGTERM, a Ctrl-C, `_watch_sweep`).
    """
    global _INTERRUPTED
    if _sweep_gone():
        os._exit(0)
    if _INTERRUPTED or (_STOP is not None and _STOP.is_set()):
        return _all(job, "interrupted")
    results = execute_unit(job)
    _INTERRUPTED = _INTERRUPTED or any(r.status == "interrupted" for r in results)
    if _sweep_gone():
        os._exit(0)
    return results


def _all(unit: Job | Pack, status: str, error: str = "") -> list[JobResult]:
    """The same result for every condition of a job or pack."""
    return [JobResult(j.name, status, error=error) for j in (unit.jobs if isinstance(unit, Pack) else [unit])]


class _Terminated(KeyboardInterrupt):
    """SIGTERM to the sweep, handled like Ctrl-C."""


@contextmanager
def _sigterm_interrupts():
    """Inside the block (main thread only), SIGTERM raises `_Terminated`."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise _Terminated()

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run_local(jobs: Sequence[Job | Pack], workers: int, on_result: Callable[[JobResult], None]) -> list[JobResult]:
    """Run ``jobs`` in up to ``workers`` local processes (one job per process at a time)."""
    from concurrent.futures import ProcessPoolExecutor

    results: list[JobResult] = []
    if not jobs:
        return results
    ctx = worker_context()
    stop = ctx.Event()
    pool = ProcessPoolExecutor(max_workers=max(1, min(workers, len(jobs))), mp_context=ctx,
                               initializer=_init_worker, initargs=(stop, os.getpid()))
    pending: dict = {}
    try:
        with _sigterm_interrupts():
            _collect(pool, jobs, pending, results, on_result)
    except KeyboardInterrupt:
        try:
            _shut_down_after_a_stop(pool, stop, list(pending))
        finally:
            end_fork_server()
        raise
    pool.shutdown(wait=True)
    return results


SECOND_SIGNAL_GRACE_S = 3.0
"""After a second signal, how long the sweep waits for its workers to stop by themselves (a Ctrl-C reaches
them too, and a trainer's second signal stops it at once) before it sends them SIGTERM."""

WORKER_EXIT_S = 30.0
"""Once every job has answered, how long an idle worker may take to exit before it is killed."""


def _shut_down_after_a_stop(pool, stop, futures: list) -> None:
    """Set the sweep's ``stop`` (queued jobs do not start; running trainers stop at their epoch end, see
    `_relay_stop`) and wait for the running jobs to answer. A second signal meanwhile stops them at once: workers
    still at work after `SECOND_SIGNAL_GRACE_S` get SIGTERM, which a stopping trainer takes as its second signal
    (the last checkpoint stands); a third kills them. Then the workers are ended and reaped here, with signals
    ignored: the pool's own shutdown joins a thread, and a signal during that join (Python before 3.13) marks the
    thread finished while it runs, which left the sweep waiting in its exit handlers for ever.
    """
    from concurrent.futures import wait

    workers = list((pool._processes or {}).values())
    try:
        stop.set()
        wait(futures)
    except KeyboardInterrupt:
        try:
            if wait(futures, timeout=SECOND_SIGNAL_GRACE_S).not_done:
                for proc in workers:
                    proc.terminate()
            wait(futures)
        except KeyboardInterrupt:
            for proc in workers:
                proc.kill()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_IGN)
    pool.shutdown(wait=False, cancel_futures=True)  # idle workers get their sentinel and exit
    for proc in workers:
        proc.join(WORKER_EXIT_S)
        if proc.is_alive():
            proc.kill()
            proc.join()


def _collect(pool, jobs: Sequence[Job | Pack], pending: dict, results: list[JobResult],
             on_result: Callable[[JobResult], None]) -> None:
    """Submit ``jobs`` to ``pool`` (their futures into ``pending``) and gather their results as they finish."""
    from concurrent.futures import FIRST_COMPLETED, wait

    pending.update({pool.submit(_execute_unless_stopped, job): job for job in jobs})
    while pending:
        finished, _ = wait(pending, return_when=FIRST_COMPLETED)
        for fut in finished:
            job = pending.pop(fut)
            try:
                done = fut.result()
            except Exception as err:  # a worker died (e.g. killed): report it, keep going
                done = _all(job, "failed", f"worker process failed: {err!r}")
            for result in done:
                results.append(result)
                on_result(result)


def _import_ray():
    """Import Ray, or explain how to get it."""
    try:
        import ray
    except ImportError:
        raise RuntimeError("the Ray executor needs Ray: pip install 'ecorl[ray]' (or pip install 'ray>=2.9'), "
                           "or use --executor local") from None
    return ray


RAY_CONNECT_TIMEOUT_S = 10.0
"""How long ``--address HOST:PORT`` may take to accept a connection before the run is refused."""


def check_ray_address(address: str | None) -> None:
    """Refuse at once a cluster address where nothing answers: Ray itself keeps retrying for many minutes."""
    if address in (None, "auto", "local"):
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    host = host.strip("[]")  # an IPv6 literal
    if not host or not port.isdigit():
        raise RuntimeError(f"--address {address!r} is not HOST:PORT, ray://HOST:PORT or auto")
    try:
        socket.create_connection((host, int(port)), timeout=RAY_CONNECT_TIMEOUT_S).close()
    except OSError as err:
        raise RuntimeError(f"no Ray cluster answers at {address} ({err.strerror or err}): start one with 'ray start "
                           f"--head' on its head node, check --address, or use --executor local") from None


def run_ray(jobs: Sequence[Job | Pack], address: str | None, on_result: Callable[[JobResult], None]) -> list[JobResult]:
    """Run ``jobs`` as Ray tasks (one CPU each) on the cluster at ``address`` (None: start a local one).

    Every node must see the results directory at the same path (a shared file system), since each task
    writes its run directory itself.
    """
    ray = _import_ray()
    if not ray.is_initialized():
        check_ray_address(address)
        ray.init(address=address, log_to_driver=False, include_dashboard=False)
    remote = ray.remote(num_cpus=1, max_retries=0)(execute_unit)
    pending = {remote.remote(job): job for job in jobs}
    results: list[JobResult] = []
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            job = pending.pop(ready[0])
            try:
                done = ray.get(ready[0])
            except Exception as err:  # the task's worker died
                done = _all(job, "failed", f"Ray task failed: {err!r}")
            for result in done:
                results.append(result)
                on_result(result)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref)
        raise
    return results
