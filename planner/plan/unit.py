"""One unit of work end to end: object -> rays -> closing -> contacts ->
quality -> reachability, returning :class:`~planner.grasp.Grasp` records for
the single database writer.

This runs inside worker processes: it reads descriptions and simulates, but
never touches the database.
"""

from __future__ import annotations

import logging
import time
import traceback
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from planner import quality
from planner.errors import PlannerError
from planner.geometry.solid import PreparedObject, load_object
from planner.grasp import Grasp
from planner.plan import sampling
from planner.plan.closing import Closed, Grasper
from planner.plan.contacts import HandContacts, contact_models
from planner.plan.measures import MIN_RESISTANCE, measure
from planner.plan.reach import ReachScene, ReachSettings
from planner.plan.sweep import IK_STREAM, PLACEMENT_STREAM, SweepSettings, candidates, unit_rng
from planner.sim import Sim
from planner.specs.hands import HandSpec, load_hand
from planner.specs.preshapes import load_preshapes

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class UnitSpec:
    """What a worker needs to run one unit (plain, picklable by value)."""

    object_name: str
    hand: str
    settings: SweepSettings
    seed: int
    scale: float | None = None
    chunk: int = 0  # which slice of the object's rays (see SweepSettings.chunk)
    label: str | None = None  # database name of the object (None: its default name)
    timeout: float | None = None  # [s] give up on the unit after this long (checked between candidates)


@dataclass
class UnitResult:
    spec: UnitSpec
    obj: PreparedObject | None = None
    grasps: list[Grasp] = field(default_factory=list)
    candidates: int = 0
    rejected: Counter = field(default_factory=Counter)
    timing: dict[str, float] = field(default_factory=lambda: dict.fromkeys(
        ("prepare", "sampling", "closing", "contacts", "quality", "reachability"), 0.0))
    error: str | None = None

    @property
    def object_name(self) -> str:
        """The object's database name."""
        return self.obj.name if self.obj is not None else (self.spec.label or self.spec.object_name)

    @property
    def force_closure(self) -> int:
        return sum(g.force_closure for g in self.grasps)


def run_unit(spec: UnitSpec) -> UnitResult:
    """Run a unit; a failure is recorded in the result, never raised."""
    result = UnitResult(spec)
    try:
        _run(spec, result)
    except PlannerError as exc:
        result.error = str(exc)
    except Exception as exc:  # a simulator or library crash: keep the batch going
        log.debug("unit %s failed:\n%s", spec, traceback.format_exc())
        result.error = f"{type(exc).__name__}: {exc}"
    return result


