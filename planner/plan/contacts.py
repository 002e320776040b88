"""Contacts read from the simulator: a batch in the object frame.

A contact is a point on the object surface, the inward unit normal there and
the hand link that touches it; the contact *model* (point, soft,
frictionless) belongs to the link and is looked up in the hand spec when the
grasp is scored. The stored form is JSON text ``[{point, normal, link}]``
(points and normals rounded to 1 um / 1e-6). A batch read back from the
database keeps that text and decodes it only on first use, so a grasp that is
only exported never pays for decoding its contacts.
"""

from __future__ import annotations

import json

import numpy as np

from planner.geometry.frames import contact_frames
from planner.plan.tolerances import MAX_PER_LINK, MERGE_RADIUS

#: Decimals kept of points [m] and normals in the stored form (1 um).
STORED_DIGITS = 6


class HandContacts:
    """n contacts between the hand and the object (immutable).

    Attributes:
        points: (n, 3) contact points c_i on the object surface [m], object frame.
        normals: (n, 3) unit normals n_i pointing into the object, object frame.
        links: (n,) names of the hand links that touch.
    """

    __slots__ = ("_arrays", "_text", "_count", "_touching")

    def __init__(self, points: np.ndarray, normals: np.ndarray, links: tuple[str, ...]) -> None:
        n = len(points)
        if points.shape != (n, 3) or normals.shape != (n, 3):
            raise ValueError("HandContacts.points and .normals must be (n, 3)")
        if len(links) != n:
            raise ValueError("HandContacts: one link per contact")
        self._arrays: tuple[np.ndarray, np.ndarray, tuple[str, ...]] | None = (points, normals, tuple(links))
        self._text: str | None = None
        self._count = n
        self._touching = len(set(links))

    @classmethod
    def stored(cls, text: str, count: int, touching: int) -> HandContacts:
        """Contacts as the database holds them: the JSON text and its two counts."""
        out = cls.__new__(cls)
        out._arrays, out._text, out._count, out._touching = None, text, count, touching
        return out

    def _decoded(self) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        if self._arrays is None:
            items = json.loads(self._text or "[]")
            self._arrays = (np.array([c["point"] for c in items], float).reshape(-1, 3),
                            np.array([c["normal"] for c in items], float).reshape(-1, 3),
                            tuple(c["link"] for c in items))
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

    def __len__(self) -> int:
        return self._count

    @property
    def touching(self) -> int:
        """How many distinct hand links touch the object."""
        return self._touching

    @property
    def frames(self) -> np.ndarray:
        """(n, 3, 3) contact frames R_i with columns (n_i, l_i, o_i)."""
        return contact_frames(self.normals)

    def to_json(self) -> list[dict]:
        """``[{point, normal, link}]``, rounded as stored."""
        return [{"point": [round(float(v), STORED_DIGITS) for v in p],
                 "normal": [round(float(v), STORED_DIGITS) for v in n], "link": link}
                for p, n, link in zip(self.points, self.normals, self.links)]

    def json_text(self) -> str:
        """The stored form: compact JSON text of :meth:`to_json`."""
        if self._text is None:
            self._text = json.dumps(self.to_json(), separators=(",", ":"))
        return self._text


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
