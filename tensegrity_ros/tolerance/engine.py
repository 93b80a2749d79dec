"""Where a tolerance study's chunks run: in this process, on a LocalCluster, or on a
running dask.distributed cluster.

The chunks are fixed before they run (the same slices of the same sample array whatever
runs them), and :func:`run_chunks` returns their results in chunk order, so the answer
does not depend on the engine.  The only module of the package that imports dask.

* ``processes=1`` (and no scheduler): a plain loop here, dask is not even imported;
* default: a ``LocalCluster`` of one single-threaded worker process per core, started
  and closed by the call;
* ``scheduler='tcp://HOST:8786'``: an existing cluster (``dask scheduler`` plus ``dask
  worker tcp://HOST:8786`` on each machine, the package installed on every worker).

A worker that dies loses no sample: the scheduler gives its tasks to another worker
(up to ``distributed.scheduler.allowed-failures`` deaths per task), and a task that
raises is retried ``retries`` times.  Ctrl-C (KeyboardInterrupt) cancels the tasks and
closes the client and the LocalCluster (its worker processes end) before it propagates.
A terminal's Ctrl-C reaches the LocalCluster's worker processes too (one process group):
they are started with SIGINT blocked, so only this process answers it (distributed's
worker processes would otherwise each die of it with a traceback on stderr).
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
import os
import signal
import time

#: Seconds to wait for a scheduler to answer before giving up.
CONNECT_TIMEOUT = 30.0


@dataclass(frozen=True)
class EngineRun:
    """How a run went: the engine, its workers, wall time of the chunks (cluster
    start-up excluded), start-up time, and the chunks' own compute time (each chunk
    timed where it ran)."""

    engine: str
    workers: int
    wall_seconds: float
    startup_seconds: float
    chunk_seconds: float
    chunk_cpu_seconds: float
    chunks: int

    @property
    def overhead(self):
        """The share of the workers' time not spent in chunks: 1 - sum(chunk time) /
        (workers x wall time); includes idle workers at the end of the run."""
        busy = self.workers * self.wall_seconds
        return max(0.0, 1.0 - self.chunk_seconds / busy) if busy > 0 else 0.0


def cores():
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                      # not on Linux
        return os.cpu_count() or 1


class WorkerMismatch(RuntimeError):
    """A worker runs other code than this process (another version of the package)."""


def run_chunks(function, chunks, *, processes=None, scheduler=None, progress=False,
               retries=2, sizes=None, description='samples', fingerprint=None):
    """``[function(*chunk) for chunk in chunks]`` on the chosen engine, in chunk order.

    ``function`` returns ``(result, wall_seconds, cpu_seconds)`` of its own work.
    ``sizes``: samples per chunk, for the progress bar.  ``fingerprint``: a function
    whose value every worker must share with this process (the code's digest), checked
    before any chunk runs (:class:`WorkerMismatch`).  Returns (results, EngineRun).
    """
    chunks = list(chunks)
    sizes = list(sizes) if sizes is not None else [1] * len(chunks)
    if scheduler is None and processes == 1:
        return _run_here(function, chunks, progress, sizes, description)
    return _run_dask(function, chunks, processes, scheduler, progress, retries, sizes,
                     description, fingerprint)


def _bar(progress, total, description):
    if not progress:
        return None
    from tqdm import tqdm

    # one refresh per finished chunk (a few per second at most): none is skipped
    return tqdm(total=total, unit=' ' + description, dynamic_ncols=True, leave=False,
                mininterval=0.0)


def _run_here(function, chunks, progress, sizes, description):
    bar = _bar(progress, sum(sizes), description)
    t0 = time.perf_counter()
    results, wall, cpu = [], 0.0, 0.0
    try:
        for chunk, size in zip(chunks, sizes):
            result, w, c = function(*chunk)
            results.append(result)
            wall, cpu = wall + w, cpu + c
            if bar is not None:
                bar.update(size)
    finally:
        if bar is not None:
            bar.close()
    return results, EngineRun('in-process', 1, time.perf_counter() - t0, 0.0, wall, cpu,
                              len(chunks))


@contextmanager
def _sigint_kept_from_new_threads():
    """Block SIGINT in this thread while the block runs, for the threads it starts.

    A thread inherits its creator's signal mask, and a process its spawning thread's
    (fork and exec keep it): the LocalCluster's event loop thread, started here, and the
    threads it starts to spawn (and respawn) worker processes keep SIGINT blocked, so
    the workers never see a terminal's Ctrl-C.  This thread's mask is restored on exit,
    and a Ctrl-C that came meanwhile is then delivered (deferred, not lost).
    multiprocessing's resource tracker is started first: starting it unblocks SIGINT in
    the thread that starts it (SIG_UNBLOCK, not the mask it found; CPython 3.11), which
    would be the event loop's.  Without pthread_sigmask (Windows) it does nothing.
    """
    if not hasattr(signal, 'pthread_sigmask'):
        yield
        return
    from multiprocessing import resource_tracker
    resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def local_cluster(n):
    """A LocalCluster of ``n`` single-threaded worker processes on 127.0.0.1 whose
    workers ignore Ctrl-C (SIGINT blocked): the caller answers it and closes the cluster.
    Their logs below CRITICAL stay silent: what fails in a chunk reaches the caller as
    the task's exception, and a Ctrl-C's close, which stops the scheduler while a
    worker may still be sending its heartbeat, made 1 in ~8 interrupted runs print that
    worker's ERROR with its traceback (test_tolerance_cluster::test_ctrl_c_on_a_terminal_
    prints_one_line_not_the_workers_tracebacks, on a 2-core AMD EPYC)."""
    import logging

    from distributed import LocalCluster
    cluster = None
    try:
        with _sigint_kept_from_new_threads():
            # loopback only; its HTTP server on a free port (8787 may be another's)
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   host='127.0.0.1', dashboard_address='127.0.0.1:0',
                                   silence_logs=logging.CRITICAL)
    except KeyboardInterrupt:           # a Ctrl-C during start-up, delivered at the end
        if cluster is not None:
            cluster.close()
        raise
    return cluster


def _check_workers(client, fingerprint):
    mine = fingerprint()
    try:
        theirs = client.run(fingerprint)
    except Exception as exc:            # e.g. an older package without this function
        raise WorkerMismatch(f'the workers cannot run this tensegrity_ros code ({exc}): '
                             f'install the same version on every worker and restart them') \
            from None
    other = sorted(w for w, value in theirs.items() if value != mine)
    if other:
        raise WorkerMismatch(f'{len(other)} of {len(theirs)} workers run other tensegrity_ros '
                             f'code than this process (e.g. {other[0]}: '
                             f'{theirs[other[0]]} != {mine}): install the same version on '
                             f'every worker and restart them')


def _run_dask(function, chunks, processes, scheduler, progress, retries, sizes, description,
              fingerprint=None):
    from distributed import as_completed, Client

    t0 = time.perf_counter()
    cluster = client = None
    futures = []
    try:
        if scheduler is None:
            n = processes or cores()
            cluster = local_cluster(n)
            client = Client(cluster, timeout=CONNECT_TIMEOUT)
            engine = f'LocalCluster ({n} worker processes)'
        else:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
            engine = f'dask scheduler {scheduler}'
        workers = len(client.scheduler_info().get('workers', {}))
        if workers == 0:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
            workers = len(client.scheduler_info().get('workers', {}))
        if fingerprint is not None:
            _check_workers(client, fingerprint)
        startup = time.perf_counter() - t0
        t1 = time.perf_counter()
        token = f'{os.getpid()}-{time.time_ns()}'
        keys = [f'tolerance-chunk-{token}-{i}' for i in range(len(chunks))]
        futures = [client.submit(function, *chunk, key=key, retries=retries, pure=False)
                   for chunk, key in zip(chunks, keys)]
        index = {f.key: i for i, f in enumerate(futures)}
        bar = _bar(progress, sum(sizes), description)
        try:
            for future in as_completed(futures):
                if bar is not None:
                    bar.update(sizes[index[future.key]])
        finally:
            if bar is not None:
                bar.close()
        done = client.gather(futures)
        wall = time.perf_counter() - t1
        results = [r for r, _, _ in done]
        run = EngineRun(engine, max(workers, 1), wall, startup, sum(w for _, w, _ in done),
                        sum(c for _, _, c in done), len(chunks))
        return results, run
    except KeyboardInterrupt:
        if client is not None and futures:
            try:
                client.cancel(futures)
            except Exception:           # closing anyway
                pass
        raise
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
