"""Where independent fits run: one ``concurrent.futures.Executor`` behind a small seam.

:func:`make_executor` turns the user's choice into an executor:

- ``workers=1``: :class:`InProcessExecutor`, each task runs at ``submit`` in the calling process;
- ``workers=N`` (default: the cores this process may use): :class:`LocalPoolExecutor`, N spawned worker
  processes (``concurrent.futures.ProcessPoolExecutor``), rebuilt by :meth:`LocalPoolExecutor.restart`
  when a worker dies;
- ``scheduler="local:N"``: :class:`DaskExecutor` on a new ``dask.distributed.LocalCluster`` of N
  single-threaded worker processes; ``scheduler="tcp://host:8786"`` (any Dask address) or a scheduler
  JSON file: an existing Dask cluster, whose scheduler reschedules the task of a worker that dies.

Every worker process runs single-threaded BLAS and numba (no oversubscription when N fits share N
cores) and compiles numba kernels into a writable cache (:func:`prepare_worker`). The executors carry
two duck-typed extras that :mod:`dynmodel.batch` uses and that foreign executors may lack:
``slots`` (tasks worth keeping in flight) and ``restart()`` (rebuild after a dead worker).
"""

from __future__ import annotations

import os
import socket
import tempfile
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from .errors import DynmodelError

#: environment of a worker process: single-threaded BLAS / OpenMP / numba
WORKER_ENV = {
    "OPENBLAS_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
}
#: seconds to wait for a Dask scheduler to answer
CONNECT_TIMEOUT = 10.0
DASK_EXTRA = 'pip install "dynmodel[dask]"'


def available_cores() -> int:
    """Cores this process may run on (CPU affinity, e.g. a SLURM allocation), else the machine's."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


# ---------------------------------------------------------------- worker set-up


def _writable(folder: Path) -> bool:
    """Can this process create files in ``folder`` (creating it if needed)? A real write, since
    permission bits say nothing on read-only mounts or for root."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".dynmodel-probe-", dir=folder)
        os.close(fd)
        os.unlink(probe)
        return True
    except OSError:
        return False


