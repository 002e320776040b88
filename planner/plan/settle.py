"""The settled epsilon: the grasp the fingers settle into (issue 15).

Closing in the sweep is kinematic: the object stays put while each finger
stops where it touches. A hand whose fingers close one after another (the
Barrett) pushes the free object before the last finger arrives, often by
more than a centimetre, so the planned contacts are not the ones that hold
it. For hands with ``settle = true`` in ``hand.toml`` the sweep therefore
closes every grasp once more, dynamically: the first two phases of the shake
test (:func:`planner.validation.shake.settled_contacts`: the fingers start
just short of the grasp and close under their motors on the free object,
which then comes to rest; no load, no shake), one grasp per PyBullet world so
that the result does not depend on how the grasps are grouped. The contacts
it settles into (PyBullet's points, each link's contact model) are scored by
the same Ferrari-Canny epsilon as the planned ones.

Each grasp settles as the database stores it (:meth:`Grasp.as_stored
<planner.record.grasp.Grasp.as_stored>`: the pose to 0.1 um, the contacts to
1 um). The settle is chaotic: moving the pose by 1 nm gives another settled
epsilon on nearly every grasp (bench/RESULTS.md, 2026-12-04), so a settle of
the unrounded grasp could not be reproduced from the stored one; of the
stored one it is, to the last bit.

Measured on the tuning objects (bench/RESULTS.md): for the Barrett the
settled epsilon predicts the shake test far better than the planned epsilon;
for the Panda, whose jaws close together, it does worse, so the Panda does
not settle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from planner.errors import PlannerError
from planner.geometry.solid import PreparedObject
from planner.plan.contacts import HandContacts, grasp_quality
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec
from planner.validation.settings import settle_settings
from planner.validation.shake import ShakeSettings, settled_contacts


def epsilon_of(contacts: HandContacts, hand: HandSpec, obj: PreparedObject, cone_edges: int = 8) -> float:
    """Epsilon of settled contacts; 0 for none or for contacts that cannot be analysed."""
    if len(contacts) == 0:
        return 0.0
    try:
        return grasp_quality(contacts, hand, obj, cone_edges, False).epsilon
    except PlannerError:
        return 0.0


def settled_epsilons(hand: HandSpec, obj: PreparedObject, grasps: Sequence[Grasp], cone_edges: int = 8,
                     settings: ShakeSettings | None = None) -> np.ndarray:
    """(n,) epsilon of the contacts each grasp, as stored, settles into; 0
    where the fingers lost the object, the trial is flagged, or the contacts
    cannot be analysed. ``settings``: the settle's trial; None: the hand's
    (:func:`~planner.validation.settings.settle_settings`)."""
    s = settle_settings(hand.settle_dynamics) if settings is None else replace(settings, batch=1)
    stored = [g.as_stored() for g in grasps]
    return np.array([epsilon_of(c, hand, obj, cone_edges) for c in settled_contacts(hand, obj, stored, s)], float)


def with_settled(hand: HandSpec, obj: PreparedObject, grasps: Sequence[Grasp], cone_edges: int = 8,
                 settings: ShakeSettings | None = None, only_force_closure: bool = True) -> list[Grasp]:
    """The grasps with ``measures.settled_epsilon`` filled in (grasps without
    measures are returned unchanged); ``settings``: the trial (the sweep's
    :attr:`~planner.plan.sweep.SweepSettings.trial`; None: the hand's).

    ``only_force_closure`` (the sweep's choice, issue 24): only grasps whose
    planned contacts are force closure are settled; the others keep
    ``settled_epsilon`` None (not measured, neutral in the ranking rule).
    Every force-closure grasp ranks above every other
    (:mod:`planner.db.ranking`), so a settled epsilon can only reorder
    grasps among those that are not force closure: the force-closure grasps,
    their scores and ranks are the same as when every grasp settles, and so
    is any top-K of an object with at least K of them; the settle, a third
    of the Barrett's sweep, is spent on the grasps that can reach the top."""
    measured = [g for g in grasps if g.measures is not None and (g.force_closure or not only_force_closure)]
    values = dict(zip((id(g) for g in measured), settled_epsilons(hand, obj, measured, cone_edges, settings)))
    return [g if id(g) not in values else replace(g, measures=replace(g.measures,  # type: ignore[arg-type]
                                                                       settled_epsilon=float(values[id(g)])))
            for g in grasps]
