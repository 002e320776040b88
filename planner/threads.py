"""One BLAS thread per unit of work.

numpy and scipy each load an OpenBLAS that starts a thread per core for
larger products. In a unit of work that buys nothing: a Barrett unit on the
mug took the same wall time with one thread as with two (19.2 s against
19.5 s) but 23% more CPU (24.0 s against 19.5 s), the second thread spinning
while it waits; with two worker processes on two cores the spinning threads
take cores from the other worker. Units and validation tasks therefore run
with BLAS limited to one thread (threadpoolctl, which also reaches the
OpenBLAS scipy loads on first use), restored afterwards for an API caller.
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits


def one_blas_thread() -> threadpool_limits:
    """A context manager: BLAS libraries loaded now use one thread inside it."""
    return threadpool_limits(limits=1, user_api="blas")