def numba_cache_dir(package_dir: Path | None = None) -> str | None:
    """Where numba should cache compiled kernels in this process: None to keep its default (next to
    the sources, shared with single fits) when that folder is writable or ``NUMBA_CACHE_DIR`` is set;
    otherwise a per-user folder in the temporary directory (cluster installs are often read-only)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    package_dir = package_dir or Path(__file__).resolve().parent
    if _writable(package_dir / "kernels" / "__pycache__"):
        return None
    user = os.environ.get("USER") or str(os.getuid() if hasattr(os, "getuid") else "user")
    return str(Path(tempfile.gettempdir()) / f"dynmodel-numba-cache-{user}")


def _tune_malloc() -> None:
    """Undo the cost of ``MALLOC_TRIM_THRESHOLD_`` in a worker process.

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``: glibc then gives back to the
    system every freed block above 64 kB and maps large arrays afresh each time, which made the same
    fit take 1.6 times the CPU time (quick-start ESN, measured). Where that variable is set (in a
    worker process, never in the user's own process), large arrays come from the heap up to 32 MB and
    the heap is trimmed above 128 MB instead."""
    import multiprocessing
    import sys

    if not os.environ.get("MALLOC_TRIM_THRESHOLD_") or multiprocessing.parent_process() is None:
        return
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 32 << 20)  # M_MMAP_THRESHOLD
        libc.mallopt(-1, 128 << 20)  # M_TRIM_THRESHOLD
    except (OSError, AttributeError):  # not glibc
        pass


_prepared = False
_prepare_lock = threading.Lock()


def prepare_worker() -> None:
    """Set up the current process for running fits (idempotent, cheap after the first call).

    Single-threaded numerics: the thread variables are set when the libraries are not loaded yet (a
    spawned worker), and fits limit BLAS threads themselves (:mod:`dynmodel.threads`). The numba cache
    goes to a writable folder (:func:`numba_cache_dir`) before the first kernel is loaded. Memory
    trimming set up by a Dask nanny is relaxed (:func:`_tune_malloc`)."""
    global _prepared
    if _prepared:
        return
    with _prepare_lock:
        if _prepared:
            return
        import sys

        if "numpy" not in sys.modules:
            for key, value in WORKER_ENV.items():
                os.environ[key] = value
        cache = numba_cache_dir()
        if cache is not None:
            Path(cache).mkdir(parents=True, exist_ok=True)
            os.environ["NUMBA_CACHE_DIR"] = cache
            if "numba" in sys.modules:
                from numba.core import config

                config.CACHE_DIR = cache
        _tune_malloc()
        _prepared = True


def warm_worker() -> int:
    """Import what a fit needs (the plugins included) in a worker, ahead of its first point; returns the
    pid. Workers do this while the parent checks the data, which hides seconds of start-up."""
    prepare_worker()
    from . import engine, registry  # noqa: F401

    registry.families()
    registry.sources()
    return os.getpid()


#: seconds between a pool worker's checks that the process that started it still runs
PARENT_CHECK = 1.0


def _exit_with_parent(parent: int) -> None:
    """A pool worker's watchdog thread: exit as soon as the process that started the pool is gone. A parent
    killed outright (SIGKILL, out of memory, a script ended by SIGTERM's default action, a notebook kernel
    restarted) cannot stop its workers, and each would otherwise finish its fit, then wait forever to hand
    over a result nobody reads, holding its memory (two such workers of a killed benchmark script were found
    25 minutes later, 300 MB each). An orphan is adopted by another process, so its parent id changes."""
    while True:
        time.sleep(PARENT_CHECK)
        if os.getppid() != parent:
            os._exit(1)


def _pool_worker_init(parent: int | None = None) -> None:
    """A local pool worker: Ctrl-C is the parent's business (it stops the workers), the worker ends with
    the parent (:func:`_exit_with_parent`), then prepare."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent is not None and os.getppid() == parent:
        threading.Thread(target=_exit_with_parent, args=(parent,), name="exit-with-parent", daemon=True).start()
    prepare_worker()


@contextmanager
def _sigint_ignored():
    """Processes started inside inherit an ignored SIGINT: a Ctrl-C in the terminal then reaches only
    the parent, which shuts them down cleanly (no tracebacks from every worker)."""
    import signal

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


# ---------------------------------------------------------------- executors


class InProcessExecutor(Executor):
    """Runs each task at ``submit``, in the calling thread: no pickling, tracebacks as usual, the
    parent's loaded data reused. KeyboardInterrupt propagates from ``submit``, also out of an annealing,
    which would otherwise keep its best state so far and return (:func:`dynmodel.anneal.interrupts_propagate`):
    a Ctrl-C stops the batch, never only the task that happens to run."""

    kind = "in-process"
    slots = 1

    def __init__(self) -> None:
        self._shutdown = False

    @property
    def description(self) -> str:
        return "in-process (1 worker)"

    def submit(self, fn: Callable, /, *args: Any, **kwargs: Any) -> Future:
        if self._shutdown:
            raise RuntimeError("cannot schedule new futures after shutdown")
        future: Future = Future()
        future.set_running_or_notify_cancel()
        from .anneal import interrupts_propagate

        try:
            with interrupts_propagate():
                result = fn(*args, **kwargs)
        except Exception as exc:  # KeyboardInterrupt and SystemExit propagate
            future.set_exception(exc)
        else:
            future.set_result(result)
        return future

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Also drops the recordings cached in this process for the tasks."""
        from .batch import clear_data_cache

        self._shutdown = True
        clear_data_cache()

    def restart(self) -> None:
        self._shutdown = False


class LocalPoolExecutor(Executor):
    """N spawned worker processes on this machine (a ``ProcessPoolExecutor``).

    Workers start with single-threaded BLAS and numba (the environment of :data:`WORKER_ENV`) and run
    :func:`prepare_worker` first. A worker killed mid-task breaks the whole pool (BrokenProcessPool);
    :meth:`restart` replaces it so that the unfinished tasks can be resubmitted."""

    kind = "process-pool"

    def __init__(self, workers: int, warm: bool = True):
        if workers < 1:
            raise ValueError("workers must be at least 1")
        self.workers = int(workers)
        self.warm = warm
        self._lock = threading.Lock()
        self._pool = self._new_pool()
        self._warm()

    def _warm(self) -> None:
        """Start every worker now and let it import dynmodel (see :func:`warm_worker`)."""
        if self.warm:
            for _ in range(self.workers):
                self.submit(warm_worker)

    @property
    def slots(self) -> int:
        return self.workers

    @property
    def description(self) -> str:
        return f"{self.workers} local worker process{'es' if self.workers > 1 else ''}"

    def _new_pool(self) -> ProcessPoolExecutor:
        import multiprocessing

        return ProcessPoolExecutor(
            self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_pool_worker_init,
            initargs=(os.getpid(),),
        )

    def submit(self, fn: Callable, /, *args: Any, **kwargs: Any) -> Future:
        # workers are spawned on demand inside submit: they inherit this environment
        with self._lock:
            saved = {k: os.environ.get(k) for k in WORKER_ENV}
            os.environ.update(WORKER_ENV)
            try:
                return self._pool.submit(fn, *args, **kwargs)
            finally:
                for key, value in saved.items():
                    if value is None:
                        os.environ.pop(key, None)
                    else:
                        os.environ[key] = value

    def _kill(self, pool: ProcessPoolExecutor) -> None:
        for proc in list((pool._processes or {}).values()):
            if proc.is_alive():
                proc.kill()

    def restart(self) -> None:
        """Replace a broken pool by a fresh one (pending tasks of the old pool are lost)."""
        with self._lock:
            old = self._pool
            self._kill(old)
            old.shutdown(wait=True, cancel_futures=True)
            self._pool = self._new_pool()
        self._warm()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """``wait=False`` also stops the workers at once (abandoned fits are killed, not awaited)."""
        if not wait:
            self._kill(self._pool)
        self._pool.shutdown(wait=wait, cancel_futures=cancel_futures or not wait)


class DaskExecutor(Executor):
    """Tasks on a Dask distributed cluster through the client's executor (``pure=False``: every
    submission runs). Owns the client, and the LocalCluster when it started one."""

    kind = "dask"

    def __init__(self, client: Any, cluster: Any = None, address: str = ""):
        self.client = client
        self.cluster = cluster
        self.address = address or str(client.scheduler.address)
        self._executor = client.get_executor(pure=False)
        self._threads = (0, -1e9)  # (worker threads, when asked)

    @property
    def workers(self) -> int:
        """Worker threads the cluster has (asked at most every 2 s: it may grow or shrink during a sweep)."""
        import time

        n, when = self._threads
        if time.monotonic() - when > 2.0:
            try:
                n = int(sum(self.client.nthreads().values()))
            except Exception:  # a scheduler that went away: the next submit reports it
                n = 0
            self._threads = (n, time.monotonic())
        return n

    @property
    def slots(self) -> int:
        # one queued task per thread hides the scheduler's round trip; at least 2 while workers start
        return max(2, 2 * self.workers)

    @property
    def description(self) -> str:
        where = "a LocalCluster" if self.cluster is not None else f"the Dask cluster at {self.address}"
        n = self.workers
        return f"{where} ({n} worker thread{'s' if n != 1 else ''})"

    def submit(self, fn: Callable, /, *args: Any, **kwargs: Any) -> Future:
        return self._executor.submit(fn, *args, **kwargs)

    def warm(self) -> None:
        """Let every current worker import dynmodel now (:func:`warm_worker`), without waiting."""
        workers = list(self.client.scheduler_info().get("workers", {}))
        self._warming = [  # held: Dask cancels a future nobody references
            self.client.submit(warm_worker, pure=False, workers=[w], allow_other_workers=False) for w in workers
        ]

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        try:
            self._executor.shutdown(wait=wait and not cancel_futures)
        finally:
            self.client.close()
            if self.cluster is not None:
                self.cluster.close()


# ---------------------------------------------------------------- choosing one


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise DynmodelError(
            "running on a Dask cluster needs the optional dask extra, which is not installed",
            "--scheduler",
            f"{DASK_EXTRA}, or leave out --scheduler to use the local process pool",
        ) from None
    return distributed


def _check_reachable(address: str, timeout: float) -> None:
    """Fail fast, in one line, when nothing listens at a tcp:// address (Dask itself retries for long)."""
    parts = urlsplit(address)
    if parts.scheme not in ("tcp", "tls") or not parts.hostname:
        return
    port = parts.port or 8786
    try:
        with socket.create_connection((parts.hostname, port), timeout=timeout):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        if isinstance(exc, socket.timeout):
            reason = f"no answer within {timeout:g} s"
        raise DynmodelError(
            f"cannot reach the Dask scheduler at {address} ({reason})",
            "--scheduler",
            "start it (dask scheduler, or a dask-jobqueue cluster) and check host and port, or use --scheduler local:N",
        ) from None


