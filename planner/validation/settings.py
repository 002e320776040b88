"""The settings of the shake trial (:mod:`planner.validation.shake`), apart
from the trial itself: the sweep's settings carry them (the settle of hands
with ``settle``), and planning must not load the simulator to read them."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

from planner.errors import ConfigError
from planner.record.tolerances import MIN_OPEN_MARGIN
from planner.specs.hand_spec import SettleDynamics

#: Trials one PyBullet world can hold apart: its collision filter bits
#: (``planner.sim.dynamics.FILTER_BITS``; a test checks they agree).
MAX_BATCH = 30


@dataclass(frozen=True)
class ShakeSettings:
    """Everything that decides a trial (stored with each result). Times in
    seconds, lengths in metres, angles in radians.

    ``dt`` and ``solver_iterations``: 1/480 s and 50 agree with a fine
    reference (1/960 s, 100 iterations, longer phases) on 96% (Panda) and 92%
    (Barrett) of sampled planner grasps; 1/240 s on 90% / 87%: coarser steps
    make contacts creep and drop grasps. ``batch``: trials per PyBullet world.
    """

    dt: float = 1.0 / 480.0
    solver_iterations: int = 50
    start_gap: float = 0.005  # fingers start this far (at the contact) short of the planned grasp
    close_time: float = 0.2  # Panda: 5 mm + 2 mm of collision margins at 0.05 m/s = 0.14 s
    settle_time: float = 0.1  # the object comes to rest before it is loaded
    load: float = 1.0  # [g] the load, in units of the object's weight
    ramp_time: float = 0.03  # from one load direction to the next
    hold_time: float = 0.1  # per direction: a slip at >= 0.15 g net moves the object > 1 cm
    max_translation: float = 0.01  # of the centre of mass relative to the hand
    max_rotation: float = 0.25
    min_clearance: float = MIN_OPEN_MARGIN  # open travel left at a touching finger's contact
    max_start_overlap: float = 0.005  # true depth of the open hand in the object's collision shape
    part_tolerance: float = 0.0005  # convex parts simplified to within this of their hulls
    gear_erp: float = 0.8  # mimic gear constraints (0.2 lets the Barrett's distal links lag)
    batch: int = 1  # trials per world (<= 30), stepped together

    def __post_init__(self) -> None:
        if not 1 <= self.batch <= MAX_BATCH:
            raise ConfigError(f"batch must be 1..{MAX_BATCH} trials per world, got {self.batch}")

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)


def settle_settings(dynamics: SettleDynamics | None) -> ShakeSettings:
    """The settle's trial (one grasp per world) for a hand with ``dynamics``
    (``[settle_dynamics]`` of hand.toml; None: the shake trial's steps and times)."""
    if dynamics is None:
        return ShakeSettings(batch=1)
    return ShakeSettings(dt=1.0 / dynamics.steps_per_second, close_time=dynamics.close_time,
                         settle_time=dynamics.rest_time, batch=1)
