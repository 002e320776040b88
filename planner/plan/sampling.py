"""Approach sampling: where and from which direction the hand comes in.

Two OpenRAVE-style ray samplers (for multi-finger hands): the hand comes in along a ray onto the surface, then closes.

- ``surface``: area-weighted random surface points with their outward normals (needs the seeded generator);
- ``box``: the bounding box grown by 1 cm, each face gridded every ``delta`` metres, rays cast inward; each first hit
  gives a point and its normal.

An optional *fan* adds directions tilted by ``fan_angle`` around each normal. The hand approaches along ``direction``
(into the object); the approach ray passes through ``point``.

On a table, the ray samplers' rays are joined by :data:`ABOVE_RAYS` rays straight down onto the object's top
(:func:`from_above`): through the centre of mass and along the long axis of the object's footprint, each with a roll
phase that puts the hand's axes along the footprint's axes. A random surface point lands a table pinch's fingertips
on the object's top more often than beside it: on a flat blob 3 cm thick (random_000 lying down) the Allegro's sweep
of 352 candidates per resting pose found 0-1 force-closure grasps, 48 centred candidates straight down 5-7.

One sampler for parallel jaws, as the large parallel-jaw datasets are made
(:func:`antipodal`, after Dex-Net's and ACRONYM's antipodal samplers): an
area-weighted surface point, a ray from it into the object, the point where
that ray leaves the object, the closing axis through both; the candidates
then put the fingers on that axis and spread approach directions around it
(:func:`antipodal_poses`). The first ray runs along the inward normal (the
squarest chord); a point whose pair is refused tries up to
:data:`CONE_TRIES` rays in random directions inside the friction cone about
that normal (:func:`cone_directions`). A pair is refused before any
simulation when the chord is wider than every preshape's opening or thinner
than a skin, or either normal lies outside the friction cone of the axis.
The rays in the cone are what find pairs on tapered and curved surfaces
(issue 26): on a cone 7 cm across and 8 cm tall the ray along the normal
meets the far side 47 degrees off its normal, outside mu = 0.5's
26.6-degree cone, while a level chord meets both sides 23.6 degrees off.
Drawing every ray in the cone instead (Dex-Net's way) also tilts the chords
where the normal was usable: on the mug and the box that halved the
force-closure grasps of the default sweep, hence the normal first.

All vectors in the object frame, lengths in metres, angles in radians.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import trimesh

from planner.errors import InputError
from planner.geometry.frames import hand_rotation, tangent_bases, tilted
from planner.plan.tolerances import (
    ABOVE_PHASES,
    ABOVE_POINTS,
    ABOVE_RAYS,
    ABOVE_SPREAD,
    ABOVE_TURN,
    BOX_MARGIN,
    MIN_CHORD,
    RAY_START,
)
from planner.specs.hands import SAMPLERS

__all__ = ["SAMPLERS", "RAY_SAMPLERS", "ABOVE_RAYS", "Approaches", "Pairs", "sample", "antipodal",
           "antipodal_poses", "cone_directions", "fan", "from_above"]

#: Antipodal sampler: rays drawn in the friction cone for a point whose pair along the
#: normal is refused. On the 7 x 8 cm cone about 5% of side points find a level chord
#: per ray; four rays find one for ~19% at no cost to points whose normal pair is usable.
CONE_TRIES = 4

#: The samplers whose candidates approach along rays (the others place the hand directly).
RAY_SAMPLERS = ("surface", "box")


@dataclass(frozen=True)
class Approaches:
    """A batch of approach rays.

    Attributes:
        points: (n, 3) surface points [m], object frame.
        normals: (n, 3) unit outward surface normals at ``points``.
        directions: (n, 3) unit approach directions (into the object).
        phases: (n,) [rad] added to every roll of a ray (None: 0 for all).
    """

    points: np.ndarray
    normals: np.ndarray
    directions: np.ndarray
    phases: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.points)
        for name in ("points", "normals", "directions"):
            if getattr(self, name).shape != (n, 3):
                raise ValueError(f"Approaches.{name} must be (n, 3)")
        if self.phases is not None and np.shape(self.phases) != (n,):
            raise ValueError("Approaches.phases must be (n,)")

    def phase(self, ray: int) -> float:
        """[rad] the roll phase of ray ``ray``."""
        return 0.0 if self.phases is None else float(self.phases[ray])

    def then(self, other: Approaches) -> Approaches:
        """These rays followed by ``other``'s."""
        phases = None if self.phases is None and other.phases is None else \
            np.r_[[self.phase(i) for i in range(len(self))], [other.phase(i) for i in range(len(other))]]
        return Approaches(np.vstack([self.points, other.points]), np.vstack([self.normals, other.normals]),
                          np.vstack([self.directions, other.directions]), phases)

    def __len__(self) -> int:
        return len(self.points)


