"""The run machinery of ``generate``, ``validate`` and ``import``: the
crash-safe worker pool (:mod:`planner.run.pool`), its worker processes
(:mod:`planner.run.worker`), the Ray backend and its launcher
(:mod:`planner.run.ray_local`, :mod:`planner.run.ray_launcher`), and the
Linux process facts and switches they rest on (:mod:`planner.run.procs`,
:mod:`planner.run.server_guard`). It imports nothing of the pipeline's
stages: units and the functions that run them come from the callers."""
