"""Contacts read from the simulator: a batch in the object frame.

A contact is a point on the object surface, the inward unit normal there,
the hand link that touches it and, for contacts read as patches
(:mod:`planner.plan.patches`), the patch region it belongs to and that
region's radius [m] when it is one soft-finger contact (0: a point contact
at a corner of a larger region). The contact *model* follows
(:func:`contact_models`): frictionless if the link's model (hand spec) is
frictionless; else soft with torsion 2/3 mu radius (uniform pressure on a
disc), at most the link's own ``mu * torsion_radius`` (the one number the
shake trial gives PyBullet as the pad's spinning friction), when the radius
is positive and the link is soft; else point with friction. Contacts without a radius (the legacy
point reading) take their link's model and torsion from the hand spec. The
stored form is JSON text ``[{point, normal, link[, radius, region]}]``
(points, normals and radii rounded to 1 um / 1e-6). A batch read back from the
database keeps that text and decodes it only on first use, so a grasp that is
only exported never pays for decoding its contacts.

:func:`grasp_quality` scores a batch: Ferrari-Canny epsilon (and GWS
volume) with each contact's model.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np

from planner.plan.tolerances import MAX_PER_LINK, MERGE_RADIUS, SOFT_TORSION
from planner.specs.hands import HandSpec

if TYPE_CHECKING:  # scipy and trimesh: loaded where used, so that reading stored contacts needs neither
    from planner import quality
    from planner.geometry.solid import PreparedObject

#: Decimals kept of points [m] and normals in the stored form (1 um).
STORED_DIGITS = 6

_Arrays = tuple[np.ndarray, np.ndarray, tuple[str, ...], np.ndarray, np.ndarray]


class HandContacts:
    """n contacts between the hand and the object (immutable).

    Attributes:
        points: (n, 3) contact points c_i on the object surface [m], object frame.
        normals: (n, 3) unit normals n_i pointing into the object, object frame.
        links: (n,) names of the hand links that touch.
        radius: (n,) [m] radius of a soft contact's region, 0 for a point
            contact, NaN where the link's own model applies (legacy reading).
        region: (n,) index of the patch region of each contact, -1 if none.
    """

    __slots__ = ("_arrays", "_text", "_count", "_touching")

    def __init__(self, points: np.ndarray, normals: np.ndarray, links: tuple[str, ...],
                 radius: np.ndarray | None = None, region: np.ndarray | None = None) -> None:
        n = len(points)
        if points.shape != (n, 3) or normals.shape != (n, 3):
            raise ValueError("HandContacts.points and .normals must be (n, 3)")
        if len(links) != n:
            raise ValueError("HandContacts: one link per contact")
        radius = np.full(n, np.nan) if radius is None else np.asarray(radius, float)
        region = np.full(n, -1) if region is None else np.asarray(region, int)
        if radius.shape != (n,) or region.shape != (n,):
            raise ValueError("HandContacts.radius and .region must be (n,)")
        self._arrays: _Arrays | None = (points, normals, tuple(links), radius, region)
        self._text: str | None = None
        self._count = n
        self._touching = len(set(links))

    @classmethod
    def stored(cls, text: str, count: int, touching: int) -> HandContacts:
        """Contacts as the database holds them: the JSON text and its two counts."""
        out = cls.__new__(cls)
        out._arrays, out._text, out._count, out._touching = None, text, count, touching
        return out

    @classmethod
    def from_items(cls, items: list[dict]) -> HandContacts:
        """Contacts from the items of :meth:`to_json` (``radius`` and ``region``
        optional: a legacy reading has neither)."""
        return cls(*_arrays(items))

    def _decoded(self) -> _Arrays:
        if self._arrays is None:
            self._arrays = _arrays(json.loads(self._text or "[]"))
        return self._arrays

    @property
    def points(self) -> np.ndarray:
        return self._decoded()[0]

    @property
    def normals(self) -> np.ndarray:
        return self._decoded()[1]

    @property
    def links(self) -> tuple[str, ...]:
        return self._decoded()[2]

    @property
    def radius(self) -> np.ndarray:
        return self._decoded()[3]

    @property
    def region(self) -> np.ndarray:
        return self._decoded()[4]

    def __len__(self) -> int:
        return self._count

    @property
    def touching(self) -> int:
        """How many distinct hand links touch the object."""
        return self._touching

    @property
    def frames(self) -> np.ndarray:
        """(n, 3, 3) contact frames R_i with columns (n_i, l_i, o_i)."""
        from planner.geometry.frames import contact_frames

        return contact_frames(self.normals)

    def to_json(self) -> list[dict]:
        """``[{point, normal, link[, radius, region]}]``, rounded as stored."""
        out = []
        for p, n, link, radius, region in zip(self.points, self.normals, self.links, self.radius, self.region):
            item = {"point": [round(float(v), STORED_DIGITS) for v in p],
                    "normal": [round(float(v), STORED_DIGITS) for v in n], "link": link}
            if not np.isnan(radius):
                item["radius"] = round(float(radius), STORED_DIGITS)
            if region >= 0:
                item["region"] = int(region)
            out.append(item)
        return out

    def json_text(self) -> str:
        """The stored form: compact JSON text of :meth:`to_json`."""
        if self._text is None:
            self._text = json.dumps(self.to_json(), separators=(",", ":"))
        return self._text


def contact_models(contacts: HandContacts, hand: HandSpec, mu: float) -> tuple[list[str], np.ndarray]:
    """(n model names, (n,) torsion [m]) of the contacts for the quality
    functions (see the module docstring)."""
    names, torsion = [], np.zeros(len(contacts))
    for i, (link, radius) in enumerate(zip(contacts.links, contacts.radius)):
        own = hand.contacts[link]
        if np.isnan(radius) or own.model == "frictionless":
            names.append(own.model)
            torsion[i] = own.torsion(mu)
        elif radius > 0 and own.model == "soft":
            names.append("soft")
            torsion[i] = min(SOFT_TORSION * mu * radius, own.torsion(mu))
        else:
            names.append("point")
    return names, torsion


def spread(points: np.ndarray, limit: int = MAX_PER_LINK, radius: float = MERGE_RADIUS) -> np.ndarray:
    """Indices of at most ``limit`` points, pairwise farther than ``radius``,
    chosen by farthest-point selection from the first (deterministic)."""
    if len(points) == 0:
        return np.zeros(0, int)
    chosen = [0]
    dist = np.linalg.norm(points - points[0], axis=1)
    while len(chosen) < limit:
        k = int(np.argmax(dist))
        if dist[k] <= radius:
            break
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(points - points[k], axis=1))
    return np.array(chosen, int)


def _arrays(items: list[dict]) -> _Arrays:
    """(points, normals, links, radius, region) of the items of :meth:`HandContacts.to_json`."""
    return (np.array([c["point"] for c in items], float).reshape(-1, 3),
            np.array([c["normal"] for c in items], float).reshape(-1, 3),
            tuple(c["link"] for c in items),
            np.array([c.get("radius", np.nan) for c in items], float),
            np.array([c.get("region", -1) for c in items], int))


def grasp_quality(contacts: HandContacts, hand: HandSpec, obj: PreparedObject, cone_edges: int,
                  volume: bool = True) -> quality.Quality:
    """Ferrari-Canny epsilon (L1), GWS volume (0 unless ``volume``) and force
    closure of contacts; each contact's model (point, soft, frictionless) as
    :func:`contact_models` says."""
    from planner import quality

    models, torsion = contact_models(contacts, hand, obj.friction)
    args = dict(mu=obj.friction, center=obj.com, torque_scale=obj.torque_scale, cone_edges=cone_edges, model=models,
                torsion=torsion)
    if volume:
        return quality.evaluate(contacts.points, contacts.frames, **args)  # type: ignore[arg-type]
    eps = quality.epsilon(contacts.points, contacts.frames, **args)  # type: ignore[arg-type]
    return quality.Quality(eps, 0.0, eps > 0.0)