def _local_cluster(text: str):
    try:
        n = int(text.split(":", 1)[1])
    except ValueError:
        n = 0
    if n < 1:
        raise DynmodelError(
            f"'{text}' does not name a number of workers", "--scheduler", "write local:N with N >= 1, e.g. local:2"
        )
    distributed = _import_distributed()
    import logging

    import dask

    # workers with glibc's own malloc thresholds, like the local pool (see _tune_malloc)
    with _sigint_ignored(), dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        cluster = distributed.LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
            env=dict(WORKER_ENV),
        )
    executor = DaskExecutor(distributed.Client(cluster), cluster, cluster.scheduler_address)
    executor.warm()
    return executor


def _remote_cluster(address: str, timeout: float):
    distributed = _import_distributed()
    if "://" not in address:
        path = Path(address)
        if not path.is_file():
            raise DynmodelError(
                f"'{address}' is neither a Dask address nor a scheduler file",
                "--scheduler",
                "write tcp://HOST:PORT, local:N, or the path of a scheduler JSON file",
            )
        kwargs: dict[str, Any] = {"scheduler_file": str(path)}
    else:
        _check_reachable(address, timeout)
        kwargs = {"address": address}
    try:
        client = distributed.Client(timeout=timeout, **kwargs)
    except (OSError, TimeoutError, ValueError) as exc:
        raise DynmodelError(
            f"cannot connect to the Dask scheduler {address} ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})",
            "--scheduler",
            "check that the scheduler runs and the address is right",
        ) from None
    return DaskExecutor(client, None, address)


