"""Contacts read from the simulator, as a batch in the object frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.geometry.frames import tangent_basis

#: Contact points of one link closer than this [m] are one contact.
MERGE_RADIUS = 0.002
#: At most this many contacts per link (spread over its contact patch).
MAX_PER_LINK = 4


@dataclass(frozen=True)
class HandContacts:
    """n contacts between the hand and the object.

    Attributes:
        points: (n, 3) contact points c_i on the object surface [m], object frame.
        normals: (n, 3) unit normals n_i pointing into the object.
        links: (n,) hand link names.
        models: (n,) contact model per contact (``point``, ``soft``, ``frictionless``).
        torsion: (n,) torsion coefficient [m] per contact (soft contacts).
    """

    points: np.ndarray
    normals: np.ndarray
    links: tuple[str, ...]
    models: tuple[str, ...]
    torsion: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.points)
        if self.points.shape != (n, 3) or self.normals.shape != (n, 3):
            raise ValueError("HandContacts.points and .normals must be (n, 3)")
        if not len(self.links) == len(self.models) == len(self.torsion) == n:
            raise ValueError("HandContacts: one link, model and torsion per contact")

    def __len__(self) -> int:
        return len(self.points)

    @property
    def frames(self) -> np.ndarray:
        """(n, 3, 3) contact frames R_i with columns (n_i, l_i, o_i)."""
        out = np.empty((len(self), 3, 3))
        for i, n in enumerate(self.normals):
            l_vec, o_vec = tangent_basis(n)
            out[i] = np.column_stack([n, l_vec, o_vec])
        return out

    @property
    def touching_links(self) -> tuple[str, ...]:
        return tuple(sorted(set(self.links)))

    def to_json(self) -> list[dict]:
        return [{"point": [round(float(v), 6) for v in p], "normal": [round(float(v), 6) for v in n], "link": link}
                for p, n, link in zip(self.points, self.normals, self.links)]


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
