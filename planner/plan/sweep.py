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
from planner.plan.sampling import SAMPLERS, Approaches
from planner.plan.tolerances import PREGRASP_DISTANCE
from planner.specs.preshapes import Preshape

#: Bumped whenever a change alters which grasps a sweep produces, so stale
#: units are recomputed rather than mixed with new ones.
ALGORITHM_VERSION = 2


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
    chunk: int = 32  # rays per unit of work (surface sampler); 0: one unit per object
    reach_placements: int = 6  # object placements for the reachability score; 0: skip reachability
    pregrasp_distance: float = PREGRASP_DISTANCE  # [m] pre-grasp back-off along the approach
    volume: bool = True  # GWS volume of force-closure grasps (a full 6-D hull; False stores 0)

    def __post_init__(self) -> None:
        if self.sampler not in SAMPLERS:
            raise InputError(f"unknown sampler '{self.sampler}'; use {', '.join(SAMPLERS)}")
        if self.approaches < 1 or self.rolls < 1 or self.cone_edges < 3 or self.fan_count < 0:
            raise InputError("approaches and rolls must be >= 1, cone edges >= 3, fan count >= 0")
        if self.chunk < 0 or self.reach_placements < 0 or self.pregrasp_distance < 0:
            raise InputError("chunk, reach placements and pre-grasp distance must be >= 0")
        if self.standoffs is not None and (not self.standoffs or min(self.standoffs) < 0):
            raise InputError("standoffs must be non-negative distances in metres")

    def to_json(self) -> str:
        data = asdict(self)
        data["algorithm"] = ALGORITHM_VERSION
        return json.dumps(data, sort_keys=True)

    @property
    def digest(self) -> str:
        return hashlib.sha256(self.to_json().encode()).hexdigest()[:16]

    @property
    def rays_known(self) -> int | None:
        """Rays per object when known before sampling (surface sampler)."""
        return self.approaches * (1 + self.fan_count) if self.sampler == "surface" else None

    def chunks(self) -> int:
        """Units of work per object."""
        rays = self.rays_known
        if rays is None or self.chunk == 0:
            return 1
        return -(-rays // self.chunk)

    def ray_range(self, chunk: int, total: int) -> range:
        if self.chunks() == 1:
            return range(total)
        return range(chunk * self.chunk, min(total, (chunk + 1) * self.chunk))

    def roll_angles(self, symmetry: int = 1) -> np.ndarray:
        """Rolls [rad]; a hand symmetric under a half turn needs only [0, pi)."""
        return 2 * np.pi * np.arange(self.rolls) / (self.rolls * symmetry)


def unit_rng(seed: int, object_name: str, hand_name: str, *stream: int) -> np.random.Generator:
    """The unit's generator: a function of (seed, object, hand) only; ``stream``
    numbers give independent sub-streams (placements, one per candidate...)."""
    return np.random.default_rng([seed, zlib.crc32(object_name.encode()), zlib.crc32(hand_name.encode()), *stream])


#: Sub-stream numbers of :func:`unit_rng`.
PLACEMENT_STREAM = 1
IK_STREAM = 2


@dataclass(frozen=True)
class Candidate:
    """One grasp to try: approach ray ``ray`` of the unit's rays, etc."""

    index: int
    ray: int
    preshape: Preshape
    roll: float
    standoff: float


def candidates(approaches: Approaches, shapes: tuple[Preshape, ...], settings: SweepSettings,
               symmetry: int = 1, rays: range | None = None) -> list[Candidate]:
    """Every (ray, preshape, roll, standoff) in a fixed order, numbered over the
    whole object; ``rays`` keeps only those of one chunk."""
    out, index = [], 0
    keep = range(len(approaches)) if rays is None else rays
    for ray, shape, roll in product(range(len(approaches)), shapes, settings.roll_angles(symmetry)):
        for standoff in settings.standoffs or shape.standoffs:
            if ray in keep:
                out.append(Candidate(index, ray, shape, float(roll), float(standoff)))
            index += 1
    return out
