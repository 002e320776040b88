"""One unit of work end to end: object -> rays -> closing -> contacts -> quality (a parallel jaw's squeeze beside it,
:mod:`planner.plan.squeeze`, and its end where force closure: :mod:`planner.plan.keeping`) -> settled epsilon
(hands with ``settle``) -> reachability, returning :class:`~planner.record.grasp.Grasp` records for the single
database writer.

On a table (``SweepSettings.table_plane``, ``grasp generate --on-table``): the table is closing's obstacle, raised by
:data:`~planner.plan.tolerances.TABLE_CLEARANCE`; approach rays shallower than
:data:`~planner.plan.tolerances.TABLE_ELEVATION` are turned down to it; candidates whose approach comes from under the
table top's level are not tried (:data:`FROM_BELOW`), grasps whose open hand at the pre-grasp would touch the table are
rejected (:data:`PREGRASP_TABLE`), and the reachability placements put the object in that resting pose.

This runs inside worker processes: it reads descriptions and simulates, but never touches the database.
"""

from __future__ import annotations

import logging
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from planner import prepare
from planner.errors import PlannerError
from planner.geometry.frames import approach_of, resting_up
from planner.geometry.solid import PreparedObject, load_object
from planner.plan import grip, sampling
from planner.plan.closing import Closed, Grasper
from planner.plan.contacts import grasp_quality  # noqa: F401 - re-exported (the importer's, the robust epsilon's)
from planner.plan.keeping import QUALITY_FAILED, Keeper, pregrasp, scored  # noqa: F401 - QUALITY_FAILED re-exported
from planner.plan.local_sdf import LocalSurface
from planner.plan.measures import MIN_RESISTANCE, measured_later
from planner.plan.reach import ReachSettings, reach_scene
from planner.plan.settle import with_settled
from planner.plan.sweep import (
    IK_STREAM,
    PLACEMENT_STREAM,
    Candidate,
    SweepSettings,
    antipodal_candidates,
    candidates,
    check_sampler,
    check_unit_size,
    unit_rng,
)
from planner.plan.tolerances import FINGER_CLEARANCE, MIN_CLEARANCE, TABLE_CLEARANCE, TABLE_ELEVATION
from planner.record.first import first_of
from planner.record.grasp import Grasp
from planner.sim import Sim
from planner.specs.hands import HandSpec, load_hand
from planner.specs.physical import NO_PHYSICAL, Physical
from planner.specs.preshapes import Preshape, sweep_preshapes
from planner.threads import one_blas_thread

log = logging.getLogger(__name__)

#: Counted among a unit's ``rejected``: candidates left untried once the unit had its share of the force-closure
#: budget (SweepSettings.budget_share).
BUDGET = "budget"
#: Rejection reasons on a table: the approach comes from under the table top's level; the open hand backed off to
#: the pre-grasp would touch the table.
FROM_BELOW = "from_below"
PREGRASP_TABLE = "pregrasp_table"


@dataclass
class Budget:
    """A unit's force-closure grasps so far against its share (None: no limit)."""

    share: int | None
    force_closure: int = 0

    @property
    def spent(self) -> bool:
        return self.share is not None and self.force_closure >= self.share


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
    physical: Physical = NO_PHYSICAL  # the user's mass or density and friction (None: the object's own)
    manifest: str | None = None  # the @manifest whose line gave the object (see ObjectRef)


@dataclass
class UnitResult:
    spec: UnitSpec
    obj: PreparedObject | None = None
    grasps: list[Grasp] = field(default_factory=list)
    candidates: int = 0
    rejected: Counter = field(default_factory=Counter)
    timing: dict[str, float] = field(default_factory=lambda: dict.fromkeys(
        ("prepare", "sampling", "rejection", "closing", "contacts", "quality", "settle", "reachability"), 0.0))
    error: str | None = None
    notes: list[str] = field(default_factory=list)  # what preparing the object noted, where nothing showed it

    @property
    def object_name(self) -> str:
        """The object's database name."""
        return self.obj.name if self.obj is not None else (self.spec.label or self.spec.object_name)

    @property
    def force_closure(self) -> int:
        return sum(g.force_closure for g in self.grasps)

    @property
    def ends(self) -> int:
        """Of :attr:`force_closure`, the squeezes' ends kept as grasps of their own (:mod:`planner.plan.keeping`)."""
        return sum(g.squeezed_from_turn is not None for g in self.grasps)


#: report(done, total): ``done`` of the unit's ``total`` candidates are finished.
Report = Callable[[int, int], None]


def _silent(done: int, total: int) -> None:
    pass


