"""The value types the exporters pass around: one batch of grasp rows as
columns, an object's properties, and a stream of batches."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ObjectInfo:
    """The ``objects`` row of an exported object (NaN / "" when missing).

    ``scale`` is the scale applied to ``file``; ``com`` (3,) [m] and
    ``inertia`` (3, 3) [kg m^2] about the COM are in the scaled mesh frame.
    """

    name: str
    file: str
    scale: float
    mass: float
    friction: float
    density: float
    volume: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class Batch:
    """Up to ``source.BATCH_SIZE`` grasps of one (object, hand) as columns.

    Float columns that may be absent hold NaN (``width``, ``reachability``,
    ``manipulability``, validation and robust values); integer ones hold -1
    (``rank``, ``sim_success``, ``sim_fingers``, ``robust_samples``). JSON
    columns stay JSON text. Poses are the hand frame in the object frame.
    """

    grasp_id: np.ndarray  # (n,) int64
    unit_id: np.ndarray  # (n,) int64
    preshape: list[str]
    candidate: np.ndarray  # (n,) int64
    seed: np.ndarray  # (n,) int64
    approach_point: np.ndarray  # (n, 3) [m] object frame
    approach_dir: np.ndarray  # (n, 3) unit, object frame
    roll: np.ndarray  # (n,) [rad]
    standoff: np.ndarray  # (n,) [m]
    pose: np.ndarray  # (n, 4, 4) hand frame in the object frame [m]
    open_joints: list[str]  # JSON {joint: value}
    closed_joints: list[str]  # JSON {joint: value}
    width: np.ndarray  # (n,) [m]
    contacts: list[str]  # JSON [{point, normal, link}]
    n_contacts: np.ndarray  # (n,) int64
    links_touching: np.ndarray  # (n,) int64
    epsilon: np.ndarray  # (n,)
    volume: np.ndarray  # (n,)
    force_closure: np.ndarray  # (n,) int64 0/1
    reachability: np.ndarray  # (n,)
    manipulability: np.ndarray  # (n,)
    score: np.ndarray  # (n,)
    rank: np.ndarray  # (n,) int64
    sim_success: np.ndarray  # (n,) int64 0/1, -1: not validated
    sim_fingers: np.ndarray  # (n,) int64 fingers in contact after shaking
    closing_linear: np.ndarray  # (n,) [m] object motion during closing
    closing_angular: np.ndarray  # (n,) [rad]
    shaking_linear: np.ndarray  # (n,) [m] object motion during shaking
    shaking_angular: np.ndarray  # (n,) [rad]
    robust_mean: np.ndarray  # (n,) robust epsilon, mean over samples
    robust_quantile: np.ndarray  # (n,) robust epsilon, low quantile
    robust_samples: np.ndarray  # (n,) int64

    def __len__(self) -> int:
        return len(self.grasp_id)

    def joints(self, names: Sequence[str], closed: bool = True) -> np.ndarray:
        """(n, J) joint values [rad or m] in the order of ``names``; NaN if absent."""
        rows = json_list(self.closed_joints if closed else self.open_joints)
        return np.array([[r.get(k, math.nan) for k in names] for r in rows], float).reshape(len(self), len(names))


def json_list(texts: Sequence[str]) -> list:
    """Decode many JSON values with one parser call (several times faster)."""
    return json.loads("[" + ",".join(texts) + "]")


@dataclass(frozen=True)
class Stream:
    """The selected grasps of one (object, hand), as batches read on demand."""

    info: ObjectInfo
    hand: str
    batches: Iterator[Batch]
