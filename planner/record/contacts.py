"""The contacts record: a batch of contacts between the hand and the object,
object frame.

A contact is a point on the object surface, the inward unit normal there,
the hand link that touches it and, for contacts read as patches
(:mod:`planner.plan.patches`), the patch region it belongs to and that
region's radius [m] when it is one soft-finger contact (0: a point contact
at a corner of a larger region). The stored form is JSON text
``[{point, normal, link[, radius, region]}]`` (points, normals and radii
rounded to 1 um / 1e-6). A batch read back from the database keeps that text
and decodes it only on first use, so a grasp that is only exported never
pays for decoding its contacts. How the contacts are modelled and scored is
planning's (:mod:`planner.plan.contacts`).
"""

from __future__ import annotations

import json

import numpy as np

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

    __slots__ = ("_arrays", "_text", "_count", "_touching", "_frames")

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
        self._frames: np.ndarray | None = None

    @classmethod
    def stored(cls, text: str, count: int, touching: int) -> HandContacts:
        """Contacts as the database holds them: the JSON text and its two counts."""
        out = cls.__new__(cls)
        out._arrays, out._text, out._count, out._touching, out._frames = None, text, count, touching, None
        return out

    def __getstate__(self) -> tuple[None, dict]:
        """Pickled without the frames (:attr:`frames` makes them again where asked): a worker's grasps travel
        to the writer without (n, 3, 3) floats each."""
        return None, {"_arrays": self._arrays, "_text": self._text, "_count": self._count,
                      "_touching": self._touching, "_frames": None}

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
    def count(self) -> int:
        """How many contacts (``len``; the stored ``n_contacts``)."""
        return self._count

    @property
    def touching(self) -> int:
        """How many distinct hand links touch the object."""
        return self._touching

    @property
    def frames(self) -> np.ndarray:
        """(n, 3, 3) contact frames R_i with columns (n_i, l_i, o_i), read-only: made once, on first use (a
        sweep's grasp reads them for its epsilon, its weight resistance and its squeeze)."""
        if self._frames is None:
            from planner.geometry.frames import contact_frames  # scipy: not needed to read stored contacts

            frames = contact_frames(self.normals)
            frames.flags.writeable = False
            self._frames = frames
        return self._frames

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


def _arrays(items: list[dict]) -> _Arrays:
    """(points, normals, links, radius, region) of the items of :meth:`HandContacts.to_json`."""
    return (np.array([c["point"] for c in items], float).reshape(-1, 3),
            np.array([c["normal"] for c in items], float).reshape(-1, 3),
            tuple(c["link"] for c in items),
            np.array([c.get("radius", np.nan) for c in items], float),
            np.array([c.get("region", -1) for c in items], int))
