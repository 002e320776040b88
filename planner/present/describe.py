"""A grasp as ``grasp best`` prints it: the frames people use, units on everything.

Two points of the hand are given, both as positions and with the hand's
orientation: the **hand base** (the hand's ``root_link`` frame, the pose the
database stores: ACRONYM's and MoveIt's "grasp pose" of the Panda is this
frame) and the **tool centre point** (``tcp`` of hand.toml: the point between
the fingers that the approach aims at). The approach direction is the hand's
approach axis (``approach`` of hand.toml) in the same frame. Every pose is in
the object frame (the frame of the scaled mesh file); with an object pose,
in the world frame too. Quaternions are (x, y, z, w).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from planner.record.grasp import Grasp
from planner.specs.hands import HandFrame


@dataclass(frozen=True)
class Frames:
    """Where a grasp puts the hand, in one frame.

    Attributes:
        frame: ``object`` or ``world``.
        base: (3,) [m] the hand base (``root_link``) position.
        tcp: (3,) [m] the tool centre point.
        quaternion: (4,) the hand's orientation, x y z w.
        approach: (3,) unit, the direction the hand moves in to grasp.
    """

    frame: str
    base: np.ndarray
    tcp: np.ndarray
    quaternion: np.ndarray
    approach: np.ndarray

    def to_json(self) -> dict:
        return {"frame": self.frame, "hand_base_m": self.base.tolist(), "tcp_m": self.tcp.tolist(),
                "quaternion_xyzw": self.quaternion.tolist(), "approach": self.approach.tolist()}


def frames(grasp: Grasp, hand: HandFrame, world: np.ndarray | None = None) -> Frames:
    """The grasp's frames in the object frame, or in the world when
    ``world`` (4, 4), the object's pose in the world, is given."""
    pose = np.asarray(grasp.pose, float) if world is None else np.asarray(world, float) @ np.asarray(grasp.pose)
    rotation = pose[:3, :3]
    return Frames("object" if world is None else "world", pose[:3, 3].copy(), rotation @ hand.tcp + pose[:3, 3],
                  quaternion_xyzw(rotation), rotation @ hand.approach)


def quaternion_xyzw(rotation: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (x, y, z, w), w >= 0, of a (3, 3) rotation matrix.

    Written with numpy (Shepperd's method: the largest of the four squares
    first, for accuracy) rather than taken from scipy, whose import is most
    of ``grasp best``'s start-up; tests check it against scipy's."""
    r = np.asarray(rotation, float)
    trace = np.trace(r)
    squares = np.array([1 + 2 * r[0, 0] - trace, 1 + 2 * r[1, 1] - trace, 1 + 2 * r[2, 2] - trace, 1 + trace])
    k = int(np.argmax(squares))
    q = np.empty(4)
    q[k] = np.sqrt(squares[k]) / 2
    if k == 3:
        q[:3] = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / (4 * q[3])
    else:
        i, j, m = k, (k + 1) % 3, (k + 2) % 3
        q[j] = (r[j, i] + r[i, j]) / (4 * q[i])
        q[m] = (r[m, i] + r[i, m]) / (4 * q[i])
        q[3] = (r[m, j] - r[j, m]) / (4 * q[i])
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def _xyz(v: np.ndarray, digits: int = 3) -> str:
    return "(" + ", ".join(f"{x:.{digits}f}" for x in v) + ")"


def frame_lines(f: Frames, hand: HandFrame) -> list[str]:
    return [f"{f.frame} frame: hand base ({hand.root_link}) at {_xyz(f.base)} m, tool centre point at "
            f"{_xyz(f.tcp)} m, orientation xyzw {_xyz(f.quaternion, 4)}, approach direction {_xyz(f.approach)}"]


def describe(grasp: Grasp, hand: HandFrame, world: np.ndarray | None = None,
             arm: Mapping[str, Mapping[str, float]] | None = None) -> list[str]:
    """The lines ``grasp best`` prints for one grasp (with ``world`` and the
    ``arm`` joint solutions by stage when it was reached at an object pose)."""
    g, m = grasp, grasp.measures
    score = "n/a" if g.score is None else f"{g.score:.4f}"
    reach = "not computed" if g.reachability is None else f"{g.reachability:.2f} of table placements"
    width = "n/a (not a parallel jaw)" if g.width is None else f"{g.width * 1000:.1f} mm"
    volume = f"{g.volume:.3g}" if g.volume else "0 (computed only with --volume, for force closure)"
    head = f"#{g.rank} {g.object}/{g.hand} preshape {g.preshape}: score {score} (ranking rule, higher is better)"
    lines = [head, *(f"    {line}" for line in frame_lines(frames(g, hand), hand))]
    if world is not None:
        lines += [f"    {line}" for line in frame_lines(frames(g, hand, world), hand)]
    lines.append(f"    finger width {width}; epsilon {g.epsilon:.4f} (Ferrari-Canny L1, "
                 f"{'force closure' if g.force_closure else 'NOT force closure'}); GWS volume {volume}; "
                 f"{len(g.contacts)} contacts; reachability {reach}")
    if m is not None:
        settled = "" if m.settled_epsilon is None else f"; settled epsilon {m.settled_epsilon:.4f}"
        lines.append(f"    holds {m.resist_worst:.1f} g in the worst direction (mean {m.resist_mean:.1f} g); push "
                     f"{m.push:.2f} (1 = pads square on); feasibility {','.join(m.reasons) or 'ok'}{settled}")
    if g.validation is not None:
        trial = g.validation
        verdict = "held" if trial.success else "dropped"
        lines.append(f"    shake trial: {verdict} ({trial.reason or 'no reason stored'})")
    for stage, joints in (arm or {}).items():
        lines.append(f"    arm at {stage} [rad]: " + ", ".join(f"{k} {v:.4f}" for k, v in joints.items()))
    return lines