def run_unit(spec: UnitSpec, report: Report | None = None) -> UnitResult:
    """Run a unit; a failure is recorded in the result, never raised. ``report`` hears of the candidates as they
    finish: (0, total) when the first begins, (total, total) when the last ends or the budget is spent (settle and
    reachability come after); it never changes the result."""
    result = UnitResult(spec)
    try:
        with one_blas_thread(), prepare.kept(result.notes):
            _run(spec, result, report or _silent)
    except PlannerError as exc:
        result.error = str(exc)
    except Exception as exc:  # a simulator or library crash: keep the batch going
        log.debug("unit %s failed:\n%s", spec, traceback.format_exc())
        result.error = f"{type(exc).__name__}: {exc}"
    return result


def plan_object(obj: PreparedObject, hand: str, settings: SweepSettings, seed: int) -> UnitResult:
    """Run one unit on an object already prepared (a stored one, rebuilt), in
    this process, chunk 0 (``settings.chunk`` 0: every ray or point): what
    ``grasp best`` plans on the spot. Errors are raised, not recorded."""
    spec = UnitSpec(obj.name, hand, settings, seed, label=obj.name)
    result = UnitResult(spec)
    try:
        with one_blas_thread():
            _run(spec, result, _silent, obj)
    finally:
        sampling.forget()  # a unit of every point: its pairs (~120 MB at 1,000,000 points) are not asked for again
    return result


def _run(spec: UnitSpec, result: UnitResult, report: Report, obj: PreparedObject | None = None) -> None:
    t0 = time.perf_counter()
    if obj is None:
        obj = load_object(spec.object_name, scale=spec.scale, label=spec.label, **spec.physical.given())
    hand = load_hand(spec.hand)
    settings = spec.settings.resolved(hand.sampler, hand.settle, hand.settle_dynamics)
    shapes = sweep_preshapes(hand, list(settings.preshapes) if settings.preshapes else None,
                             settings.table_plane is not None)
    result.obj = obj
    result.timing["prepare"] += time.perf_counter() - t0
    rng = unit_rng(spec.seed, obj.name, hand.name)
    budget = Budget(settings.budget_share())
    support = settings.support()
    table = None if support is None else support.raised(TABLE_CLEARANCE).frame()
    with Sim() as sim, measured_later(result.grasps, result.timing) as later:  # measures: once the loop ends
        grasper = Grasper.for_object(sim, hand, obj, table=table)
        gripping = grip.GripSurface(obj.mesh, normals_at=grasper.normals_at())  # the exact surface
        local = LocalSurface(hand, obj.mesh if grasper.mesh is None else grasper.mesh)  # a large mesh's proxy
        up = resting_up(settings.table_plane, obj.up)  # the object's up; on a table, the table's (object frame)
        keeper = Keeper(hand, obj, settings, spec.seed, grasper, gripping, local, up, result.grasps, later)
        sweep = _antipodal if settings.sampler == "antipodal" else _rays
        for cand, closed, ray in sweep(spec, settings, obj, hand, shapes, rng, grasper, result, t0, budget,
                                    report):
            tb = time.perf_counter()
            if support is not None and grasper.on_table_at(pregrasp(closed.pose, hand, settings.pregrasp_distance),
                                                           dict(closed.open_joints)):
                result.rejected[PREGRASP_TABLE] += 1
                result.timing["closing"] += time.perf_counter() - tb
                continue
            q = scored(closed.contacts, hand, obj, settings.cone_edges, result.rejected, settings.volume)
            if q is not None:
                budget.force_closure += keeper.keep(cand, closed, ray, q)  # and a squeeze's end where it is kept
            result.timing["quality"] += time.perf_counter() - tb
        # contact reading happens inside closing; report it as its own stage
        result.timing["contacts"] = grasper.contact_seconds
        result.timing["closing"] -= grasper.contact_seconds
    if settings.settle:
        t2 = time.perf_counter()
        result.grasps = with_settled(hand, obj, result.grasps, settings.cone_edges, settings.trial)
        result.timing["settle"] += time.perf_counter() - t2
    if settings.reach_placements and hand.arm is not None:
        t3 = time.perf_counter()
        result.grasps = add_reachability(result.grasps, obj, hand, spec, settings)
        result.timing["reachability"] += time.perf_counter() - t3


#: What a sweep yields per closed candidate: the candidate, the closed hand,
#: and (approach point [m], approach direction, roll [rad], standoff [m]) for the record.
Swept = Iterator[tuple[Candidate, Closed, tuple[np.ndarray, np.ndarray, float, float]]]


def _check_time(spec: UnitSpec, t0: float) -> float:
    now = time.perf_counter()
    if spec.timeout is not None and now - t0 > spec.timeout:
        raise PlannerError(f"time-out: unit not finished after {spec.timeout:g} s")
    return now