def _run(spec: UnitSpec, result: UnitResult) -> None:
    t0 = time.perf_counter()
    obj = load_object(spec.object_name, scale=spec.scale, label=spec.label)
    hand = load_hand(spec.hand)
    shapes = load_preshapes(hand, list(spec.settings.preshapes) if spec.settings.preshapes else None)
    result.obj = obj
    t1 = time.perf_counter()
    result.timing["prepare"] += t1 - t0
    rng = unit_rng(spec.seed, obj.name, hand.name)
    rays = sampling.sample(obj.mesh, sampler=spec.settings.sampler, count=spec.settings.approaches, rng=rng,
                           delta=spec.settings.box_delta, fan_count=spec.settings.fan_count,
                           fan_angle=spec.settings.fan_angle)
    todo = candidates(rays, shapes, spec.settings, hand.roll_symmetry, spec.settings.ray_range(spec.chunk, len(rays)))
    result.candidates = len(todo)
    t2 = time.perf_counter()
    result.timing["sampling"] += t2 - t1
    radius = obj.torque_scale + float(np.linalg.norm(obj.com))
    with Sim() as sim:
        grasper = Grasper.for_mesh(sim, hand, obj.mesh)
        for cand in todo:
            ta = time.perf_counter()
            if spec.timeout is not None and ta - t0 > spec.timeout:
                raise PlannerError(f"time-out: unit not finished after {spec.timeout:g} s")
            closed = grasper.close(rays.points[cand.ray], rays.directions[cand.ray], cand.roll, cand.standoff,
                                   cand.preshape, radius)
            tb = time.perf_counter()
            result.timing["closing"] += tb - ta
            if not isinstance(closed, Closed):
                result.rejected[closed.reason] += 1
                continue
            q = grasp_quality(closed.contacts, hand, obj, spec.settings.cone_edges, spec.settings.volume)
            width = closed_width(hand, closed.closed_joints)
            m = measure(closed.contacts, closed.frames, hand, cand.preshape, closed.closed_joints, obj, width)  # type: ignore[arg-type]
            result.timing["quality"] += time.perf_counter() - tb
            result.grasps.append(Grasp(
                object=obj.name, hand=hand.name, preshape=cand.preshape.name, candidate=cand.index, seed=spec.seed,
                approach_point=rays.points[cand.ray], approach_dir=rays.directions[cand.ray], roll=cand.roll,
                standoff=cand.standoff, pose=closed.pose, open_joints=closed.open_joints,
                closed_joints=closed.closed_joints, width=width, contacts=closed.contacts, epsilon=q.epsilon,
                volume=q.volume, force_closure=q.force_closure, measures=m))
        # contact reading happens inside closing; report it as its own stage
        result.timing["contacts"] = grasper.contact_seconds
        result.timing["closing"] -= grasper.contact_seconds
    if spec.settings.reach_placements and hand.arm is not None:
        t3 = time.perf_counter()
        result.grasps = add_reachability(result.grasps, obj, hand, spec)
        result.timing["reachability"] += time.perf_counter() - t3


def add_reachability(grasps: list[Grasp], obj: PreparedObject, hand: HandSpec, spec: UnitSpec) -> list[Grasp]:
    """Reachability over the unit's sampled placements of each grasp that is
    force closure or holds its object's weight."""
    settings = ReachSettings(placements=spec.settings.reach_placements,
                             pregrasp_distance=spec.settings.pregrasp_distance)
    out = []
    with Sim() as sim:
        scene = ReachScene(sim, hand, obj, settings)
        placements = scene.placements(unit_rng(spec.seed, obj.name, hand.name, PLACEMENT_STREAM))
        for g in grasps:
            if not (g.force_closure or (g.measures is not None and g.measures.resist_worst >= MIN_RESISTANCE)):
                out.append(g)
                continue
            rng = unit_rng(spec.seed, obj.name, hand.name, IK_STREAM, g.candidate)
            reached, manip = 0, 0.0
            for pose in placements:
                scene.place_object(pose)
                r = scene.check(g.pose, g.closed_joints, g.open_joints, rng)
                if r.reachable:
                    reached += 1
                    manip = max(manip, r.grasp.manipulability)  # type: ignore[union-attr]
            out.append(replace(g, reachability=reached / len(placements), manipulability=manip))
    return out


def grasp_quality(contacts: HandContacts, hand: HandSpec, obj: PreparedObject, cone_edges: int,
                  volume: bool = True) -> quality.Quality:
    """Ferrari-Canny epsilon (L1), GWS volume (0 unless ``volume``) and force
    closure of contacts; each contact's model (point, soft, frictionless) as
    :func:`contact_models` says."""
    models, torsion = contact_models(contacts, hand, obj.friction)
    args = dict(mu=obj.friction, center=obj.com, torque_scale=obj.torque_scale, cone_edges=cone_edges, model=models,
                torsion=torsion)
    if volume:
        return quality.evaluate(contacts.points, contacts.frames, **args)  # type: ignore[arg-type]
    eps = quality.epsilon(contacts.points, contacts.frames, **args)  # type: ignore[arg-type]
    return quality.Quality(eps, 0.0, eps > 0.0)


def closed_width(hand: HandSpec, closed_joints: Mapping[str, float]) -> float | None:
    """[m] distance between the fingers of a self-centring parallel jaw, else None."""
    if not hand.centering:
        return None
    return float(sum(closed_joints[j.name] for j in hand.joints if j.kind == "prismatic"))
