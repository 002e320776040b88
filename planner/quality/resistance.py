"""Weight resistance: the largest multiple of the object's weight a grasp holds,
per direction of gravity, with the hand's real motors (sec. 2.3.3, grasping
force optimisation, as a linear program).

For gravity along the unit direction d ({W}), the grasp holds s times the
object's weight m g when contact forces x exist with

    G x + s m g (d, 0) = 0                 equilibrium at p = the centre of mass (eq 2.5)
    x in the friction cones                 (eq 2.6), linearised: x = L lambda, lambda >= 0
    tau = J^T x                             joint torques (hand Jacobian J = B J~, eq 2.29)
    0 <= sense_a (T tau)_a <= limit_a       a motor pushes only in its closing sense
    |(T tau)_a| <= limit_a                  a motor that holds its joints still (sense 0)

and the resistance in that direction is the largest such s (in units of g),
capped at ``cap`` (a contact on a link no joint moves, the palm, is pushed by
the arm and bounds nothing). L's columns are the primitive contact forces of
wrenches.py in each contact frame {C}_i: the m cone edges (1, mu cos, mu sin)
and, for soft fingers, the normal with +-torsion of spin about n_i. T is the
transmission: motor a's generalised force is sum_j T_aj tau_j (virtual work,
T_aj = dq_j per unit travel of the motor: a mimic joint q_m = r q_d adds
r tau_m to its driver's motor). Gravity acts at the centre of mass, so only
(d, 0) loads the object.

Units: forces [N], torques [N m], s in g (1 = the object's weight).
The fast path builds one HiGHS model per grasp and changes only the load
column between directions; ``planner.quality.reference.reference_resistance``
is the same program through ``scipy.optimize.linprog``. A sweep solves all its
grasps' programs together (:mod:`planner.quality.resistance_batch`, the same
optima at less than half the cost), HiGHS only where that cannot.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from planner.errors import DegenerateGraspError
from planner.geometry.gravity import AXES, DIAGONALS, SPHERE14  # noqa: F401 (the directions, named here too)
from planner.quality.contacts import FRICTIONLESS, SOFT, Contacts, ModelArg, as_array, as_center, as_contacts
from planner.quality.grasp_matrix import partial_grasp_matrices, selection_lengths
from planner.quality.jacobian import contacts_jacobian
from planner.quality.tolerances import GRAVITY, RANK_TOL, RESISTANCE_CAP
from planner.quality.wrenches import _cone_table, as_cone_edges


@dataclass(frozen=True)
class HandDrive:
    """The hand's joints at the grasp and the motors that drive them, {W}.

    joint_origins : (n_q, 3) zeta_j [m]; joint_axes : (n_q, 3) unit z_j;
    joint_types : n_q names ("revolute", "prismatic");
    transmission : (n_a, n_q) T, motor a's generalised force is (T tau)_a;
    sense : (n_a,) +1 / -1: the motor pushes only in that sense of (T tau)_a
        (its closing sense); 0: it holds its joints still, either way;
    limit : (n_a,) [N or N m] largest |(T tau)_a|; inf: unbounded (a worm
        gear holding a joint).
    """

    joint_origins: np.ndarray
    joint_axes: np.ndarray
    joint_types: tuple[str, ...]
    transmission: np.ndarray
    sense: np.ndarray
    limit: np.ndarray

    def __post_init__(self) -> None:
        n_q, n_a = len(self.joint_origins), len(self.sense)
        shapes = {"joint_origins": (n_q, 3), "joint_axes": (n_q, 3), "transmission": (n_a, n_q),
                  "sense": (n_a,), "limit": (n_a,)}
        for name, shape in shapes.items():
            if np.shape(getattr(self, name)) != shape:
                raise DegenerateGraspError(f"HandDrive.{name} must have shape {shape}, got "
                                           f"{np.shape(getattr(self, name))}")
        if len(self.joint_types) != n_q:
            raise DegenerateGraspError(f"HandDrive.joint_types has {len(self.joint_types)} entries for {n_q} joints")
        if (np.asarray(self.limit) < 0).any() or not np.isin(self.sense, (-1, 0, 1)).all():
            raise DegenerateGraspError("HandDrive: limits must be >= 0 and senses -1, 0 or +1")


@dataclass(frozen=True)
class Resistance:
    """Weight resistance [g] per gravity direction, its worst and its mean."""

    per_direction: np.ndarray  # (k,)
    worst: float
    mean: float


@dataclass(frozen=True)
class ResistanceProgram:
    """The linear program of one grasp, direction-free (see the module docstring).

    wrench : (6, k) wrench of each generator lambda_k on the object [N, N m about p];
    rows : (r, k), bounds : (r,): motor rows, rows @ lambda <= bounds;
    weight : m g [N]; cap : largest s [g].
    """

    wrench: np.ndarray
    rows: np.ndarray
    bounds: np.ndarray
    weight: float
    cap: float


def generators(contacts: Contacts, m: int) -> np.ndarray:
    """L (l, k): primitive contact forces in the stacked contact frames
    (l = sum l_i rows of B, as in G = G~ B^T), one column per generator: per contact, its normal's row 1 in
    each of its columns, its m edges mu (cos, sin) in the tangent rows, a soft contact's two torsion columns
    +-torsion in its fourth row. :func:`generators_reference`'s matrix to the bit (the same products), written
    at once instead of block by block (~9 blocks a Panda grasp)."""
    cos, sin = _cone_table(m)
    lengths, model = selection_lengths(contacts), contacts.model
    if not len(lengths):
        return np.zeros((0, 0))
    width = np.where(model == FRICTIONLESS, 1, np.where(model == SOFT, m + 2, m))
    starts, first = np.cumsum(lengths) - lengths, np.cumsum(width) - width
    out = np.zeros((int(lengths.sum()), int(width.sum())))
    out[np.repeat(starts, width), np.arange(out.shape[1])] = 1.0
    rub = np.flatnonzero(model != FRICTIONLESS)
    cols = first[rub, None] + np.arange(m)
    out[starts[rub, None] + 1, cols] = contacts.mu[rub, None] * cos[:m]
    out[starts[rub, None] + 2, cols] = contacts.mu[rub, None] * sin[:m]
    soft = np.flatnonzero(model == SOFT)
    out[starts[soft] + 3, first[soft] + m] = contacts.torsion[soft]
    out[starts[soft] + 3, first[soft] + m + 1] = -contacts.torsion[soft]
    return out


def generators_reference(contacts: Contacts, m: int) -> np.ndarray:
    """:func:`generators` block by block, one contact at a time."""
    cos, sin = _cone_table(m)
    lengths = selection_lengths(contacts)
    starts = np.cumsum(lengths) - lengths
    blocks = []
    for i, start in enumerate(starts):
        if contacts.model[i] == FRICTIONLESS:
            cols = np.zeros((lengths.sum(), 1))
            cols[start, 0] = 1.0
        else:
            extra = 2 if contacts.model[i] == SOFT else 0
            cols = np.zeros((lengths.sum(), m + extra))
            cols[start] = 1.0
            cols[start + 1, :m] = contacts.mu[i] * cos[:m]
            cols[start + 2, :m] = contacts.mu[i] * sin[:m]
            if extra:
                cols[start + 3, m:] = [contacts.torsion[i], -contacts.torsion[i]]
        blocks.append(cols)
    return np.hstack(blocks) if blocks else np.zeros((0, 0))


def program(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike, center: ArrayLike, mass: float,
            drive: HandDrive, contact_links: ArrayLike, joint_affects: ArrayLike, model: ModelArg = "point",
            torsion: ArrayLike = 0.0, cone_edges: int = 8, cap: float = RESISTANCE_CAP) -> ResistanceProgram:
    """The direction-free part of the program.

    points : (n, 3) c_i [m]; frames : (n, 3, 3) R_i, columns (n_i, l_i, o_i),
    n_i into the object; mu, torsion [m] : scalar or (n,); model : name or n
    names; center : (3,) the centre of mass [m]; mass [kg]; contact_links :
    (n,) int, joint_affects : (n, n_q) bool as ``hand_jacobian``.
    """
    contacts = as_contacts(points, frames, mu=mu, model=model, torsion=torsion)
    weight = float(as_array(mass, "mass", ())) * GRAVITY
    if weight <= 0:
        raise DegenerateGraspError(f"mass must be > 0 kg, got {mass}")
    m = as_cone_edges(cone_edges)
    n = len(contacts.points)
    if n == 0:
        return ResistanceProgram(np.zeros((6, 0)), np.zeros((0, 0)), np.zeros(0), weight, cap)
    lengths = selection_lengths(contacts)
    tilde = partial_grasp_matrices(contacts, as_center(center))
    grasp = np.concatenate([g[:, :k] for g, k in zip(tilde, lengths)], axis=1)  # G (6, l), eq 2.28
    lam = generators(contacts, m)  # L (l, k)
    jac = contacts_jacobian(contacts, contact_links, drive.joint_origins, drive.joint_axes, drive.joint_types,
                            joint_affects)  # J (l, n_q), eq 2.29
    motor = np.asarray(drive.transmission, float) @ jac.T @ lam  # (n_a, k): (T J^T L)
    sense, limit = np.asarray(drive.sense, float), np.asarray(drive.limit, float)
    push = sense != 0
    rows = [sense[push, None] * motor[push], -sense[push, None] * motor[push], motor[~push], -motor[~push]]
    bounds = [limit[push], np.zeros(int(push.sum())), limit[~push], limit[~push]]
    a_ub, b_ub = np.vstack(rows), np.concatenate(bounds)
    finite = np.isfinite(b_ub)
    return ResistanceProgram(grasp @ lam, a_ub[finite], b_ub[finite], weight, cap)


def weight_resistance(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike, center: ArrayLike, mass: float,
                      drive: HandDrive, contact_links: ArrayLike, joint_affects: ArrayLike,
                      directions: ArrayLike = SPHERE14, model: ModelArg = "point", torsion: ArrayLike = 0.0,
                      cone_edges: int = 8, cap: float = RESISTANCE_CAP) -> Resistance:
    """Weight resistance [g] for gravity along each row of ``directions``
    (k, 3) unit vectors in {W}; arguments as :func:`program`."""
    dirs = _directions(directions)
    prog = program(points, frames, mu=mu, center=center, mass=mass, drive=drive, contact_links=contact_links,
                   joint_affects=joint_affects, model=model, torsion=torsion, cone_edges=cone_edges, cap=cap)
    return summarise(solve(prog, dirs))


def summarise(per_direction: np.ndarray) -> Resistance:
    """Worst and mean of (k,) resistances (k >= 1)."""
    return Resistance(per_direction, float(per_direction.min()), float(per_direction.mean()))


def _directions(directions: ArrayLike) -> np.ndarray:
    dirs = as_array(directions, "directions", (-1, 3))
    if len(dirs) == 0 or (np.abs(np.linalg.norm(dirs, axis=1) - 1.0) > 1e-6).any():
        raise DegenerateGraspError("directions must be one or more unit vectors (k, 3)")
    return dirs


#: This process's HiGHS instance, by process id (a forked child makes its own).
_SOLVERS: dict[int, object] = {}


def _solver():  # type: ignore[no-untyped-def]
    """This process's HiGHS solver, its model cleared, output off. The first
    ``Highs()`` of a process prints HiGHS's banner on standard output (before
    any option can turn output off), which broke ``grasp generate --json``:
    it is made once, with file descriptor 1 pointed at /dev/null meanwhile."""
    import highspy

    solver = _SOLVERS.get(os.getpid())
    if solver is None:
        sys.stdout.flush()
        saved, devnull = os.dup(1), os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, 1)
            solver = highspy.Highs()
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            os.close(devnull)
        solver.setOptionValue("output_flag", False)
        # presolve finds nothing to remove in these small dense programs and costs ~17% of each solve
        # (measured on 492 of the Panda's programs: the same optima to 4e-11)
        solver.setOptionValue("presolve", "off")
        # the primal simplex re-optimises after the load column changes faster than the dual (HiGHS's
        # default): measured on the 3,367 programs of the Panda's and the Barrett's mug sweeps, 14-16% less
        # time in solve(), the same optima to 1.2e-8 g
        solver.setOptionValue("simplex_strategy", 4)
        # one thread: HiGHS's task scheduler costs ~40 us a run in these ~70-column programs, ~27% of the
        # time in solve() (measured on 400 of the Panda's mug programs: the same optima, bit for bit)
        solver.setOptionValue("threads", 1)
        _SOLVERS[os.getpid()] = solver
    solver.clearModel()
    return solver


def solve(prog: ResistanceProgram, directions: np.ndarray) -> np.ndarray:
    """(k,) largest s per direction: one HiGHS model, warm-started between
    directions (only the load column changes). The equilibrium rows are those
    of the wrench matrix's numerical row space (singular values above
    ``RANK_TOL`` of the largest): a direction no contact wrench reaches (two
    point contacts exert no torque about their line) would otherwise be a row
    of round-off that the solver's scaling turns into a constraint (the same
    pinch resisted 17.84 or 12.61 g depending on a 1e-7 rad turn). A load with
    a part outside that space cannot be balanced: 0."""
    import highspy

    k = prog.wrench.shape[1]
    if k == 0:
        return np.zeros(len(directions))
    basis, outside = row_space(prog.wrench)
    rank = basis.shape[1]
    n_rows = rank + len(prog.rows)
    matrix = np.zeros((n_rows, k + 1))
    matrix[:rank, :k] = basis.T @ prog.wrench
    matrix[rank:, :k] = prog.rows
    matrix[:rank, k] = basis[:3].T @ (prog.weight * directions[0])
    inf = highspy.kHighsInf
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = k + 1, n_rows
    lp.col_cost_ = np.r_[np.zeros(k), -1.0]
    lp.col_lower_, lp.col_upper_ = np.zeros(k + 1), np.r_[np.full(k, inf), prog.cap]
    lp.row_lower_ = np.r_[np.zeros(rank), np.full(len(prog.rows), -inf)]
    lp.row_upper_ = np.r_[np.zeros(rank), prog.bounds]
    start, index, value = _columnwise(matrix)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_, lp.a_matrix_.index_, lp.a_matrix_.value_ = start, index, value
    solver = _solver()
    solver.passModel(lp)
    out = np.zeros(len(directions))
    bounded = outside.shape[1] > 0  # a full-rank wrench matrix balances every load: nothing to test
    for r, d in enumerate(directions):
        load = basis[:3].T @ (prog.weight * d)
        for row, value in enumerate(load.tolist()):
            solver.changeCoeff(row, k, value)
        if bounded and np.abs(outside.T @ d).max() > RANK_TOL:  # a load the contacts cannot balance at all
            continue
        solver.run()
        if solver.getModelStatus() == highspy.HighsModelStatus.kOptimal:
            out[r] = min(max(-solver.getObjectiveValue(), 0.0), prog.cap)
    return out


def row_space(wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(basis (6, r), outside (3, 6 - r)) of a wrench matrix (6, k), k >= 1: an orthonormal basis of its
    numerical column space (singular values above ``RANK_TOL`` of the largest) and the force rows of the rest
    of R^6. U alone is needed, all 6 of its columns: the thin SVD has them all once k >= 6 and skips V (k, k)
    (one BLAS thread: 28 against 200 us at the Barrett's ~140 columns, 21 against 46 us at the Panda's ~70),
    with the same U and singular values bit for bit (:func:`row_space_reference`)."""
    u, sing, _ = np.linalg.svd(wrench, full_matrices=wrench.shape[1] < 6)
    rank = int((sing > sing[0] * RANK_TOL).sum()) if sing[0] > 0 else 0
    return u[:, :rank], u[:3, rank:]


