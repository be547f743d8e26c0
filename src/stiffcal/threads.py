"""One answer per input: the solvers run on one BLAS thread whatever the caller's setting.

A matrix product split over several BLAS threads adds its terms in another order, so its last bits depend on the
thread count; an exchange step or a line search that compares such numbers can then take another branch, and
the plan changes (issue 24: O_t 1.2828e-10 with 2 threads, 1.2963e-10 with 1, for the same input). The matrices
here are small (tens of columns), so threads only cost CPU time anyway. :func:`single_threaded` limits BLAS to
one thread inside the decorated solver (``threadpoolctl``, pinned), once per outermost call, and restores the
caller's setting afterwards; the command line and the workflow's jobs also start with
``OPENBLAS_NUM_THREADS=1``.
"""

from __future__ import annotations

import functools
import threading
from contextlib import contextmanager

_state = threading.local()


@contextmanager
def one_blas_thread():
    """Run the block with BLAS (OpenBLAS, MKL, BLIS) limited to one thread; nested blocks cost nothing."""
    if getattr(_state, "depth", 0):
        _state.depth += 1
        try:
            yield
        finally:
            _state.depth -= 1
        return
    from threadpoolctl import threadpool_limits

    _state.depth = 1
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        _state.depth = 0


def single_threaded(fun):
    """Decorator: ``fun`` runs inside :func:`one_blas_thread`."""
    @functools.wraps(fun)
    def wrapper(*args, **kwargs):
        with one_blas_thread():
            return fun(*args, **kwargs)
    return wrapper
