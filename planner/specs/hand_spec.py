"""The hand's description as the planner holds it (read from
``hands/<name>/hand.toml`` and its URDF by :mod:`planner.specs.hands`):
finger joints (:class:`JointSpec`), contact models (:class:`ContactModel`),
finger motors (:class:`Actuators`), the arm (:class:`ArmSpec`) and the hand
(:class:`HandSpec`), which knows its fingers: finger DOFs with mimics,
centring and breakaway (:class:`FingerDof`), the parallel jaw, contact
velocities and the travel left to a joint limit.

Frames: the *hand frame* is the frame of ``root_link``; grasp poses are the
pose of that frame in the object frame. ``approach`` is the unit vector (in
the hand frame) along which the hand moves onto the object, ``tcp`` the tool
centre point [m] that the approach ray passes through.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Protocol, TypeVar

import numpy as np

from planner.errors import UnknownNameError
from planner.record.measures import LOCAL_CELLS  # noqa: F401 - the grid's size, declared with the measure

#: [rad or m] a mimic joint further than this from its coupling broke away.
BREAKAWAY_TOL = 1e-6
#: [m per unit closing] contact motion slower than this does not move.
STILL = 1e-9


@dataclass(frozen=True)
class JointSpec:
    """One finger joint.

    ``close`` is the synergy coefficient: how fast this joint moves (rad or m
    per unit of closing) when the hand closes; 0 for joints that hold still.
    A ``mimic`` joint follows ``q = multiplier * q[mimic] + offset``.
    ``moves`` lists every link this joint (or a joint mimicking it) moves.
    """

    name: str
    kind: str  # "revolute" or "prismatic"
    lower: float
    upper: float
    close: float
    mimic: str | None
    multiplier: float
    offset: float
    child: str
    moves: tuple[str, ...]
    breakaway: bool = False  # driven joint whose mimics close on alone once it is stopped (BH8 TorqueSwitch)


@dataclass(frozen=True)
class ContactModel:
    """Contact model of one link: ``point``, ``soft`` or frictionless.

    A soft link (a pad) also resists a moment about the contact normal:
    Coulomb friction over its contact patch gives at most
    ``mu * torsion_radius * normal force``, ``torsion_radius`` [m] being the
    patch's mean distance from its centre (uniform pressure on a disc of
    radius a: 2a/3). This one number per link is what the dynamic trial gives
    PyBullet (a link's spinning friction, which Bullet multiplies by the
    object's mu) and what the analytic soft-finger model uses
    (:meth:`torsion`), so label and score model the same pad.
    """

    model: str
    torsion_radius: float = 0.0  # [m]

    def torsion(self, mu: float) -> float:
        """[m] the largest moment about the normal per newton of normal force
        at friction ``mu`` (0 unless soft)."""
        return mu * self.torsion_radius if self.model == "soft" else 0.0


@dataclass(frozen=True)
class SettleDynamics:
    """The settle's own dynamic closing (``[settle_dynamics]`` of hand.toml):
    ``steps_per_second`` [1/s], ``close_time`` [s] the fingers close under
    their motors, ``rest_time`` [s] the object then rests before the contacts
    are read. A hand without it settles with the shake trial's
    (:class:`planner.validation.settings.ShakeSettings`)."""

    steps_per_second: float
    close_time: float
    rest_time: float




#: [m] a turned grid point this close to another is that point.
GRID_TOL = 1e-9


@dataclass(frozen=True)
class LocalGrid:
    """Where the measure ``local_sdf`` reads the object around a grasp
    (``[local_sdf]`` of hand.toml, :mod:`planner.plan.local_sdf`): the box
    ``low``..``high`` (3,) [m] in the hand frame, ``counts`` (3,) points per
    axis (their product: :data:`LOCAL_CELLS`), spread evenly
    from face to face."""

    low: tuple[float, float, float]
    high: tuple[float, float, float]
    counts: tuple[int, int, int]

    def points(self) -> np.ndarray:
        """(CELLS, 3) [m] the grid's points, hand frame, x slowest and z fastest."""
        axes = [np.linspace(a, b, n) if n > 1 else np.array([(a + b) / 2]) for a, b, n in
                zip(self.low, self.high, self.counts)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


@dataclass(frozen=True)
class Actuators:
    """The finger motors, from published specifications (``[dynamics]``).

    One motor per driven joint; its mimics are geared to it (a Panda motor
    drives both fingers, a Barrett motor one finger's two links). ``effort``
    [N or N m] is the motor's continuous force or torque limit on the driven
    joint (the synergy's generalised force, shared with the mimics through the
    gearing); ``closing_speed`` [m/s or rad/s] of the driven joint;
    ``backdrivable`` False for worm-gear fingers an external load cannot open;
    ``source`` says where the numbers come from.
    """

    effort: float
    closing_speed: float
    backdrivable: bool
    source: str


class _Posture(Protocol):
    """What :meth:`HandSpec.widest` reads of a preshape (:class:`planner.specs.preshapes.Preshape`)."""

    @property
    def joints(self) -> dict[str, float]: ...

    @property
    def close(self) -> dict[str, float]: ...


P = TypeVar("P", bound=_Posture)


@dataclass(frozen=True)
class FingerDof:
    """One finger DOF as the hand closes it.

    ``rates`` {joint: dq per unit of closing} [rad or m]: the driven joint
    ``driven`` and the mimics that move with it (the mimics at the driven
    joint's rate times their multiplier); ``after``: for a ``breakaway``
    driven joint, the rates that close on alone once the links only the
    driven joint moves are stopped (its mimics); None otherwise.
    """

    driven: str
    rates: dict[str, float]
    after: dict[str, float] | None = None


@dataclass(frozen=True)
class ArmSpec:
    """The arm that carries the hand (reachability), located at run time."""

    urdf: Path
    ee_link: str
    mount: np.ndarray  # (4, 4) hand frame in the arm's end-effector frame


@dataclass(frozen=True)
class HandSpec:
    name: str
    folder: Path
    description: str
    urdf: Path  # the (cut down) URDF PyBullet and yourdfpy load
    root_link: str
    approach: np.ndarray  # (3,) unit, hand frame
    tcp: np.ndarray  # (3,) [m], hand frame
    joints: tuple[JointSpec, ...]
    contact_links: tuple[str, ...]
    contacts: dict[str, ContactModel]
    centering: bool  # a self-centring parallel jaw: re-centre after closing
    distance_offset: float  # [m] PyBullet's collision margins: true gap = reported + offset
    roll_symmetry: int  # the hand looks the same after 2 pi / roll_symmetry about the approach
    links: tuple[str, ...]
    arm: ArmSpec | None
    export_frame: np.ndarray  # (4, 4) dataset gripper frame in the hand frame (ACRONYM convention)
    actuators: Actuators  # the finger motors: weight resistance, dynamic trials
    sampler: str = "surface"  # the sweep's approach sampler unless the user picks one
    settle: bool = False  # the sweep measures the settled epsilon (a dynamic closing per grasp) unless told not to
    settle_dynamics: SettleDynamics | None = None  # the settle's steps and times; None: the shake trial's
    local_grid: LocalGrid | None = None  # where local_sdf reads the object; None: not measured for this hand
    #: {link: (3,) [kg m^2]} principal moments of inertia, about the URDF's centre of mass in its inertial axes,
    #: replacing the URDF's (a placeholder) in both dynamic trials ([dynamics.link_inertia]); empty: the URDF's
    link_inertia: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    #: the two links (pads) the grasp's width is the gap between, at its closed joints
    #: (:mod:`planner.plan.width`); None: a self-centring jaw's opening, or no width
    width_links: tuple[str, str] | None = None

    @cached_property
    def cell_turns(self) -> tuple[tuple[int, ...], ...]:
        """The hand turned onto itself reads the same object in another
        order of its ``local_sdf`` cells: for each turn by 2 pi j /
        ``roll_symmetry`` (j >= 1) about the approach axis through the
        hand frame's origin that maps the grid onto itself, the index of the
        point each grid point lands on (the turned hand's cells are the
        cells in this order; the Panda's half turn swaps its fingers: the
        same grasp). Empty: no grid, no symmetry, or a grid the turns do
        not map onto itself."""
        if self.local_grid is None:
            return ()
        points = self.local_grid.points()
        k = np.asarray(self.approach, float)
        cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        out = []
        for j in range(1, self.roll_symmetry):
            angle = 2.0 * np.pi * j / self.roll_symmetry  # Rodrigues' rotation about the unit axis k
            turn = np.eye(3) + np.sin(angle) * cross + (1.0 - np.cos(angle)) * cross @ cross
            gaps = np.linalg.norm((points @ turn.T)[:, None, :] - points[None, :, :], axis=2)
            order = np.argmin(gaps, axis=1)
            if np.all(gaps[np.arange(len(points)), order] < GRID_TOL) and len(set(order.tolist())) == len(points):
                out.append(tuple(int(i) for i in order))
        return tuple(out)

    def joint(self, name: str) -> JointSpec:
        found = self._joint_map.get(name)
        if found is None:
            raise UnknownNameError("joint", name, [j.name for j in self.joints])
        return found

    @cached_property
    def _joint_map(self) -> dict[str, JointSpec]:
        """Joints by name (closing looks joints up in its inner loop)."""
        return {j.name: j for j in self.joints}

    @property
    def driven(self) -> tuple[JointSpec, ...]:
        """Joints that are not mimics: the hand's independent finger DOFs."""
        return tuple(j for j in self.joints if j.mimic is None)

    def full_configuration(self, driven: dict[str, float]) -> dict[str, float]:
        """Joint values of every finger joint from the driven ones (mimics follow)."""
        values = {j.name: float(driven.get(j.name, j.lower)) for j in self.driven}
        for j in self.joints:
            if j.mimic is not None:
                values[j.name] = j.multiplier * values[j.mimic] + j.offset
        return values

    def posture(self, joints: Mapping[str, float]) -> dict[str, float]:
        """Every finger joint's value [rad or m] of a stored configuration:
        the stored ones, and the mimics it leaves out at their coupling (the
        antipodal sweep stores only the driven joints of the opening it fits;
        a broken-away mimic is stored)."""
        return {**self.full_configuration(dict(joints)), **{k: float(v) for k, v in joints.items()}}

    # -- the fingers: what closing, the measures, the trial and the exports share --

    @cached_property
    def fingers(self) -> tuple[tuple[str, ...], ...]:
        """The hand's fingers as link chains, whatever the preshape: the links
        each joint moves, a chain nested in another merged into the outer one
        (a Barrett finger's spread, proximal and distal links are one finger;
        the Panda's two mimic-coupled fingers are two). Sorted, so that finger
        order does not depend on the joints' order."""
        chains = {frozenset(j.moves) for j in self.joints if j.moves}
        return tuple(sorted(tuple(sorted(c)) for c in chains if not any(c < other for other in chains)))
    def coupling(self, name: str) -> dict[str, float]:
        """The joints driven joint ``name`` moves, dq per unit of it: itself
        (1) and each joint mimicking it (its multiplier)."""
        return {name: 1.0, **{m.name: m.multiplier for m in self.joints if m.mimic == name}}

    def joint_rates(self, close: Mapping[str, float]) -> dict[str, float]:
        """Closing rate [rad or m per unit of closing] of every finger joint
        under the synergy ``close`` {driven joint: rate} (a driven joint left
        out closes at its hand.toml rate); a mimic closes at its master's rate
        times its multiplier; 0: the joint holds."""
        rates = {j.name: float(close.get(j.name, j.close)) for j in self.driven}
        for j in self.joints:
            if j.mimic is not None:
                rates[j.name] = rates[j.mimic] * j.multiplier
        return rates

    def broken_away(self, closed: Mapping[str, float]) -> set[str]:
        """Breakaway driven joints whose mimics closed on past the coupling at ``closed``."""
        out = set()
        for j in self.joints:
            if j.mimic is not None and self.joint(j.mimic).breakaway and j.name in closed and j.mimic in closed:
                if abs(closed[j.name] - (j.multiplier * closed[j.mimic] + j.offset)) > BREAKAWAY_TOL:
                    out.add(j.mimic)
        return out

    def closing_dofs(self, close: Mapping[str, float], closed: Mapping[str, float] | None = None
                     ) -> tuple[FingerDof, ...]:
        """The finger DOFs of the synergy ``close`` (see :meth:`joint_rates`):
        every driven joint that closes, with its mimics; a self-centring jaw's
        fingers apart (each stops on its own contact). With ``closed`` (a
        closed configuration), the DOFs as they ended: a finger that broke
        away closes its mimics alone."""
        broken = set() if closed is None else self.broken_away(closed)
        out = []
        for joint in self.driven:
            rate = close.get(joint.name, joint.close)
            if rate == 0.0:
                continue
            rates = {name: rate * c for name, c in self.coupling(joint.name).items()}
            mimics = {name: r for name, r in rates.items() if name != joint.name}
            if self.centering:
                groups = [{name: r} for name, r in rates.items()]
            elif joint.name in broken:
                out.append(FingerDof(joint.name, mimics))
                continue
            else:
                groups = [rates]
            for group in groups:
                after = {name: r for name, r in group.items() if name != joint.name}
                out.append(FingerDof(joint.name, group, after if joint.breakaway and after else None))
        return tuple(out)

    @cached_property
    def jaw(self) -> tuple[JointSpec, JointSpec] | None:
        """(master, slave) finger joints of a parallel jaw: the first driven
        prismatic joint and the joint mimicking it; None for other hands."""
        master = next((j for j in self.driven if j.kind == "prismatic"), None)
        slave = None if master is None else next((j for j in self.joints if j.mimic == master.name), None)
        return None if master is None or slave is None else (master, slave)

    def opening(self, joints: Mapping[str, float]) -> float:
        """[m] distance between the fingers of a parallel jaw at ``joints``."""
        return float(sum(joints[j.name] for j in self.joints if j.kind == "prismatic"))

    def widest(self, shapes: Sequence[P]) -> P:
        """The most open of ``shapes`` (this hand's preshapes): the largest
        travel against its closing synergy."""
        return max(shapes, key=lambda s: -sum(r * s.joints[j] for j, r in s.close.items()))

    def contact_velocity(self, rates: Mapping[str, float], points: np.ndarray, links: Sequence[str],
                         axes: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """(n, 3) velocity [m per unit closing] of each contact point ``points``
        (n, 3) [m], on link ``links[i]``, when one DOF moves its joints at
        ``rates``; ``axes[name]``: (origin (3,) [m], unit direction (3,)) of
        each joint's axis in the frame of ``points`` (needed only for the
        joints that move a contact)."""
        v = np.zeros((len(points), 3))
        for name, rate in rates.items():
            joint = self.joint(name)
            moved = np.array([link in joint.moves for link in links], bool)
            if not moved.any():
                continue
            origin, axis = axes[name]
            if joint.kind == "revolute":  # axis x (points - origin): np.cross's products, without its set-up
                rel = points - origin
                lin = np.column_stack([axis[1] * rel[:, 2] - axis[2] * rel[:, 1], axis[2] * rel[:, 0] -
                                       axis[0] * rel[:, 2], axis[0] * rel[:, 1] - axis[1] * rel[:, 0]])
            else:
                lin = np.broadcast_to(axis, points.shape)
            v += rate * lin * moved[:, None]
        return v

    def travel(self, rates: Mapping[str, float], q: Mapping[str, float], speed: float, towards: str) -> float:
        """[m] how far a contact moving at ``speed`` [m per unit closing]
        with one DOF (``rates``) gets before one of its joints reaches its
        open (``towards="open"``) or closed limit from ``q`` (a joint not in
        ``q`` at its lower limit): per joint, the room left [rad or m] times
        speed over rate; the least."""
        if towards not in ("open", "closed"):
            raise ValueError(f"towards must be 'open' or 'closed', not {towards!r}")
        out = np.inf
        for name, rate in rates.items():
            spec = self.joint(name)
            value = q.get(name, spec.lower)
            lever = float(speed / abs(rate))
            room = (value - spec.lower) if (rate > 0) == (towards == "open") else (spec.upper - value)
            out = min(out, room * lever)
        return float(out)

    def open_travel(self, close: Mapping[str, float], closed: Mapping[str, float], points: np.ndarray,
                    links: Sequence[str], axes: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> float:
        """[m] the smallest open travel a touching finger has left at its
        contacts: for each finger DOF as it ended (:meth:`closing_dofs`) that
        moves a contact, how far its fastest contact gets back along the
        synergy until a joint of it reaches its open limit (:meth:`travel`).
        Near 0 the open hand could not have been put around the object (no
        squeeze travel); ``inf`` if no finger touches. Contacts ``points``
        (n, 3) [m] on ``links``, joint ``axes`` as :meth:`contact_velocity`."""
        out = np.inf
        for dof in self.closing_dofs(close, closed):
            speed = np.linalg.norm(self.contact_velocity(dof.rates, points, links, axes), axis=1)
            on = speed > STILL
            if on.any():
                out = min(out, self.travel(dof.rates, closed, speed[on].max(), "open"))
        return float(out)
