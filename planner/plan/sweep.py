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
import math
import zlib
from collections.abc import Collection, Sequence
from dataclasses import asdict, dataclass, replace
from itertools import product
from typing import TYPE_CHECKING

import numpy as np

from planner.errors import InputError
from planner.geometry.support import Support
from planner.plan.tolerances import ABOVE_RAYS, PREGRASP_DISTANCE
from planner.specs.hand_spec import SettleDynamics
from planner.specs.hands import SAMPLERS
from planner.specs.preshapes import Preshape
from planner.validation.settings import ShakeSettings, settle_settings

if TYPE_CHECKING:  # sampling imports trimesh: `grasp --help` reads these settings without it
    from planner.plan.sampling import Approaches, Pairs
    from planner.specs.hand_spec import HandSpec

#: Bumped whenever a change alters which grasps a sweep produces, so stale
#: units are recomputed rather than mixed with new ones.
#: 2-5 (issues 15, 16): soft contacts, antipodal sampler, patches, breakaway; open-limit flag; settled epsilon;
#: BLAS-independent settles. 6-10 (issue 26): force closure ranks first; cone rays, 127 hulls; only FC settles,
#: proxies over 5,000 faces; eps/settled weights; grip measures for p_hold. 11-13: exact-closest-point patches;
#: settle as stored; a hand's settle dynamics. 14-16: torque_per_mu, local_sdf (sided by winding number). 17: finger
#: axes read at the origin; union mass. 18: edge normals from the object's cone; mesh tables and hand primitives.
#: 19: the settle's every convex part. 20-21: the PR2's and Allegro's dynamics. 22: 0.5 mm proxies, normals averaged
#: over 2 mm; pre-grasp IK branch. 23: the ray samplers and grip measures too. 24: a parallel jaw's squeeze measured
#: beside the planned grasp (planner.plan.squeeze). 25: where it ends force closure, its end a grasp of its own;
#: such a grasp reached by its squeeze's epsilon. 26: that end is its squeeze's last closing, not closed again.
#: 27: a parent whose end is kept takes no reach slot (the end ranks for it: planner.db.ranking). 28: a squeeze
#: that turns back bisects its last turn (planner.plan.squeeze.bracketed). 29: at a bracket's middle, a turn about
#: another axis is a turn, not a half of the bracket. 30: a finger's speed bound from the hand alone (its links'
#: own boxes), not from the first pose a grasper closed: closings no longer depend on the order of work.
ALGORITHM_VERSION = 30

#: Named in the digest of sweeps on a table only (those of the object alone stay
#: as they were), bumped when a change alters only which grasps they produce.
#: 2: the hands' table preshapes (``table = true``) join the sweep on a table (issue 25).
#: 3: the Allegro's ``table_spread``, and a preshape's ``roll_symmetry`` spreading its rolls (issue 25).
#: 4: ray samplers also come straight down onto the object's top (planner.plan.sampling.from_above) (issue 25).
#: 5: com_height and gravity_arm about the table's up (the object rests there in another pose), and so p_hold
#: (issue 26); the same grasps. 6: the squeeze's turns do not take the object through the table (the object turns,
#: not the hand: planner.plan.squeeze.through_table); the same grasps, other squeeze measures and ranks.
TABLE_VERSION = 6

#: Decimals kept of a table plane in the settings (1e-7: 0.1 um, 1e-7 rad).
PLANE_DIGITS = 7

#: What the settings left unset mean, per sampler: surface points (or rays)
#: per object, rolls (antipodal: approach directions about the closing
#: axis) and points (or rays) per unit of work.
SAMPLER_DEFAULTS = {
    "surface": {"approaches": 48, "rolls": 4, "chunk": 32},
    "box": {"approaches": 48, "rolls": 4, "chunk": 32},
    "antipodal": {"approaches": 2048, "rolls": 8, "chunk": 256},
}


AT_LEAST = (("approaches", "--approaches", 1), ("rolls", "--rolls", 1), ("cone_edges", "cone_edges", 3),  # counts,
            ("fan_count", "--fan", 0), ("chunk", "--chunk", 0), ("reach_placements", "--reach-placements", 0),
            ("reach_top", "--reach-top", 0), ("fc_budget", "--fc-budget", 0))  # the option of each, its least
