"""What closing (:mod:`planner.plan.closing`) asks the simulator: the part of
:class:`~planner.plan.closing.Grasper` that finds the pairs of the hand (or one link) and the object within a range
(:class:`ObstacleQueries`), and the safe travel they allow.

Far from the object the surface hulls (:mod:`planner.geometry.hulls`) answer, whose gaps are lower bounds of the
true ones (they contain the surface); within ``near`` of them the exact mesh, a long range cut to ``exact_reach``
(:class:`Bounded`); a box test before each query of the hulls skips the links too far for any pair
(:meth:`ObstacleQueries._beyond`). A finger closing expects near the hulls asks the exact mesh first
(:meth:`ObstacleQueries._closest_near`: the same pairs, one query of the hulls fewer); a revolute finger's link
whose bracket (:class:`HullBracket`) shows it near the hulls asks the exact mesh alone, one it expects near asks
the exact mesh first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.plan.contact_reading import NO_PAIRS
from planner.plan.tolerances import BRACKET_SLACK, CLOSING_SPEED_MIN, NEAR_SLACK
from planner.sim import Body, Closest, Sim
from planner.specs.hands import HandSpec

if TYPE_CHECKING:
    from planner.plan.closing_types import CloseSettings

__all__ = ["BROADPHASE_SLACK", "Bounded", "HullBracket", "ObstacleQueries"]

#: [m] The broadphase (:meth:`Grasper._beyond`) skips a query of the surface hulls when a link's box is
#: farther than the query's range plus this from theirs. PyBullet's boxes hold its shapes with their
#: margins, so no pair can be nearer than the boxes' gap; the slack covers its round-off many times.
BROADPHASE_SLACK = 0.001


@dataclass(frozen=True)
class Bounded(Closest):
    """Closest pairs complete only up to a true gap ``reach`` [m]: any pair
    not listed is at least that far."""

    reach: float = np.inf


class HullBracket:
    """What a link's query of the surface hulls would answer where it is now, bracketed: ``low`` <= its gap
    (:meth:`ObstacleQueries._obstacle_gap`'s ``distance + offset`` [m], inf without a pair in range) <= ``high``.
    Set by each query (a pair's gap, a range no pair was within, the boxes' gap) and widened by each step by the
    link's speed bound times the step (:meth:`moved`): a link ``low`` shows far from the hulls is asked only if its
    gap could bound the step (:mod:`planner.plan.finger_closing`), one ``high`` shows near asks the exact mesh
    alone, whose answer then decides (exact: the same gaps, fewer queries); one :meth:`expected` near asks it first
    (:meth:`ObstacleQueries._obstacle_gap`)."""

    __slots__ = ("high", "low")

    def __init__(self) -> None:
        self.low, self.high = -math.inf, math.inf

    def set(self, low: float, high: float = math.inf) -> None:
        self.low, self.high = low - BRACKET_SLACK, high + BRACKET_SLACK

    def expected(self) -> float:
        """[m] A guess of the gap now (inf or NaN when no query set both ends): the last answer less half the travel
        since (a link closes at about half its speed bound), a guess only: which query to ask first."""
        return 0.75 * self.low + 0.25 * self.high

    def moved(self, travel: float) -> None:
        """The link moved by at most ``travel`` [m]."""
        self.low, self.high = self.low - travel, self.high + travel


class ObstacleQueries:
    """The queries of :class:`~planner.plan.closing.Grasper` (which holds the attributes below)."""

    sim: Sim
    hand: HandSpec
    body: Body
    settings: CloseSettings
    object_body: int
    far_body: int | None  # the surface hulls (None: the reference path)
    table_body: int | None
    queries: int
    _far_box: tuple
    _indices: tuple[int, ...]  # the links with geometry, the tips first

    def _closest(self, reach: float, link: str | None = None, exact: Closest | None = None) -> Closest:
        """Pairs whose *true* gap is below ``reach`` [m]: with the exact mesh,
        or, while the hand is farther than ``near`` from the surface hulls
        (:mod:`planner.geometry.hulls`), with the hulls (lower bounds of the
        true gaps, as they contain the surface). Near the hulls, a long reach
        is cut to ``exact_reach`` (:class:`Bounded`). ``exact``: the exact mesh's
        pairs within ``exact_reach`` already asked (:meth:`_closest_near`), not asked again."""
        self.queries += 1
        index = None if link is None else self.body.links[link]
        offset, s = self.hand.distance_offset, self.settings
        if self.far_body is not None:
            if all(self._beyond(i, reach - offset) for i in ((index,) if link else self._indices)):
                return NO_PAIRS  # what the query below would give: no pair within its range
            far = self.sim.closest(self.body.uid, self.far_body, reach - offset, index)
            if len(far) == 0 or far.min_distance + offset > s.near:
                return far
            if reach > s.exact_reach:
                pairs = exact if exact is not None else self.sim.closest(self.body.uid, self.object_body,
                                                                         s.exact_reach - offset, index)
                return Bounded(pairs.links, pairs.distance, pairs.on_a, pairs.on_b, pairs.normal_b, s.exact_reach)
        return self.sim.closest(self.body.uid, self.object_body, reach - offset, index)

    def _closest_near(self, reach: float, link: str) -> Closest:
        """:meth:`_closest` (``reach``, ``link``) of a link closing expects near the surface hulls, the same pairs:
        the exact mesh asked first (within ``exact_reach``, what the hulls' being near leads to), and where it has a
        pair nearer than ``near`` by :data:`NEAR_SLACK`, the hulls, which contain the surface, are nearer still:
        their query would only confirm it (issue 24: one query of the hulls of each finger's closing, 0.1-0.2 ms).
        Otherwise the hulls decide as in :meth:`_closest`, the exact pairs kept for it."""
        s, offset = self.settings, self.hand.distance_offset
        if self.far_body is None or reach <= s.exact_reach:
            return self._closest(reach, link)
        pairs = self.sim.closest(self.body.uid, self.object_body, s.exact_reach - offset, self.body.links[link])
        if len(pairs) and pairs.min_distance + offset <= s.near - NEAR_SLACK:
            self.queries += 1
            return Bounded(pairs.links, pairs.distance, pairs.on_a, pairs.on_b, pairs.normal_b, s.exact_reach)
        return self._closest(reach, link, pairs)

    def _obstacles(self, reach: float, link: str | None = None, near: bool = False) -> Closest:
        """:meth:`_closest` with the table's pairs within ``reach`` added (what stops the hand and the fingers);
        ``near``: the link is expected near the surface hulls (:meth:`_closest_near`, the same pairs)."""
        pairs = self._closest_near(reach, link) if near and link is not None else self._closest(reach, link)
        if self.table_body is None:
            return pairs
        index = None if link is None else self.body.links[link]
        table = self.sim.closest(self.body.uid, self.table_body, reach - self.hand.distance_offset, index)
        if len(table) == 0:
            return pairs
        joined = [np.concatenate([getattr(pairs, k), getattr(table, k)]) for k in
                  ("links", "distance", "on_a", "on_b", "normal_b")]
        return Bounded(*joined, pairs.reach) if isinstance(pairs, Bounded) else Closest(*joined)

    def _obstacle_gap(self, reach: float, link: str, bracket: HullBracket | None = None) -> float:
        """:meth:`_gap` of :meth:`_obstacles` (``reach``, ``link``), the same value without making the pairs:
        what closing a finger reads of a link that does not only translate. ``bracket``: the link's (without a
        table), read (a link near the hulls asks the exact mesh alone) and set anew."""
        self.queries += 1
        index, offset, s, bound = self.body.links[link], self.hand.distance_offset, self.settings, np.inf
        uid, query = self.body.uid, self.sim.min_distance
        cut = s.exact_reach if self.far_body is not None and reach > s.exact_reach else np.inf  # near: a long reach cut
        distance = exact = np.nan
        if self.far_body is not None and not (bracket is not None and bracket.high <= min(s.near, reach)):
            if bracket is not None and bracket.expected() <= s.near - 2 * NEAR_SLACK:
                # expected near: the exact mesh first (what the hulls' being near leads to); a pair nearer than near
                # by NEAR_SLACK shows the hulls, which contain the surface, nearer still: their query is left out (a
                # wrong guess costs a query, never the answer; the bracket is not set: it still holds)
                exact = query(uid, self.object_body, min(reach, cut) - offset, index)
            if not exact + offset <= s.near - NEAR_SLACK:
                box = self._box_gap(index)  # no pair within the range: inf, and nothing near the hulls
                distance = np.inf if box > reach - offset + BROADPHASE_SLACK else query(uid, self.far_body,
                                                                                        reach - offset, index)
                if bracket is not None:
                    if box > reach - offset + BROADPHASE_SLACK:
                        bracket.set(box + offset - BROADPHASE_SLACK)
                    elif math.isinf(distance):
                        bracket.set(reach)
                    else:
                        bracket.set(distance + offset, distance + offset)
        if not distance + offset > s.near:  # near the hulls (or none): the exact mesh, a long reach cut
            bound = cut
            distance = exact if exact == exact else query(uid, self.object_body, min(reach, bound) - offset, index)
        if self.table_body is not None:
            distance = min(distance, query(uid, self.table_body, reach - offset, index))
        return min(distance + offset, bound)

    def _beyond(self, index: int, distance: float) -> bool:
        """Is link ``index`` of the hand, as placed, farther than ``distance`` [m] from the surface hulls by
        the two boxes (then PyBullet finds no pair within ``distance``: its query costs 2-6x this test)?"""
        return self._box_gap(index) > distance + BROADPHASE_SLACK

    def _box_gap(self, index: int) -> float:
        """[m] The gap between the boxes of link ``index`` as placed and of the surface hulls along the axis that
        parts them most (at most their true gap; <= 0 where they overlap)."""
        (ax, ay, az), (bx, by, bz) = self.sim.link_box(self.body.uid, index)
        (lx, ly, lz), (hx, hy, hz) = self._far_box
        return max(lx - bx, ax - hx, ly - by, ay - hy, lz - bz, az - hz)

    def _gap(self, closest: Closest) -> float:
        gap = closest.min_distance + self.hand.distance_offset
        return min(gap, closest.reach) if isinstance(closest, Bounded) else gap

    def _translation_step(self, pairs: Closest, velocity: np.ndarray) -> tuple[bool, float]:
        """(touching, safe travel [m]) for links translating along unit ``velocity``.

        Each closest-point pair is a convex link piece and a convex object piece
        (a triangle); their distance is a convex function of the travel, so it
        cannot reach zero before ``gap / closing speed`` along the pair's
        normal, and a pair that is not closing in never collides. Pairs beyond
        the query range are at least ``coarse_step`` away.
        """
        s = self.settings
        longest = s.coarse_step if not isinstance(pairs, Bounded) else min(s.coarse_step,
                                                                             max(pairs.reach - s.gap, 0.0))
        if len(pairs) == 0:
            return False, longest
        gaps = pairs.distance + self.hand.distance_offset
        speed = -(pairs.normal_b @ velocity)
        closing = speed > CLOSING_SPEED_MIN
        if np.any(closing & (gaps <= s.contact_tol)):
            return True, 0.0
        if not np.any(closing):
            return False, longest
        step = float(np.min((gaps[closing] - s.gap) / speed[closing]))
        return False, min(max(step, 0.0), longest)