def _tried(todo: list[Candidate], budget: Budget, result: UnitResult, report: Report) -> Iterator[Candidate]:
    """The candidates in order, counted in ``result.candidates``, until the budget is spent when a new ray or
    point would begin; the rest are counted as :data:`BUDGET` in ``result.rejected``. ``report`` gets the
    candidates finished before each one, then all of them."""
    previous = None
    for i, cand in enumerate(todo):
        report(i, len(todo))
        if cand.ray != previous and budget.spent:
            result.rejected[BUDGET] += len(todo) - i
            break
        previous = cand.ray
        result.candidates += 1
        yield cand
    report(len(todo), len(todo))


def _rays(spec: UnitSpec, settings: SweepSettings, obj: PreparedObject, hand: HandSpec, shapes: tuple[Preshape, ...],
          rng: np.random.Generator, grasper: Grasper, result: UnitResult, t0: float, budget: Budget,
          report: Report) -> Swept:
    """OpenRAVE-style: approach along each ray until contact, back off, close."""
    t1 = time.perf_counter()
    if settings.sampler == "box":  # its rays known once its mesh is: the unit's candidates bounded before they are made
        check_unit_size(settings, shapes, sampling.box_ray_count(obj.mesh, settings.box_delta))
    rays = sampling.sample(obj.mesh, sampler=settings.sampler or "surface", count=settings.approaches or 0, rng=rng,
                           delta=settings.box_delta, fan_count=settings.fan_count, fan_angle=settings.fan_angle,
                           normals_at=grasper.normals_at())
    keep: range | list[int] = settings.ray_range(spec.chunk, len(rays))
    support = settings.support()
    if support is not None:  # straight down onto the top first (the first unit), then the sampled rays, steepened
        above = sampling.from_above(obj.mesh, support.normal, obj.com, hand.approach)
        steep = sampling.Approaches(rays.points, rays.normals, support.steepened(rays.directions, TABLE_ELEVATION),
                                    rays.phases)
        first = settings.above_rays(spec.chunk)
        keep = [*range(first), *(len(above) + i for i in keep)]
        rays = above.then(steep)
    todo = candidates(rays, shapes, settings, hand.roll_symmetry, keep)
    result.timing["sampling"] += time.perf_counter() - t1
    radius = obj.torque_scale + float(np.linalg.norm(obj.com))
    below = np.zeros(len(rays), bool) if support is None else support.from_below(rays.directions)
    for cand in _tried(todo, budget, result, report):
        if below[cand.ray]:
            result.rejected[FROM_BELOW] += 1
            continue
        ta = _check_time(spec, t0)
        closed = grasper.close(rays.points[cand.ray], rays.directions[cand.ray], cand.roll, cand.standoff,
                               cand.preshape, radius)
        result.timing["closing"] += time.perf_counter() - ta
        if not isinstance(closed, Closed):
            result.rejected[closed.reason] += 1
            continue
        yield cand, closed, (rays.points[cand.ray], rays.directions[cand.ray], cand.roll, cand.standoff)


def _antipodal(spec: UnitSpec, settings: SweepSettings, obj: PreparedObject, hand: HandSpec,
               shapes: tuple[Preshape, ...], rng: np.random.Generator, grasper: Grasper, result: UnitResult,
               t0: float, budget: Budget, report: Report) -> Swept:
    """Parallel jaws: the hand put straight on each antipodal pair, refused before simulation when the pair is
    unusable or the open hand overlaps the object, else closed where it is."""
    t1 = time.perf_counter()
    openings = {s.name: hand.opening(s.joints) for s in shapes}
    pairs = sampling.antipodal_once((obj.name, obj.mesh_hash, hand.name), obj.mesh, settings.approaches or 0, rng,
                                    mu=obj.friction, max_width=max(openings.values()) - 2 * MIN_CLEARANCE,
                                    normals_at=grasper.normals_at())
    todo = antipodal_candidates(pairs, shapes, openings, settings, MIN_CLEARANCE,
                                settings.ray_range(spec.chunk, len(pairs)))
    check_sampler(settings, hand)
    master = hand.jaw[0]
    usable = [c for c in todo if not pairs.reasons[c.ray]]
    rows = np.array([c.ray for c in usable], int)
    poses = sampling.antipodal_poses(hand.approach, grasper.axis_in_root(master.name),
                                     np.array([c.preshape.tcp for c in usable]).reshape(-1, 3), pairs.axes[rows],
                                     pairs.midpoints[rows], np.array([c.roll for c in usable]),
                                     np.array([c.standoff for c in usable]))
    pose_of = {c.index: pose for c, pose in zip(usable, poses)}
    support = settings.support()
    result.timing["sampling"] += time.perf_counter() - t1
    opened: tuple[tuple[int, str], dict[str, float]] | None = None  # a pair's candidates (its rolls, depths) open alike
    for cand in _tried(todo, budget, result, report):
        if pairs.reasons[cand.ray]:
            result.rejected[pairs.reasons[cand.ray]] += 1
            continue
        pose = pose_of[cand.index]
        if support is not None and support.from_below(pose[:3, :3] @ hand.approach)[0]:
            result.rejected[FROM_BELOW] += 1
            continue
        ta = _check_time(spec, t0)
        if opened is None or opened[0] != (cand.ray, cand.preshape.name):
            opened = (cand.ray, cand.preshape.name), fitted_opening(hand, cand.preshape, master.name,
                                                                     pairs.widths[cand.ray] + 2 * FINGER_CLEARANCE)
        fitted = opened[1]
        free = not grasper.overlaps_at(pose, fitted)
        tb = time.perf_counter()
        result.timing["rejection"] += tb - ta
        if not free:
            result.rejected["overlap"] += 1
            continue
        closed = grasper.close_from(pose, cand.preshape, fitted)
        result.timing["closing"] += time.perf_counter() - tb
        if not isinstance(closed, Closed):
            result.rejected[closed.reason] += 1
            continue
        yield cand, closed, (*approach_of(pose, hand.approach, cand.preshape.tcp), 0.0)


