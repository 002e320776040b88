"""The hand as a shake trial drives it: which joints close and how fast,
which links make up each finger, and how much open travel a grasp leaves
(the finger DOFs and the open travel are the hand spec's, as closing and
the measures have them).

Pure functions of the hand spec, the grasp and (for revolute joints) the
joint axes at the grasp's closed configuration; frames are the hand frame,
lengths in metres, angles in radians.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from planner.geometry.frames import rows_cross
from planner.record.grasp import Grasp
from planner.specs.hands import HandSpec
from planner.specs.preshapes import load_preshapes
from planner.validation.tolerances import DEFAULT_LEVER


def synergy(hand: HandSpec, preshape: str) -> dict[str, float]:
    """The closing synergy {driven joint: rate} of the grasp's preshape (its
    override of the hand's); empty for a preshape the hand does not have
    (every driven joint then closes at its hand.toml rate)."""
    shapes = {p.name: p for p in load_preshapes(hand)}
    return dict(shapes[preshape].close) if preshape in shapes else {}


def closing_rates(hand: HandSpec, preshape: str, close: Mapping[str, float] | None = None) -> dict[str, float]:
    """Closing rate of every finger joint [rad or m per unit of closing] for
    the grasp's preshape (:meth:`~planner.specs.hands.HandSpec.joint_rates`);
    ``close``: its :func:`synergy` if already at hand (None: read)."""
    return hand.joint_rates(synergy(hand, preshape) if close is None else close)


def fingers(hand: HandSpec, rates: Mapping[str, float]) -> tuple[frozenset[str], ...]:
    """The fingers: the links each closing joint moves, a chain nested in
    another merged into the outer one (a Barrett finger's proximal and distal
    links are one finger; the Panda's two mimic-coupled fingers are two)."""
    chains = {frozenset(j.moves) for j in hand.joints if rates.get(j.name, 0.0) != 0.0 and j.moves}
    return tuple(sorted((c for c in chains if not any(c < other for other in chains)), key=sorted))


def levers(hand: HandSpec, grasp: Grasp, axes: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, float]:
    """[m] for each revolute joint that moves a link with a planned contact:
    the largest distance from its axis (``axes[name]`` = (point, unit
    direction), hand frame, closed configuration) to those contacts.

    Every (joint, contact) pair at once: each row's arm is the one a joint
    at a time gave (``np.cross``'s products, the norm's sum of squares in its
    order), the largest per joint the same, to the bit."""
    to_hand = np.linalg.inv(np.asarray(grasp.pose, float))
    points = grasp.contacts.points @ to_hand[:3, :3].T + to_hand[:3, 3]
    links = grasp.contacts.links
    names: list[str] = []
    rows: list[int] = []
    starts: list[int] = []
    ends: list[np.ndarray] = []
    for j in hand.joints:
        if j.kind != "revolute" or j.name not in axes or not len(points):
            continue
        on = [i for i, link in enumerate(links) if link in j.moves]
        if on:
            names.append(j.name)
            starts.append(len(rows))
            rows += on
            ends.append(np.broadcast_to(np.concatenate(axes[j.name]), (len(on), 6)))
    if not names:
        return {}
    at = np.concatenate(ends) if len(ends) > 1 else ends[0]
    arm = rows_cross(points[rows] - at[:, :3], at[:, 3:])  # np.cross's, to the bit
    return dict(zip(names, np.maximum.reduceat(np.linalg.norm(arm, axis=1), starts).tolist()))


def clearance(hand: HandSpec, grasp: Grasp, axes: Mapping[str, tuple[np.ndarray, np.ndarray]],
              close: Mapping[str, float] | None = None) -> float:
    """[m] the smallest open travel left at the contacts of a touching finger:
    the sweep's open margin (:meth:`~planner.specs.hands.HandSpec.open_travel`)
    of the planned (closed) configuration, ``axes`` = (point, unit direction)
    of every finger joint's axis there, hand frame; ``close``: the grasp's
    :func:`synergy` if already at hand (None: read). Near 0, the open hand
    could not have been put around the object (no squeeze travel). ``inf``
    if nothing touches."""
    to_hand = np.linalg.inv(np.asarray(grasp.pose, float))
    points = grasp.contacts.points @ to_hand[:3, :3].T + to_hand[:3, 3]
    close = synergy(hand, grasp.preshape) if close is None else close
    return hand.open_travel(close, grasp.closed_joints, points, grasp.contacts.links, axes)


def start_joints(hand: HandSpec, grasp: Grasp, rates: Mapping[str, float], lever: Mapping[str, float],
                 gap: float) -> dict[str, float]:
    """Every finger joint a ``gap`` [m] (at the contact; revolute: gap / lever)
    short of the planned grasp towards open, within limits; mimics follow
    their master (the gear coupling holds from the first step)."""
    driven = {}
    for j in hand.driven:
        closed = float(grasp.closed_joints.get(j.name, j.lower))
        rate = rates.get(j.name, 0.0)
        if rate == 0.0:
            driven[j.name] = closed
            continue
        step = gap if j.kind == "prismatic" else gap / lever.get(j.name, DEFAULT_LEVER)
        driven[j.name] = float(np.clip(closed - np.sign(rate) * step, j.lower, j.upper))
    return hand.full_configuration(driven)


def open_start(hand: HandSpec, grasp: Grasp, rates: Mapping[str, float]) -> dict[str, float]:
    """Every finger joint where the MuJoCo trial starts: the grasp's open preshape;
    a driven joint it lacks at its open limit if it closes (``rates``, the
    preshape's closing rates), else as planned; a mimic it lacks follows its
    master (the antipodal sweep stores only the driven joints of the opening
    it fitted to the chord: the Panda's second finger once started 4 cm open
    beside a first one fitted to 1.4 cm, into a neighbouring lobe of the
    object, and the gearing snapped it back)."""
    driven = {}
    for j in hand.driven:
        if j.name in grasp.open_joints:
            driven[j.name] = float(grasp.open_joints[j.name])
        elif rates.get(j.name, 0.0) != 0.0:
            driven[j.name] = j.lower if rates[j.name] > 0 else j.upper
        else:
            driven[j.name] = float(grasp.closed_joints.get(j.name, j.lower))
    out = hand.full_configuration(driven)
    return {**out, **{name: float(v) for name, v in grasp.open_joints.items() if name in out}}


def inertia(hand: HandSpec) -> dict[str, dict[str, list[float]]]:
    """The links' moments of inertia a hand's trials replace (``link_inertia``), as their stored settings record
    them: a hand's verdicts made before it replaced them (or with others) are of another trial; {} for a hand
    that replaces none (its settings as before)."""
    return {"link_inertia": {k: list(v) for k, v in sorted(hand.link_inertia.items())}} if hand.link_inertia else {}