#: Rays (or antipodal points) per object, fan included: every unit of work samples the object's whole set and holds
#: it (points, normals, directions, the cone's tries: ~0.3 kB a ray); 10**9 ran out of memory.
MAX_RAYS = 1_000_000
#: Table placements of the reachability score: it is the fraction of them an arm reaches (1,000 resolve it to 0.1%),
#: each two IK solves per grasp checked; 10**9 ran out of memory.
MAX_REACH_PLACEMENTS = 1_000
#: Candidates of one unit of work: a worker lists them all (an antipodal one with their poses) in memory, measured
#: 0.21 kB a candidate and 0.33 kB a pose: 1,000,000 is ~0.5 GB per worker (--rolls 10**9 ran out of memory).
MAX_UNIT_CANDIDATES = 1_000_000


@dataclass(frozen=True)
class SweepSettings:
    """What to try. Angles in radians, lengths in metres. ``None``: the
    hand's sampler (its ``hand.toml``) and that sampler's defaults
    (:data:`SAMPLER_DEFAULTS`), filled in by :meth:`resolved`."""

    approaches: int | None = None  # rays (surface) or surface points (antipodal) per object
    sampler: str | None = None  # "surface", "box" or "antipodal"
    box_delta: float = 0.02  # box sampler: grid spacing [m]
    fan_count: int = 0  # ray samplers: extra tilted directions per ray
    fan_angle: float = 0.3  # their tilt [rad]
    rolls: int | None = None  # rays: rolls about the approach, evenly spaced in [0, 2 pi / hand symmetry);
    #                           antipodal: approach directions about the closing axis, evenly spaced in [0, 2 pi)
    standoffs: tuple[float, ...] | None = None  # ray samplers; None: each preshape's own
    depths: tuple[float, ...] = (0.0, 0.01)  # antipodal: the tool centre point this far past the chord's middle
    preshapes: tuple[str, ...] | None = None  # None: all of the hand's
    cone_edges: int = 8  # friction cone edges m
    chunk: int | None = None  # rays or points per unit of work (not the box sampler); 0: one unit per object
    reach_placements: int = 6  # object placements for the reachability score; 0: skip reachability
    reach_top: int = 8  # reachability of this many force-closure grasps per unit, best epsilon first; 0: all
    pregrasp_distance: float = PREGRASP_DISTANCE  # [m] pre-grasp back-off along the approach
    volume: bool = False  # GWS volume of force-closure grasps (a full 6-D hull, slow; False stores 0)
    settle: bool | None = None  # the settled epsilon of every grasp (a dynamic closing); None: the hand's default
    trial: ShakeSettings | None = None  # the settle's dynamic closing; None: the hand's (settle_settings)
    fc_budget: int = 1000  # about this many force-closure grasps per object (see budget_share); 0: no limit
    table_plane: tuple[float, float, float, float] | None = None  # plan on a table: Support.vector(); None: no table

    def __post_init__(self) -> None:
        if self.sampler is not None and self.sampler not in SAMPLERS:
            raise InputError(f"unknown sampler '{self.sampler}'; use {', '.join(SAMPLERS)}")
        for field, option, low in AT_LEAST:  # each named with its value (one message named five options)
            if (value := getattr(self, field)) is not None and value < low:
                raise InputError(f"{option} must be at least {low}, got {value}")
        if (rays := (self.approaches or 0) * (1 + self.fan_count)) > MAX_RAYS:
            fan = f" x (1 + --fan {self.fan_count})" if self.fan_count else ""
            raise InputError(f"--approaches {self.approaches}{fan} is {rays:,} rays per object: at most {MAX_RAYS:,} "
                             "(every unit of work holds them all in memory)")
        if self.reach_placements > MAX_REACH_PLACEMENTS:
            raise InputError(f"--reach-placements must be at most {MAX_REACH_PLACEMENTS:,} (the score is the fraction "
                             f"of them reached, each costs IK solves per grasp), got {self.reach_placements}")
        if self.standoffs is not None and not _distances(self.standoffs):
            raise InputError(f"--standoffs must be non-negative distances in metres, got {list(self.standoffs)}")
        if not _distances(self.depths):
            raise InputError(f"--depths must be non-negative distances in metres, got {list(self.depths)}")
        if not (math.isfinite(self.box_delta) and self.box_delta > 0):
            raise InputError(f"--box-delta must be a positive distance in metres, got {self.box_delta}")
        if not _distances([self.pregrasp_distance]):
            raise InputError(f"the pre-grasp distance must be a non-negative distance in metres, got "
                             f"{self.pregrasp_distance}")
        if self.sampler == "antipodal" and self.fan_count:
            raise InputError("--fan tilts approach rays: it needs the surface or box sampler")
        if self.table_plane is not None:
            try:
                Support.from_vector(self.table_plane)
            except ValueError as exc:
                raise InputError(f"table plane: {exc}") from None

    def resolved(self, hand_sampler: str, hand_settle: bool = False,
                 hand_dynamics: SettleDynamics | None = None) -> SweepSettings:
        """These settings with the sampler (``hand_sampler`` unless set), its
        defaults, ``settle`` (``hand_settle`` unless set) and the settle's
        trial filled in (``trial`` if set, else the hand's ``hand_dynamics``,
        :func:`~planner.validation.settings.settle_settings`): what a unit
        runs and what its digest names. The trial (one grasp per world, as
        :func:`planner.plan.settle.settled_epsilons` runs it) decides the
        stored settled epsilons, so it is part of the digest when the sweep
        settles, and absent when it does not."""
        sampler = self.sampler or hand_sampler
        unset = {k: v for k, v in SAMPLER_DEFAULTS[sampler].items() if getattr(self, k) is None}
        settle = hand_settle if self.settle is None else self.settle
        trial = (settle_settings(hand_dynamics) if self.trial is None else replace(self.trial, batch=1)) if settle \
            else None
        return replace(self, sampler=sampler, settle=settle, trial=trial, **unset)

    def to_json(self) -> str:
        data = asdict(self)
        if data["trial"] is None:  # no settle: the digests of sweeps that do not settle stay as they were
            del data["trial"]
        if data["table_plane"] is None:  # no table: the digests of sweeps on the object alone stay as they were
            del data["table_plane"]
        else:
            data["table_version"] = TABLE_VERSION
        data["algorithm"] = ALGORITHM_VERSION
        return json.dumps(data, sort_keys=True)

    def support(self) -> Support | None:
        """The table the sweep plans on (None: the object alone)."""
        return None if self.table_plane is None else Support.from_vector(self.table_plane)

    def on(self, support: Support | None) -> SweepSettings:
        """These settings planning on ``support`` (its plane rounded as the
        database stores vectors, so that the digest is the same wherever the
        plane is computed)."""
        plane = None if support is None else tuple(round(float(v), PLANE_DIGITS) for v in support.vector())
        return replace(self, table_plane=plane)  # type: ignore[arg-type]

    @property
    def digest(self) -> str:
        return hashlib.sha256(self.to_json().encode()).hexdigest()[:16]

    def _resolved_field(self, name: str) -> int:
        value = getattr(self, name)
        if value is None:
            raise InputError(f"sweep setting '{name}' is not resolved: call SweepSettings.resolved first")
        return int(value)

    @property
    def rays_known(self) -> int | None:
        """Rays (or antipodal points) per object when known before sampling."""
        if self.sampler is None:
            raise InputError("the sweep's sampler is not resolved: call SweepSettings.resolved first")
        if self.sampler == "surface":
            return self._resolved_field("approaches") * (1 + self.fan_count)
        return self._resolved_field("approaches") if self.sampler == "antipodal" else None

    def chunks(self) -> int:
        """Units of work per object."""
        rays = self.rays_known
        if rays is None or self._resolved_field("chunk") == 0:
            return 1
        return -(-rays // self._resolved_field("chunk"))

    def ray_range(self, chunk: int, total: int) -> range:
        if self.chunks() == 1:
            return range(total)
        size = self._resolved_field("chunk")
        return range(chunk * size, min(total, (chunk + 1) * size))

    def budget_share(self) -> int | None:
        """Force-closure grasps after which one unit of work stops trying new
        rays or points: ``fc_budget`` split evenly over the object's units
        (rounded up), None without a budget. A unit finishes the ray or point
        in progress, then leaves the rest untried: its rays and points are
        independent random draws (or a grid, for the box sampler's one
        unit), so stopping early is sampling fewer of them, no region of the
        object favoured; the unit's grasps depend on the unit alone, whatever
        the worker count or backend."""
        if not self.fc_budget:
            return None
        return -(-self.fc_budget // self.chunks())

    def above_rays(self, chunk: int) -> int:
        """Rays straight down onto an object on a table that unit ``chunk``
        tries before its sampled rays (ray samplers on a table, the first
        unit: :func:`planner.plan.sampling.from_above`)."""
        return ABOVE_RAYS if self.table_plane is not None and self.sampler != "antipodal" and chunk == 0 else 0

    def roll_angles(self, symmetry: int = 1) -> np.ndarray:
        """Rolls [rad]; a hand symmetric under a half turn needs only [0, pi)."""
        rolls = self._resolved_field("rolls")
        return 2 * np.pi * np.arange(rolls) / (rolls * symmetry)


def unit_rng(seed: int, object_name: str, hand_name: str, *stream: int) -> np.random.Generator:
    """The unit's generator: a function of (seed, object, hand) only; ``stream``
    numbers give independent sub-streams (placements, one per candidate...)."""
    return np.random.default_rng([seed, zlib.crc32(object_name.encode()), zlib.crc32(hand_name.encode()), *stream])


#: Sub-stream numbers of :func:`unit_rng`.
PLACEMENT_STREAM = 1
IK_STREAM = 2


@dataclass(frozen=True)
class Candidate:
    """One grasp to try. Ray samplers: approach ray ``ray`` of the object's
    rays, the hand rolled by ``roll`` [rad] about it, backed off by
    ``standoff`` [m] after first contact. Antipodal sampler: pair ``ray`` of
    the object's points, the approach direction at ``roll`` [rad] about its
    closing axis, the tool centre point ``standoff`` [m] past the chord's
    middle (a depth)."""

    index: int
    ray: int
    preshape: Preshape
    roll: float
    standoff: float


def candidates(approaches: Approaches, shapes: tuple[Preshape, ...], settings: SweepSettings,
               symmetry: int = 1, rays: Collection[int] | None = None) -> list[Candidate]:
    """Every (ray, preshape, roll, standoff) in a fixed order, numbered over the
    whole object; ``rays`` keeps only those of one chunk. A preshape's rolls
    spread over the turn after which the hand and that preshape's grasp
    repeat (2 pi / (``symmetry`` x its ``roll_symmetry``)), from the ray's
    phase (:meth:`~planner.plan.sampling.Approaches.phase`)."""
    rolls = {shape.name: settings.roll_angles(symmetry * shape.roll_symmetry) for shape in shapes}
    per_ray = [(shape, roll, standoff) for shape in shapes  # each ray's candidates, numbered ray by ray: only the
               for roll, standoff in product(rolls[shape.name], settings.standoffs or shape.standoffs)]  # unit's made
    keep = range(len(approaches)) if rays is None else sorted({r for r in rays if 0 <= r < len(approaches)})
    return [Candidate(ray * len(per_ray) + k, ray, shape, float(approaches.phase(ray) + roll), float(standoff))
            for ray in keep for k, (shape, roll, standoff) in enumerate(per_ray)]


def antipodal_candidates(pairs: Pairs, shapes: tuple[Preshape, ...], openings: dict[str, float],
                         settings: SweepSettings, clearance: float, rays: range | None = None) -> list[Candidate]:
    """For every point pair (usable or not: a refused pair's candidates are
    counted as rejected), every approach direction and depth, numbered over
    the whole object; ``rays`` keeps one chunk's points. The preshape of a
    pair is the least open one whose opening ``openings[name]`` [m] exceeds
    the chord by ``clearance`` per side (the fingers are then opened to fit
    the chord), else the most open one."""
    by_opening = sorted(shapes, key=lambda s: openings[s.name])
    angles = 2 * np.pi * np.arange(settings._resolved_field("rolls")) / settings._resolved_field("rolls")
    per_point = len(angles) * len(settings.depths)
    out = []
    for i in range(len(pairs)) if rays is None else rays:
        width = pairs.widths[i]
        shape = next((s for s in by_opening if openings[s.name] >= width + 2 * clearance), by_opening[-1])
        for k, angle in enumerate(angles):
            for j, depth in enumerate(settings.depths):
                index = i * per_point + k * len(settings.depths) + j
                out.append(Candidate(index, i, shape, float(pairs.phases[i] + angle), float(depth)))
    return out


def candidate_count(settings: SweepSettings, shapes: tuple[Preshape, ...], chunk: int = 0,
                    rays: int | None = None) -> int | None:
    """Candidates of unit ``chunk`` as :func:`candidates` or
    :func:`antipodal_candidates` will list them, known before sampling (for
    progress); None for the box sampler, whose rays depend on the mesh, unless given (``rays``: its grid's that hit
    it, :func:`~planner.plan.sampling.box_ray_count`; their ``--fan`` tilted ones added here)."""
    rays = settings.rays_known if rays is None else rays * (1 + settings.fan_count)
    if rays is None:
        return None
    points = len(settings.ray_range(chunk, rays))
    if settings.sampler == "antipodal":
        return points * settings._resolved_field("rolls") * len(settings.depths)
    points += settings.above_rays(chunk)
    per_ray = sum(len(settings.standoffs or shape.standoffs) for shape in shapes)
    return points * settings._resolved_field("rolls") * per_ray


def check_unit_size(settings: SweepSettings, shapes: tuple[Preshape, ...], rays: int | None = None) -> None:
    """Refuse a sweep whose first unit of work (the largest: full, with a table's rays from above) would hold more
    than :data:`MAX_UNIT_CANDIDATES` candidates, before any work, naming the options whose product it is; ``rays``:
    the box sampler's, known once its mesh is (:func:`planner.plan.sampling.box_ray_count`)."""
    count = candidate_count(settings, shapes, 0, rays)
    if count is None or count <= MAX_UNIT_CANDIDATES:
        return
    cast = len(settings.ray_range(0, settings.rays_known or (rays or 0) * (1 + settings.fan_count)))
    cast += settings.above_rays(0)
    per = (f"{len(settings.depths)} --depths" if settings.sampler == "antipodal" else
           f"{sum(len(settings.standoffs or s.standoffs) for s in shapes)} standoffs over the preshapes")
    fan = f", with --fan {settings.fan_count} tilted ones each" if settings.fan_count else ""
    given = {"antipodal": "points (--approaches, or --chunk of them)",
             "box": f"rays (the --box-delta grid's that meet it{fan})"}
    raise InputError(f"a unit of work would hold {count:,} candidates ({cast:,} "
                     f"{given.get(settings.sampler or '', 'rays (--approaches, or --chunk of them)')} x --rolls "
                     f"{settings.rolls} x {per}): at most {MAX_UNIT_CANDIDATES:,}, each held in a worker's memory; use "
                     f"{'a larger --box-delta' if settings.sampler == 'box' else 'a smaller --chunk'} or fewer --rolls")


def _distances(values: Sequence[float]) -> bool:
    """At least one value, each finite and >= 0 [m]."""
    return bool(len(values)) and all(math.isfinite(v) and v >= 0 for v in values)


def check_sampler(settings: SweepSettings, hand: HandSpec) -> None:
    """Refuse the antipodal sampler for a hand that is not a parallel jaw (before any unit runs)."""
    if settings.sampler == "antipodal" and hand.jaw is None:
        raise InputError(f"hand '{hand.name}': the antipodal sampler needs a parallel jaw; use --sampler surface or "
                         "box")


def stored_conflict(stored: str, ours: Sequence[str]) -> tuple[dict, dict, list[str]] | None:
    """(stored settings, ours, the keys that differ) where a sweep stored with
    settings ``stored`` (JSON, as the units table holds it) would be swept
    again by a run with settings ``ours`` (JSON, one per table plane), else
    None: another table plane, an import, or (ray samplers) explicit
    preshapes that share none is another set of candidates (an antipodal
    candidate is a chord, an approach and a depth: the preshape only opens
    the jaw on it, so the same chords close alike under another); any other
    difference (the planner's
    version, a budget, the reach settings, the chunk, the preshapes named or
    not or in another order) tries the same candidates again and would store
    their grasps twice."""
    old = json.loads(stored)
    if "import" in old:
        return None
    for new in map(json.loads, ours):
        if new.get("table_plane") != old.get("table_plane"):
            continue
        if new.get("preshapes") and old.get("preshapes") and not set(new["preshapes"]) & set(old["preshapes"]) and \
                "antipodal" not in (new.get("sampler"), old.get("sampler")):
            continue  # rays: each preshape its own candidates (antipodal: the chord's, whatever opens on it)
        return old, new, sorted(k for k in new.keys() | old.keys() if new.get(k) != old.get(k))
    return None


def differences(old: dict, new: dict, keys: Sequence[str]) -> str:
    """``keys`` of two settings as a run's message says them: ours, then stored."""
    return ", ".join(f"{_NAMED.get(k, k)} {json.dumps(new.get(k))} (stored {json.dumps(old.get(k))})" for k in keys)


#: How :func:`differences` names the settings that are not options.
_NAMED = {"algorithm": "the planner's algorithm version", "table_version": "the table sweep's version"}
