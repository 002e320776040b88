"""One BLAS thread per unit of work.

numpy and scipy each load an OpenBLAS that starts a thread per core for
larger products. In a unit of work that buys nothing: a Barrett unit on the
mug took the same wall time with one thread as with two (19.2 s against
19.5 s) but 23% more CPU (24.0 s against 19.5 s), the second thread spinning
while it waits; with two worker processes on two cores the spinning threads
take cores from the other worker. Units and validation tasks therefore run
with BLAS limited to one thread (threadpoolctl, which also reaches the
OpenBLAS scipy loads on first use), restored afterwards for an API caller.

Finding the loaded libraries (threadpoolctl reads ``/proc/self/maps``) cost
~2-3 ms a call, once per ``grasp validate`` task of 32 trials (~0.08 ms a
trial): the libraries found are kept and looked for again only once a module
has been imported since (a BLAS library comes with the extension module that
loads it).
"""

from __future__ import annotations

import sys
from contextlib import AbstractContextManager

from threadpoolctl import ThreadpoolController

#: (modules imported when it was made, the controller of the libraries then loaded)
_FOUND: list[tuple[int, ThreadpoolController]] = []


def one_blas_thread() -> AbstractContextManager:
    """A context manager: BLAS libraries loaded now use one thread inside it."""
    return loaded_libraries().limit(limits=1, user_api="blas")


def loaded_libraries() -> ThreadpoolController:
    """threadpoolctl's controller of the libraries loaded now: the kept one unless a module was imported
    since it was made."""
    if not _FOUND or _FOUND[-1][0] != len(sys.modules):
        controller = ThreadpoolController()
        _FOUND[:] = [(len(sys.modules), controller)]
    return _FOUND[-1][1]
