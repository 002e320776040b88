"""How contacts are modelled and scored. The contacts themselves (points,
normals, links, patch regions and radii, object frame) are the record's
:class:`~planner.record.contacts.HandContacts`.

The contact *model* follows (:func:`contact_models`): frictionless if the
link's model (hand spec) is frictionless; else soft with torsion 2/3 mu
radius (uniform pressure on a disc), at most the link's own ``mu *
torsion_radius`` (the one number the shake trial gives PyBullet as the pad's
spinning friction), when the radius is positive and the link is soft; else
point with friction. Contacts without a radius (the legacy point reading)
take their link's model and torsion from the hand spec.

:func:`grasp_quality` scores a batch: Ferrari-Canny epsilon (and GWS
volume) with each contact's model; :func:`spread` picks the contacts kept
of one link.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.plan.tolerances import MAX_PER_LINK, MERGE_RADIUS, SOFT_TORSION
from planner.record.contacts import HandContacts
from planner.specs.hands import HandSpec

if TYPE_CHECKING:  # scipy and trimesh: loaded where used, so that reading stored contacts needs neither
    from planner import quality
    from planner.geometry.solid import PreparedObject

#: HandContacts stays importable from here for planning modules that read
#: contacts beside these functions (closing); the type is the record's.
__all__ = ["HandContacts", "contact_models", "grasp_quality", "spread"]


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
