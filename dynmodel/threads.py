"""BLAS threads during fits: one, so that results do not depend on the machine's core count.

OpenBLAS splits some operations (X^T X, triangular solves) across its threads and sums the pieces in
another order, so the same fit gives results that differ in the last bits between 1 and 2 threads
(measured on a ridge readout). Fits therefore run with one BLAS thread, in ``dynmodel fit``, in
every sweep worker and in-process alike; parallelism comes from running several fits at once
(``dynmodel sweep``). ``DYNMODEL_BLAS_THREADS=N`` allows N threads (faster single large fits, at the
price of bit-identity with runs that use another thread count).

The limit is reference-counted across threads: the first fit to start sets it, the last to finish
restores the previous setting (threadpoolctl changes a process-wide setting).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_lock = threading.Lock()
_depth = 0
_limiter = None


def blas_threads() -> int:
    """BLAS threads used during fits (``DYNMODEL_BLAS_THREADS``, default 1)."""
    try:
        return max(1, int(os.environ.get("DYNMODEL_BLAS_THREADS", "1")))
    except ValueError:
        return 1


@contextmanager
def fit_threads() -> Iterator[None]:
    """Run the body with :func:`blas_threads` BLAS threads (every BLAS library numpy and scipy load)."""
    global _depth, _limiter
    with _lock:
        if _depth == 0:
            import numpy  # noqa: F401  load every BLAS before limiting: a library loaded later
            import scipy.linalg  # noqa: F401  would keep its default thread count
            from threadpoolctl import threadpool_limits

            _limiter = threadpool_limits(limits=blas_threads(), user_api="blas")
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _limiter is not None:
                _limiter.restore_original_limits()
                _limiter = None
