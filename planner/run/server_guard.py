"""Imported first by the pool's fork server, and only there (see
:func:`planner.run.pool._context`): ties the server's life to the driver.

The fork server is the parent of every worker, so the workers' own
``PR_SET_PDEATHSIG`` fires when the *server* dies, not the driver; and the
server by itself outlives a killed driver until its last worker is gone.
Armed here (Linux), the kernel SIGKILLs the server when the driver's thread
that started it ends, and then every worker -- no watcher thread needs the
GIL, so a worker stuck in a long simulator call goes at once too. The pool
starts the server this way only from the driver's main thread, which ends
only with the driver.
"""

from planner.run import procs

procs.die_with_parent()
