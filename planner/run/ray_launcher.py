"""``python -m planner.run.ray_launcher NUM_CPUS``: own a private local Ray
instance for one driver (:func:`planner.run.ray_local.local_ray`), and take
it down, every process of it, when that driver ends -- however it ends.

The driver holds the write end of our stdin; EOF means it is finished or
dead. We start the instance with ``ray.init`` (so GCS and raylet are our
children, armed by Ray with PR_SET_PDEATHSIG) and, as child subreaper
(Linux), adopt every process of the instance that loses its parent, so at
EOF the whole instance is exactly our process subtree: we SIGKILL it, reap
it and exit. Without us, Ray's dashboard and runtime-env agents outlive a
SIGKILLed driver by about 60 s.

Prints one JSON line on stdout when ready: ``{"address": ..., "pid": ...}``.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time

from planner.run import procs

#: [s] between looks at the subtree while killing it (lets the kills land).
KILL_POLL = 0.01


def kill_subtree() -> None:
    """SIGKILL every process below us until none runs, reaping as we go."""
    me = os.getpid()
    while tree := procs.descendants(me):
        for pid in tree:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        _reap()
        time.sleep(KILL_POLL)
    _reap()


def _reap() -> None:
    try:
        while os.waitpid(-1, os.WNOHANG)[0]:
            pass
    except ChildProcessError:
        pass


def main() -> None:
    num_cpus = int(sys.argv[1])
    procs.adopt_orphans()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the driver decides
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # still take the instance down
    import ray

    try:
        ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
        print(json.dumps({"address": ray.get_runtime_context().gcs_address, "pid": os.getpid()}), flush=True)
        os.dup2(2, 1)  # the driver stops reading our stdout
        sys.stdin.buffer.read()
    finally:
        kill_subtree()
        os._exit(0)  # skip Ray's exit hooks: they would talk to the dead GCS


if __name__ == "__main__":
    main()
