"""What every backend of :func:`planner.run.pool.execute` hands back for a
unit without a result, and how often a unit is tried: the contract the local
pool and Ray (:mod:`planner.run.ray_local`) share."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

#: A unit is tried this many times when it kills its worker.
MAX_CRASHES = 2


@dataclass(frozen=True)
class Failure:
    """Why a unit has no result."""

    kind: Literal["error", "crash", "timeout"]
    message: str
    attempts: int  # how many times the unit was started

    def __str__(self) -> str:
        return self.message