def sample(mesh: trimesh.Trimesh, *, sampler: str, count: int, rng: np.random.Generator,
           delta: float = 0.02, fan_count: int = 0, fan_angle: float = 0.3,
           normals_at: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> Approaches:
    """Sample approach rays on ``mesh`` (see module docstring); ``normals_at``
    as :func:`antipodal`'s (default: the faces' own normals)."""
    normals_at = normals_at or _face_normals(mesh)
    if sampler == "surface":
        if count < 1:
            raise InputError(f"--approaches must be at least 1, got {count}")
        points, faces = trimesh.sample.sample_surface(mesh, count, seed=rng)
        normals = normals_at(points, faces)
    elif sampler == "box":
        points, faces = _box_rays(mesh, delta)
        normals = normals_at(points, faces) if len(faces) else np.zeros((0, 3))
    elif sampler == "antipodal":
        raise InputError("the antipodal sampler makes point pairs: use sampling.antipodal")
    else:
        raise InputError(f"unknown sampler '{sampler}'; use {', '.join(SAMPLERS)}")
    base = Approaches(np.asarray(points, float), np.asarray(normals, float), -np.asarray(normals, float))
    return fan(base, fan_count, fan_angle) if fan_count > 0 else base


def from_above(mesh: trimesh.Trimesh, up: np.ndarray, com: np.ndarray, approach_hand: np.ndarray) -> Approaches:
    """:data:`ABOVE_RAYS` rays straight down (along ``-up``, ``up`` the unit
    normal of the table top the object rests on, object frame) onto the
    object: through the centre of mass ``com`` (3,) [m], and through the
    centre of the footprint's smallest enclosing rectangle (``mesh``'s
    vertices projected on the table) moved +- :data:`ABOVE_SPREAD` of its
    length along its long side. Each ray's point is where it first meets
    the mesh (the top level above the footprint where it passes beside it),
    its normal ``up``; its phase is the roll that turns the hand axis most
    nearly square to ``approach_hand`` (hand frame) onto the long side; the
    three points are repeated :data:`ABOVE_PHASES` times, each time with
    that phase turned by another :data:`ABOVE_TURN`."""
    up = np.asarray(up, float) / np.linalg.norm(up)
    e1, e2 = (b[0] for b in tangent_bases(up[None]))
    plane = np.c_[e1, e2]
    flat = np.asarray(mesh.vertices, float) @ plane
    to_box, extents = trimesh.bounds.oriented_bounds_2D(flat)
    back = np.linalg.inv(to_box)
    centre2, axes2 = back[:2, 2], back[:2, :2]
    long2 = axes2[:, int(np.argmax(extents))]
    long = plane @ long2
    top = float(np.max(np.asarray(mesh.vertices, float) @ up))
    com_flat = np.asarray(com, float) - (np.asarray(com, float) @ up) * up
    centre = plane @ centre2
    aims = np.array([com_flat, centre + ABOVE_SPREAD * max(extents) * long,
                     centre - ABOVE_SPREAD * max(extents) * long]) + (top + RAY_START) * up
    down = np.tile(-up, (ABOVE_POINTS, 1))
    hits, rays, _ = mesh.ray.intersects_location(aims, down, multiple_hits=False)
    points = aims - RAY_START * up
    points[rays] = hits
    approach_hand = np.asarray(approach_hand, float)
    ref = np.eye(3)[int(np.argmin(np.abs(approach_hand)))]
    ref = ref - (ref @ approach_hand) * approach_hand / (approach_hand @ approach_hand)
    seen = hand_rotation(approach_hand, -up, 0.0) @ ref
    phase = float(np.arctan2(np.cross(seen, long) @ -up, seen @ long))
    phases = np.repeat(phase + ABOVE_TURN * np.arange(ABOVE_PHASES), ABOVE_POINTS)
    return Approaches(np.tile(points, (ABOVE_PHASES, 1)), np.tile(up, (ABOVE_RAYS, 1)),
                      np.tile(-up, (ABOVE_RAYS, 1)), phases)


#: Rays the box sampler may cast on one object (a 2 mm grid on a 30 cm box: 135,000).
MAX_BOX_RAYS = 1_000_000


def _check_grid(mesh: trimesh.Trimesh, delta: float) -> None:
    """Refuse a spacing ``delta`` [m] casting over :data:`MAX_BOX_RAYS` rays on ``mesh``'s box (1e-9 m took 24 GB)."""
    if delta <= 0:
        raise InputError(f"box sampler spacing must be positive, got {delta}")
    steps = np.floor((mesh.bounds[1] - mesh.bounds[0] + 2 * BOX_MARGIN) / delta) + 1
    rays = 2 * (steps[1] * steps[2] + steps[0] * steps[2] + steps[0] * steps[1])
    if rays > MAX_BOX_RAYS:
        raise InputError(f"--box-delta {delta:g} m casts {rays:.3g} rays on this object's box (at most "
                         f"{MAX_BOX_RAYS:,}): use a larger spacing")


def box_ray_count(mesh: trimesh.Trimesh, delta: float) -> int:
    """The box sampler's approach rays on ``mesh`` at spacing ``delta`` [m] before ``--fan``: its grid's that hit."""
    return len(_box_rays(mesh, delta)[0])


def _box_rays(mesh: trimesh.Trimesh, delta: float) -> tuple[np.ndarray, np.ndarray]:
    _check_grid(mesh, delta)
    lo, hi = mesh.bounds[0] - BOX_MARGIN, mesh.bounds[1] + BOX_MARGIN
    origins, dirs = [], []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        us = np.arange(lo[u], hi[u] + 1e-12, delta)
        vs = np.arange(lo[v], hi[v] + 1e-12, delta)
        grid = np.array(list(itertools.product(us, vs)))
        for side, start in ((1.0, lo[axis]), (-1.0, hi[axis])):
            o = np.zeros((len(grid), 3))
            o[:, u], o[:, v], o[:, axis] = grid[:, 0], grid[:, 1], start
            d = np.zeros_like(o)
            d[:, axis] = side
            origins.append(o)
            dirs.append(d)
    o, d = np.vstack(origins), np.vstack(dirs)
    hits, rays, tris = mesh.ray.intersects_location(o, d, multiple_hits=False)
    order = np.argsort(rays, kind="stable")
    return hits[order], tris[order]


def _face_normals(mesh: trimesh.Trimesh) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The samplers' default ``normals_at``: each point's face's own outward normal."""
    return lambda _, faces: mesh.face_normals[faces]


def fan(base: Approaches, count: int, angle: float) -> Approaches:
    """Add ``count`` directions tilted by ``angle`` [rad] around each normal."""
    points, normals, dirs = [base.points], [base.normals], [base.directions]
    for k in range(count):
        phi = 2 * np.pi * k / count
        points.append(base.points)
        normals.append(base.normals)
        dirs.append(tilted(base.directions, angle, phi))
    phases = None if base.phases is None else np.tile(base.phases, count + 1)
    return Approaches(np.vstack(points), np.vstack(normals), np.vstack(dirs), phases)


@dataclass(frozen=True)
class Pairs:
    """Antipodal point pairs for each of n sampled surface points; a point
    without a usable pair keeps its row, with the reason, so that point ``i``
    is the same whatever part of the object a unit of work covers.

    Attributes:
        points: (n, 3) sampled surface points p1 [m].
        normals: (n, 3) unit outward normals at p1.
        opposite: (n, 3) where the ray from p1 (a direction in the friction cone about -normal)
            leaves the object, p2 [m] (NaN: none).
        axes: (n, 3) unit closing axes, p1 -> p2 (NaN: none).
        widths: (n,) chord lengths |p2 - p1| [m] (NaN: none).
        phases: (n,) [rad] the first approach direction's angle about the axis, random per point.
        reasons: (n,) why a pair is refused ("no_pair", "too_wide", "too_thin", "cone"), or "" when usable.
    """

    points: np.ndarray
    normals: np.ndarray
    opposite: np.ndarray
    axes: np.ndarray
    widths: np.ndarray
    phases: np.ndarray
    reasons: tuple[str, ...]

    def __post_init__(self) -> None:
        n = len(self.points)
        for name in ("points", "normals", "opposite", "axes"):
            if getattr(self, name).shape != (n, 3):
                raise ValueError(f"Pairs.{name} must be (n, 3)")
        if self.widths.shape != (n,) or self.phases.shape != (n,) or len(self.reasons) != n:
            raise ValueError("Pairs.widths, .phases and .reasons must be (n,)")

    def __len__(self) -> int:
        return len(self.points)

    @property
    def midpoints(self) -> np.ndarray:
        """(n, 3) chord midpoints [m]."""
        return 0.5 * (self.points + self.opposite)


def cone_directions(axes: np.ndarray, spread: float, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) unit directions inside the cone of half-angle ``atan(spread)``
    about each of the (n, 3) unit ``axes``: the axis plus a tangent offset of
    length ``spread * u`` (u uniform in [0, 1)) at a uniform azimuth, as
    Dex-Net's antipodal sampler draws them (denser near the axis than a
    uniform spread over the cone's solid angle, so square chords stay
    common). Draws 2 n numbers from ``rng`` whatever ``spread`` (0: the axes)."""
    axes = np.asarray(axes, float).reshape(-1, 3)
    offset = spread * rng.uniform(0.0, 1.0, len(axes))
    azimuth = rng.uniform(0.0, 2 * np.pi, len(axes))
    l_vec, o_vec = tangent_bases(axes)
    d = axes + offset[:, None] * (np.cos(azimuth)[:, None] * l_vec + np.sin(azimuth)[:, None] * o_vec)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def antipodal(mesh: trimesh.Trimesh, count: int, rng: np.random.Generator, *, max_width: float, mu: float,
              min_width: float = MIN_CHORD, spread: float | None = None, tries: int = CONE_TRIES,
              normals_at: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> Pairs:
    """``count`` area-weighted surface points of ``mesh`` and their antipodal
    partners (see module docstring). ``max_width`` [m]: the widest chord the
    hand can take; ``mu``: friction coefficient of the cone test (both
    normals within atan(mu) of the axis: -n1 . axis and n2 . axis >=
    cos(atan(mu)), so each finger pushing along the axis stays inside its
    friction cone). The first ray of a point runs along its inward normal;
    a point whose pair is refused tries up to ``tries`` more rays drawn in
    the cone of half-angle atan(``spread``) about that normal (default
    ``spread`` = ``mu``: anywhere in the friction cone; ``tries`` = 0: the
    normal only) and keeps the first usable pair, else the last refusal.
    The random numbers are drawn in a fixed order and amount (points,
    phases, then ``tries`` directions for every point, used or not), so
    point i is replayable. ``normals_at(points (n, 3), faces (n,))``: the
    outward unit normals at surface points (default: their faces'; a scan's
    at a contact's scale, :mod:`planner.geometry.normals`)."""
    if count < 1:
        raise InputError(f"--approaches must be at least 1, got {count}")
    points, faces = trimesh.sample.sample_surface(mesh, count, seed=rng)
    phases = rng.uniform(0.0, 2 * np.pi, count)  # drawn for every point: point i is replayable
    points = np.asarray(points, float)
    normals_at = normals_at or _face_normals(mesh)
    normals = np.asarray(normals_at(points, faces), float)
    spread = mu if spread is None else spread
    drawn = [cone_directions(-normals, spread, rng) for _ in range(tries)]
    opposite, axes, widths, reasons = _chords(mesh, points, normals, -normals, max_width, mu, min_width, normals_at)
    for directions in drawn:
        retry = np.flatnonzero(reasons != "")
        if len(retry) == 0:
            break
        found = _chords(mesh, points[retry], normals[retry], directions[retry], max_width, mu, min_width,
                        normals_at)
        for whole, part in zip((opposite, axes, widths, reasons), found):
            whole[retry] = part
    return Pairs(points, normals, opposite, axes, widths, phases, tuple(str(r) for r in reasons))


#: The pairs of the last object sampled in this process (:func:`antipodal_once`).
_SAMPLED: dict[tuple, Pairs] = {}


def antipodal_once(key: tuple, mesh: trimesh.Trimesh, count: int, rng: np.random.Generator, **kwargs: object
                   ) -> Pairs:
    """:func:`antipodal` once per ``key`` in this process (the last key's pairs kept, read-only): an object's units all
    sample its whole surface from the object's generator (a 100k-face scan: ~0.5 s a unit). ``key``: object and mesh;
    the generator's state and the arguments join it (``normals_at`` by its keywords); ``rng`` left where reused."""
    key = (*key, count, repr(rng.bit_generator.state),
           *((k, repr(getattr(v, "keywords", None)) if callable(v) else v) for k, v in sorted(kwargs.items())))
    if key not in _SAMPLED:
        _SAMPLED.clear()
        _SAMPLED[key] = pairs = antipodal(mesh, count, rng, **kwargs)  # type: ignore[arg-type]
        for value in (v for v in vars(pairs).values() if isinstance(v, np.ndarray)):
            value.flags.writeable = False
    return _SAMPLED[key]


def forget() -> None:
    """Drop the pairs :func:`antipodal_once` keeps (1,000,000 points: ~120 MB) once their object's units are done."""
    _SAMPLED.clear()


def _chords(mesh: trimesh.Trimesh, points: np.ndarray, normals: np.ndarray, directions: np.ndarray, max_width: float,
            mu: float, min_width: float, normals_at: Callable[[np.ndarray, np.ndarray], np.ndarray]
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(opposite (n, 3), axes (n, 3), widths (n,), reasons (n,)) of rays from
    ``points`` (n, 3) along unit ``directions`` (n, 3) into the object (see
    :class:`Pairs`); a chord is usable (reason "") when both normals lie
    within the friction cone of its axis."""
    n = len(points)
    hits, rays, tris = mesh.ray.intersects_location(points - normals * RAY_START, directions, multiple_hits=False)
    opposite = np.full((n, 3), np.nan)
    exit_normals = np.full((n, 3), np.nan)
    if len(rays):
        opposite[rays], exit_normals[rays] = hits, normals_at(hits, tris)
    chord = opposite - points
    widths = np.linalg.norm(chord, axis=1)
    axes = chord / np.where(widths > 0, widths, 1.0)[:, None]
    inside = np.cos(np.arctan(mu))
    cone = (np.einsum("ij,ij->i", exit_normals, axes) >= inside) & (np.einsum("ij,ij->i", -normals, axes) >= inside)
    reasons = np.where(~np.isfinite(widths), "no_pair",
                       np.where(widths > max_width, "too_wide",
                                np.where(widths < min_width, "too_thin", np.where(cone, "", "cone"))))
    return opposite, axes, widths, reasons.astype(object)


def antipodal_poses(approach_hand: np.ndarray, finger_hand: np.ndarray, tcp: np.ndarray, axes: np.ndarray,
                    centres: np.ndarray, angles: np.ndarray, depths: np.ndarray) -> np.ndarray:
    """(m, 4, 4) hand poses, one per candidate: the fingers close along
    ``axes`` (m, 3) with the tool centre point ``tcp`` ((m, 3) or (3,) [m],
    hand frame) ``depths`` (m,) [m] past ``centres`` (m, 3) along the
    approach; the approach direction lies at ``angles`` (m,) [rad] about the
    axis, from the axis's first tangent (:func:`tangent_bases`).
    ``approach_hand``, ``finger_hand``: (3,) perpendicular unit hand-frame
    axes of the approach and of the fingers' closing."""
    u, v = tangent_bases(axes)
    d = np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * v
    world = np.stack([d, axes, np.cross(d, axes)], axis=2)
    a, f = np.asarray(approach_hand, float), np.asarray(finger_hand, float)
    hand = np.column_stack([a, f, np.cross(a, f)])
    poses = np.zeros((len(axes), 4, 4))
    poses[:, :3, :3] = world @ hand.T
    poses[:, 3, 3] = 1.0
    poses[:, :3, 3] = centres + d * np.asarray(depths)[:, None] - np.einsum(
        "mij,mj->mi", poses[:, :3, :3], np.broadcast_to(np.asarray(tcp, float), (len(axes), 3)))
    return poses