def fitted_opening(hand: HandSpec, shape: Preshape, master: str, width: float) -> dict[str, float]:
    """Every finger joint of ``shape`` with the fingers opened to ``width``
    [m] (mimics follow), or to the preshape's own opening if that is less."""
    per_unit = hand.opening(hand.full_configuration({master: 1.0})) - hand.opening(hand.full_configuration(
        {master: 0.0}))
    base = hand.opening(hand.full_configuration({master: 0.0}))
    value = min((width - base) / per_unit, shape.joints[master])
    driven = {j.name: shape.joints[j.name] for j in hand.driven}
    driven[master] = max(value, hand.joint(master).lower)
    return hand.full_configuration(driven)


def add_reachability(grasps: list[Grasp], obj: PreparedObject, hand: HandSpec, spec: UnitSpec,
                     settings: SweepSettings) -> list[Grasp]:
    """Reachability over the unit's sampled placements of its ``reach_top``
    grasps (all if 0) that are force closure (as planned, or once a parallel
    jaw's squeeze ends: the grasps that rank first) or hold their object's
    weight, highest epsilon first (a squeeze's where only it is force closure:
    until 2026-12-07 its planned 0 left such a grasp unreached, neutral, above
    its reached end), then highest weight resistance; the others keep ``None``
    (not computed). The scene is built once per worker process."""
    first = {_key(g) for g, f in zip(grasps, first_of(grasps)) if f}
    ranked = sorted((g for g in grasps if _key(g) in first or _holds_weight(g)),
                    key=lambda g: (-_first_epsilon(g, _key(g) in first),
                                   -(g.measures.resist_worst if g.measures else 0.0), _key(g)))
    chosen = {_key(g) for g in (ranked[:settings.reach_top] if settings.reach_top else ranked)}
    if not chosen:
        return grasps
    scene = reach_scene(hand, obj, ReachSettings(placements=settings.reach_placements,
                                                 pregrasp_distance=settings.pregrasp_distance))
    placements = scene.placements(unit_rng(spec.seed, obj.name, hand.name, PLACEMENT_STREAM), settings.support())
    out = []
    for g in grasps:
        if _key(g) not in chosen:
            out.append(g)
            continue
        rng = unit_rng(spec.seed, obj.name, hand.name, IK_STREAM, *_key(g)[:1 + (g.squeezed_from_turn is not None)])
        reached, manip = 0, 0.0
        for pose in placements:
            scene.place_object(pose)
            r = scene.check(g.pose, g.closed_joints, g.open_joints, rng)
            if r.reachable:
                reached += 1
                manip = max(manip, r.grasp.manipulability)  # type: ignore[union-attr]
        out.append(replace(g, reachability=reached / len(placements), manipulability=manip))
    return out


def _first_epsilon(g: Grasp, first: bool) -> float:
    """The epsilon that ranks ``g`` first: the squeeze's where it ranks first (:func:`planner.record.first.first_of`;
    a kept end stands for its parent and gets the reach: until ALGORITHM_VERSION 27 the parent took a reach slot
    too) but is not force closure as planned, else the planned one."""
    return float(g.measures.squeezed_epsilon) if first and not g.force_closure else g.epsilon  # type: ignore[union-attr]


def _holds_weight(g: Grasp) -> bool:
    return g.measures is not None and g.measures.resist_worst >= MIN_RESISTANCE


def _key(g: Grasp) -> tuple[int, int]:
    """What tells a unit's grasps apart: the candidate, and 1 for a squeeze's end (kept beside its parent, 0)."""
    return g.candidate, int(g.squeezed_from_turn is not None)
