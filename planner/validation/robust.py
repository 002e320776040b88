"""Robust epsilon (Dex-Net style): epsilon averaged over noisy copies of a
grasp, each re-closed in the simulator.

Each sample perturbs the grasp pose (translation ~ N(0, sigma_t) per axis,
rotation ~ N(0, sigma_r) axis-angle, in the hand frame), the object pose
(the same, about the object's centre of mass; moving the object by T is
moving the hand by T^-1) and the friction coefficient (mu (1 + N(0,
sigma_mu)), at least 0.05). The hand is placed at the noisy pose with its
preshape open and closed again (``Grasper.close_at``); a sample whose hand
cannot close on the object scores 0.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace

import numpy as np

from planner.geometry.frames import rotation_from_rotvec
from planner.geometry.solid import PreparedObject
from planner.plan.closing import Closed, Grasper
from planner.plan.unit import grasp_quality
from planner.record.grasp import Grasp, RobustEpsilon
from planner.sim import Sim
from planner.specs.hands import HandSpec
from planner.specs.preshapes import load_preshapes
from planner.validation.tolerances import MIN_FRICTION


@dataclass(frozen=True)
class NoiseSettings:
    samples: int = 10
    grasp_translation: float = 0.005  # [m] std per axis
    grasp_rotation: float = 0.05  # [rad] std of the axis-angle components
    object_translation: float = 0.005  # [m]
    object_rotation: float = 0.05  # [rad]
    friction: float = 0.1  # relative std of mu
    quantile: float = 0.1  # the "low quantile" reported with the mean
    cone_edges: int = 8

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)


def _jitter(rng: np.random.Generator, translation: float, rotation: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rotation_from_rotvec(rng.normal(0.0, rotation, 3))
    t[:3, 3] = rng.normal(0.0, translation, 3)
    return t


def robust_epsilon(hand: HandSpec, obj: PreparedObject, grasp: Grasp, rng: np.random.Generator,
                   settings: NoiseSettings | None = None, grasper: Grasper | None = None) -> RobustEpsilon:
    """Mean and low quantile of :func:`epsilon_samples`."""
    s = settings or NoiseSettings()
    return summarise(epsilon_samples(hand, obj, grasp, rng, s, grasper), s.quantile)


def summarise(values: np.ndarray, quantile: float) -> RobustEpsilon:
    """The mean and the ``quantile`` of (N,) epsilon samples."""
    return RobustEpsilon(float(values.mean()), float(np.quantile(values, quantile)), len(values))


def epsilon_samples(hand: HandSpec, obj: PreparedObject, grasp: Grasp, rng: np.random.Generator,
                    settings: NoiseSettings | None = None, grasper: Grasper | None = None) -> np.ndarray:
    """(N,) epsilon of N noisy copies of ``grasp``, each re-closed (0 where the
    hand does not close on the object) by ``grasper`` (:meth:`Grasper.for_object` of ``hand`` and ``obj``; one
    of its own when None: building it, on a mesh of over 5,000 faces its proxy's world, normals and distance
    trees, ~0.1 s, is for the caller to share over an object's grasps)."""
    if grasper is None:
        with Sim() as sim:
            return epsilon_samples(hand, obj, grasp, rng, settings, Grasper.for_object(sim, hand, obj))
    s = settings or NoiseSettings()
    shape = next(p for p in load_preshapes(hand) if p.name == grasp.preshape)
    pose = np.array(grasp.pose, float)
    about_com = np.eye(4)
    about_com[:3, 3] = obj.com
    values = np.zeros(s.samples)
    for k in range(s.samples):
        hand_noise = _jitter(rng, s.grasp_translation, s.grasp_rotation)
        obj_noise = about_com @ _jitter(rng, s.object_translation, s.object_rotation) @ np.linalg.inv(about_com)
        noisy = np.linalg.inv(obj_noise) @ pose @ hand_noise
        mu = max(MIN_FRICTION, obj.friction * (1.0 + rng.normal(0.0, s.friction)))
        closed = grasper.close_at(noisy, shape)
        if isinstance(closed, Closed):
            noisy_obj = replace(obj, spec=replace(obj.spec, friction=mu))
            values[k] = grasp_quality(closed.contacts, hand, noisy_obj, s.cone_edges).epsilon
    return values