def row_space_reference(wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`row_space` from the full SVD."""
    u, sing, _ = np.linalg.svd(wrench, full_matrices=True)
    rank = int((sing > sing[0] * RANK_TOL).sum()) if sing[0] > 0 else 0
    return u[:, :rank], u[:3, rank:]


def _columnwise(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(start (c + 1,) int32, index (nnz,) int32, value (nnz,)): the nonzeros of ``matrix`` (r, c) column by
    column, rows ascending in each (HiGHS's column-wise format; the same arrays as
    :func:`_columnwise_reference`)."""
    col, row = np.nonzero(matrix.T)
    start = np.r_[0, np.cumsum(np.bincount(col, minlength=matrix.shape[1]))].astype(np.int32)
    return start, row.astype(np.int32), matrix[row, col]


def _columnwise_reference(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_columnwise` one column at a time."""
    columns = [np.flatnonzero(matrix[:, j]) for j in range(matrix.shape[1])]
    return (np.r_[0, np.cumsum([len(c) for c in columns])].astype(np.int32), np.concatenate(columns).astype(np.int32),
            np.concatenate([matrix[c, j] for j, c in enumerate(columns)]))


def drive_rows(joint_names: Sequence[str], motors: Sequence[tuple[dict[str, float], int, float]]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(transmission (n_a, n_q), sense (n_a,), limit (n_a,)) from motors given
    as ({joint: dq_j per unit motor travel}, sense, limit)."""
    t = np.zeros((len(motors), len(joint_names)))
    for a, (rates, _, _) in enumerate(motors):
        for name, rate in rates.items():
            t[a, list(joint_names).index(name)] = rate
    return t, np.array([s for _, s, _ in motors], float), np.array([lim for _, _, lim in motors], float)
