"""Reading the contacts of a closed hand, step 6 of
:mod:`planner.plan.closing`: the part of
:class:`~planner.plan.closing.Grasper` that turns the links touching the
object into contacts (:class:`ContactReading`): contact patches
(:mod:`planner.plan.patches`, the default) or the legacy closest points
spread over each link, moved onto the exact mesh when closing ran against a
proxy; and the joint frames and link poses the grip measures read.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.plan.closing_types import Closed, CloseSettings, Rejected
from planner.plan.contacts import HandContacts, spread
from planner.plan.measures import JointFrames
from planner.plan.patches import ObjectSurface, discretise, regions
from planner.sim import Body, Closest, Sim
from planner.specs.hands import HandSpec

#: No closest pair.
NO_PAIRS = Closest(np.zeros(0, int), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))


class ContactReading:
    """Reads the contacts of :class:`~planner.plan.closing.Grasper` (which
    holds the attributes below and answers the queries)."""

    sim: Sim
    hand: HandSpec
    body: Body
    names: dict[int, str]  # link index -> name
    settings: CloseSettings
    surface: ObjectSurface | None
    exact_surface: ObjectSurface | None
    queries: int
    far_body: int | None  # the surface hulls (None: the reference path)
    object_body: int
    _indices: tuple[int, ...]  # the links with geometry

    if TYPE_CHECKING:  # the queries of planner.plan.closing.Grasper
        def _closest(self, reach: float, link: str | None = None) -> Closest: ...

        def _beyond(self, index: int, distance: float) -> bool: ...

        def _place(self, pose: np.ndarray, joints: dict[str, float]) -> None: ...

    def _read(self, pose: np.ndarray, open_joints: dict[str, float], closed: dict[str, float]) -> Closed | Rejected:
        s = self.settings
        pairs = self._touching(s.contact_tol)
        if len(pairs) == 0:
            return Rejected("no_contact", self.queries)
        true_gap = pairs.distance + self.hand.distance_offset
        if true_gap.min() < -s.max_penetration:
            return Rejected("penetration", self.queries)
        names = [self.names[i] for i in pairs.links]
        if any(n not in self.hand.contact_links for n in names):
            return Rejected("bad_link", self.queries)
        link_poses = self._link_poses()  # read once: the patches, the joint frames and the grasp's record
        if s.contacts == "patch" and self.surface is not None:
            contacts = self._patches(pairs, names, link_poses)
        else:
            contacts = self._points(pairs, names)
        if self.exact_surface is not None:
            contacts = self._onto_exact(contacts)
        return Closed(pose.copy(), dict(open_joints), {k: float(v) for k, v in closed.items()}, contacts, self.queries,
                      self._joint_frames(link_poses), link_poses)

    def _touching(self, reach: float) -> Closest:
        """:meth:`_closest` of the whole hand within ``reach`` [m] (no more than ``settings.near``): the same rows
        in the same order, the exact mesh asked only of the links within ``near`` of the surface hulls, link by
        link, as :meth:`_closest` asks it only of a hand within ``near``. Why (issue 24): PyBullet answers a
        link's query of a concave mesh triangle by triangle under the link's box; the palm's, a few millimetres
        off the hulls on most grasps, cost 1.2 ms a grasp on the peer's 5,758-face scan and 1.7 ms on a
        100k-face capsule's 4,000-face proxy (a finger's 0.16-0.28 ms) and found no pair."""
        s, offset = self.settings, self.hand.distance_offset
        if self.far_body is None or reach > s.near:
            return self._closest(reach)
        self.queries += 1
        if all(self._beyond(i, reach - offset) for i in self._indices):
            return NO_PAIRS  # what _closest gives
        far = self.sim.closest(self.body.uid, self.far_body, s.near - offset)
        if not np.any(far.distance <= reach - offset):  # what _closest's query of the hulls within reach finds
            return NO_PAIRS
        return self.sim.closest(self.body.uid, self.object_body, reach - offset, tuple(sorted(set(far.links.tolist()))))

    def read(self, pose: np.ndarray, open_joints: dict[str, float], closed: dict[str, float]) -> Closed | Rejected:
        """The hand placed at ``pose`` with ``closed`` joints (a stored grasp),
        its contacts read as the settings say (e.g. the legacy points of a
        grasp planned with patches)."""
        self.queries = 0
        self._place(np.array(pose, float), dict(closed))
        return self._read(np.array(pose, float), dict(open_joints), dict(closed))

    def _link_poses(self) -> dict[str, np.ndarray]:
        """(4, 4) pose of every contact link as placed, object frame."""
        return {link: self.sim.link_pose(self.body, link) for link in self.hand.contact_links}

    def _joint_frames(self, link_poses: dict[str, np.ndarray]) -> JointFrames:
        """Origins and unit axes of the finger joints as placed, object frame
        (a URDF joint frame is its child link's frame; ``link_poses``: the
        :meth:`_link_poses` as placed, the child's read from them where there)."""
        names = tuple(j.name for j in self.hand.joints)
        origins, axes = np.zeros((len(names), 3)), np.zeros((len(names), 3))
        for i, joint in enumerate(self.hand.joints):
            frame = link_poses[joint.child] if joint.child in link_poses else self.sim.link_pose(self.body, joint.child)
            axis = frame[:3, :3] @ self.body.joint_axes[joint.name]
            origins[i], axes[i] = frame[:3, 3], axis / np.linalg.norm(axis)
        return JointFrames(names, origins, axes)

    def _patches(self, pairs: Closest, names: list[str], link_poses: dict[str, np.ndarray]) -> HandContacts:
        """Contact patches of the links PyBullet finds touching (``names``: the link of each of ``pairs``; every
        one a contact link, whose pose ``link_poses`` holds); a link whose patch comes out empty (a sliver below
        the sampling) keeps its points (:meth:`_points`, read only then: every link has a patch on nearly every
        grasp)."""
        touching = tuple(sorted(set(names)))
        found = regions(self.hand, self.surface, link_poses, touching)  # type: ignore[arg-type]
        patch = discretise(found, self.settings.patches)
        if set(touching) <= set(patch.links):
            return patch
        points = self._points(pairs, names)
        missing = [i for i, link in enumerate(points.links) if link not in set(patch.links)]
        keep = np.array(missing, int)
        return HandContacts(np.vstack([patch.points, points.points[keep]]),
                            np.vstack([patch.normals, points.normals[keep]]),
                            patch.links + tuple(points.links[i] for i in missing),
                            np.r_[patch.radius, points.radius[keep]], np.r_[patch.region, points.region[keep]])

    def _onto_exact(self, contacts: HandContacts) -> HandContacts:
        """The contacts read on the proxy with their points moved to the
        nearest point found on the exact surface (at most the proxy's
        deviation away) and their normals the exact surface's averaged over
        ``patches.normal_radius`` (:mod:`planner.geometry.normals`), of the
        faces on the side of the proxy's normal (at a sharp edge, the
        proxy's reading chose a normal in the edge's cone): a
        scan's triangles and its proxy's facets are tilted by its noise, and
        a contact's normal taken from one of them made force closure a
        matter of which proxy (a rough capsule: 300 of 362 grasps force
        closure on one, 233 on another, from the same poses)."""
        if len(contacts) == 0:
            return contacts
        exact = self.exact_surface
        points, _, face = exact.nearest(contacts.points)  # type: ignore[union-attr]
        radius = self.settings.patches.normal_radius
        normals = -exact.scale_normals.at(points, face, radius, toward=-contacts.normals)  # type: ignore[union-attr]
        return HandContacts(points, normals, contacts.links, contacts.radius, contacts.region)

    def _points(self, pairs: Closest, names: list[str]) -> HandContacts:
        """The legacy reading: closest points, at most MAX_PER_LINK per link spread over it."""
        normals = -pairs.normal_b
        points = pairs.on_b - pairs.normal_b * (self.hand.distance_offset / 2)
        keep_pts, keep_nrm, keep_links = [], [], []
        for link in sorted(set(names)):
            idx = np.flatnonzero(np.array(names) == link)
            chosen = idx[spread(points[idx])]
            keep_pts.append(points[chosen])
            keep_nrm.append(normals[chosen])
            keep_links += [link] * len(chosen)
        return HandContacts(np.vstack(keep_pts), np.vstack(keep_nrm), tuple(keep_links))
