"""The sweep: settings, seeds, and the enumeration of candidate grasps.

A *unit of work* is (object, hand, sweep settings, seed). Its random stream
is derived from the user's seed and the object and hand names -- never from
the worker that runs it -- so any unit gives the same grasps wherever and
whenever it runs. Candidate ``i`` of a unit is fully determined by the unit,
so every stored grasp can be replayed.
"""

from __future__ import annotations

import hashlib
import json
import zlib
from dataclasses import asdict, dataclass
from itertools import product

import numpy as np

from planner.errors import InputError
from planner.preshapes import Preshape
from planner.sampling import SAMPLERS, Approaches

#: Bumped whenever a change alters which grasps a sweep produces, so stale
#: units are recomputed rather than mixed with new ones.
ALGORITHM_VERSION = 1


@dataclass(frozen=True)
class SweepSettings:
    """What to try. Angles in radians, lengths in metres."""

    approaches: int = 48  # surface sampler: rays per object
    sampler: str = "surface"  # "surface" or "box"
    box_delta: float = 0.02  # box sampler: grid spacing [m]
    fan_count: int = 0  # extra tilted directions per ray
    fan_angle: float = 0.3  # their tilt [rad]
    rolls: int = 4  # rolls about the approach axis, evenly spaced in [0, 2 pi / hand symmetry)
    standoffs: tuple[float, ...] | None = None  # None: each preshape's own
    preshapes: tuple[str, ...] | None = None  # None: all of the hand's
    cone_edges: int = 8  # friction cone edges m

    def __post_init__(self) -> None:
        if self.sampler not in SAMPLERS:
            raise InputError(f"unknown sampler '{self.sampler}'; use {', '.join(SAMPLERS)}")
        if self.approaches < 1 or self.rolls < 1 or self.cone_edges < 3 or self.fan_count < 0:
            raise InputError("approaches and rolls must be >= 1, cone edges >= 3, fan count >= 0")
        if self.standoffs is not None and (not self.standoffs or min(self.standoffs) < 0):
            raise InputError("standoffs must be non-negative distances in metres")

    def to_json(self) -> str:
        data = asdict(self)
        data["algorithm"] = ALGORITHM_VERSION
        return json.dumps(data, sort_keys=True)

    @property
    def digest(self) -> str:
        return hashlib.sha256(self.to_json().encode()).hexdigest()[:16]

    def roll_angles(self, symmetry: int = 1) -> np.ndarray:
        """Rolls [rad]; a hand symmetric under a half turn needs only [0, pi)."""
        return 2 * np.pi * np.arange(self.rolls) / (self.rolls * symmetry)


def unit_rng(seed: int, object_name: str, hand_name: str) -> np.random.Generator:
    """The unit's generator: a function of (seed, object, hand) only."""
    return np.random.default_rng([seed, zlib.crc32(object_name.encode()), zlib.crc32(hand_name.encode())])


@dataclass(frozen=True)
class Candidate:
    """One grasp to try: approach ray ``ray`` of the unit's rays, etc."""

    index: int
    ray: int
    preshape: Preshape
    roll: float
    standoff: float


def candidates(approaches: Approaches, shapes: tuple[Preshape, ...], settings: SweepSettings,
               symmetry: int = 1) -> list[Candidate]:
    """Every (ray, preshape, roll, standoff), in a fixed order."""
    out = []
    for ray, shape, roll in product(range(len(approaches)), shapes, settings.roll_angles(symmetry)):
        for standoff in settings.standoffs or shape.standoffs:
            out.append(Candidate(len(out), ray, shape, float(roll), float(standoff)))
    return out