def make_executor(
    workers: int | None = None, scheduler: str | None = None, *, connect_timeout: float = CONNECT_TIMEOUT
) -> Executor:
    """The executor for ``workers`` / ``scheduler`` (see the module docstring). Use it as a context
    manager, or call ``shutdown()``; ``shutdown(wait=False)`` abandons running tasks.

    Raises DynmodelError (one line) for an unknown or unreachable scheduler or a missing dask extra."""
    if scheduler:
        if workers is not None:
            raise DynmodelError(
                "--workers sets the local process pool and --scheduler a Dask cluster; give one of them",
                "--workers",
                "leave out --workers (the cluster's workers run the points; local:N sets their number)",
            )
        if scheduler.startswith("local:") or scheduler == "local":
            return _local_cluster(scheduler)
        return _remote_cluster(scheduler, connect_timeout)
    n = available_cores() if workers is None else int(workers)
    if n < 1:
        raise DynmodelError(f"--workers {n} is not a number of processes", "--workers", "use --workers 1 or more")
    return InProcessExecutor() if n == 1 else LocalPoolExecutor(n)


def slots(executor: Executor) -> int:
    """Tasks worth keeping in flight on ``executor`` (its own ``slots``, else its worker count)."""
    own = getattr(executor, "slots", None)
    if isinstance(own, int) and own > 0:
        return own
    client = getattr(executor, "_client", None)  # a distributed ClientExecutor
    if client is not None:
        try:
            return max(2, 2 * int(sum(client.nthreads().values())))
        except Exception:
            return 2
    return max(1, int(getattr(executor, "_max_workers", 1) or 1))


def describe(executor: Executor) -> str:
    """A few words on where tasks run (for progress lines and reports)."""
    text = getattr(executor, "description", None)
    if isinstance(text, str):
        return text
    return f"{type(executor).__name__} ({slots(executor)} slot{'s' if slots(executor) != 1 else ''})"
