"""Weight resistance of many grasps at once: the linear programs of
:mod:`planner.quality.resistance`, solved together by a dual simplex in numpy.

HiGHS pays ~60-130 us a run whatever the program's size, and the Panda's
programs are tiny (6 equality rows and 2 motor rows, ~70 columns), so a unit
of ~1,000 grasps x 14 directions spent ~2.4 ms a grasp in ``solve``. Here the
same programs go through one simplex whose every step is one numpy operation
on a stack of tableaux (all directions of all grasps of a shape together).

The ratio form. With lambda = s mu and t = 1/s (s > 0), the program of
:func:`planner.quality.resistance.solve` (max s: W lambda + s m g d = 0,
rows lambda <= bounds, lambda >= 0, s <= cap) is

    min t   s.t.   W~ mu = -g_d,   rows mu - bounds t <= 0,   mu >= 0,   t >= 1 / cap

(W~ and g_d: the wrench matrix and the load m g (d, 0) in the wrench matrix's
row space, as ``solve`` writes them); s = 1 / t, and s = 0 where it has no
solution. In standard form, x = (mu, tau, sigma) >= 0 with t = tau + 1/cap
and slacks sigma, A x = (-g_d, bounds / cap), cost tau. The direction moves
the right-hand side only, so a basis of r independent columns of W~ and the
slacks (cost 0 on every basic column: all reduced costs >= 0) is dual
feasible for every direction at once: the dual simplex starts there, the
leaving row the most negative basic value, the entering column by the
ratio test (ties: the largest pivot; no pivot below ``LP_PIVOT_TOL`` of its row).

Every answer is checked from the original data before it is used: an optimum
by its basis recomputed (each basic value and reduced cost >= -``LP_TOL``, not
relative to the largest, and those values, the negative ones set to 0,
solving each row to ``LP_TOL`` of that row's own terms: the basis is optimal,
so its objective is the program's optimum); an infeasible program by the
leaving row of B^-1 A (>= 0 on every column to ``FARKAS_TOL`` of that column's own scale, tau's to s <= ``LP_TOL``,
negative on the right-hand side: a Farkas certificate). A program whose check
fails, or that did not finish in ``MAX_PIVOTS``, is solved by HiGHS. The same
optima as ``solve``: to 8e-11 g on the 22,218 (grasp, direction) programs of the Panda's mug and
random_003 units and the Barrett's mug unit; where the two differ more (HiGHS
stops at its 1e-7 feasibility tolerances, up to ~2e-7 g off), this is the
nearer to a linprog at 1e-10 (``tests/quality/test_quality_resistance_batch.py``).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from planner.quality.resistance import ResistanceProgram, row_space, solve
from planner.quality.tolerances import FARKAS_TOL, LP_PIVOT_TOL, LP_ROUNDOFF, LP_TOL, RANK_TOL

#: Pivots of one stack before its programs still running go to HiGHS (the Panda's: ~10, at most ~35).
MAX_PIVOTS = 100
#: Tableaux pivoted together: large enough that numpy's per-call cost is spread thin, small enough to stay in cache.
CHUNK = 512
#: Tableaux of more rows (equilibrium and motor rows) go to HiGHS: a pivot costs rows x columns, HiGHS about the
#: same whatever the size. Measured (all of a mug unit's programs, both ways in one process): the Allegro's 38
#: rows (32 motor rows) 2.2 s batched against 0.95 s by HiGHS; the Barrett's 12 rows 1.1 against 1.4 s, the
#: PR2's 10 0.16 against 0.36 s.
MAX_ROWS = 16


@dataclass(frozen=True)
class _Standard:
    """One grasp's programs in standard form (see the module docstring).

    matrix : (n, c) A, columns mu (k), tau, sigma (p); rhs : (m, n) per kept direction; start : (n,) the
    starting basis; tau : the column of tau; kept : (m,) the directions' indices.
    """

    matrix: np.ndarray
    rhs: np.ndarray
    start: np.ndarray
    tau: int
    kept: np.ndarray


def standard(prog: ResistanceProgram, directions: np.ndarray) -> _Standard | None:
    """The programs of ``prog`` for the rows of ``directions`` (d, 3) in standard form; None when no direction
    has a program (no generator, or every load outside the wrench matrix's row space: 0 in ``solve`` too)."""
    k = prog.wrench.shape[1]
    if k == 0:
        return None
    basis, outside = row_space(prog.wrench)
    kept = np.flatnonzero(np.abs(directions @ outside).max(axis=1) <= RANK_TOL) if outside.shape[1] \
        else np.arange(len(directions))
    if not len(kept):
        return None
    rank, p = basis.shape[1], len(prog.rows)
    w = basis.T @ prog.wrench
    matrix = np.zeros((rank + p, k + 1 + p))
    matrix[:rank, :k] = w
    matrix[rank:, :k] = prog.rows
    matrix[rank:, k] = -prog.bounds
    matrix[rank:, k + 1:] = np.eye(p)
    rhs = np.empty((len(kept), rank + p))
    rhs[:, :rank] = -(prog.weight * directions[kept]) @ basis[:3]
    rhs[:, rank:] = prog.bounds / prog.cap
    _, _, pivots = scipy.linalg.qr(w, pivoting=True, mode="economic", check_finite=False)
    return _Standard(matrix, rhs, np.r_[pivots[:rank], k + 1 + np.arange(p)], k, kept)


def solve_many(programs: Sequence[ResistanceProgram], directions: np.ndarray) -> list[np.ndarray]:
    """(d,) largest s per row of ``directions`` (d, 3) for each program: ``solve``'s answers."""
    out = [np.zeros(len(directions)) for _ in programs]
    stacks: dict[tuple[int, int], list[tuple[int, _Standard]]] = defaultdict(list)
    for g, prog in enumerate(programs):
        if 6 + len(prog.rows) > MAX_ROWS:  # up to 6 equilibrium rows
            out[g] = solve(prog, directions)
            continue
        form = standard(prog, directions)
        if form is not None:
            stacks[form.matrix.shape].append((g, form))
    for members in stacks.values():  # a stack's tableaux built a chunk at a time: memory of CHUNK, not of the unit
        forms = [f for _, f in members]
        owner = np.repeat(np.arange(len(forms)), [len(f.kept) for f in forms])
        rhs = np.concatenate([f.rhs for f in forms])
        start = np.stack([f.start for f in forms])
        tau = np.array([f.tau for f in forms])
        caps = np.array([programs[g].cap for g, _ in members], float)
        value = np.full(len(rhs), np.nan)
        for lo in range(0, len(rhs), CHUNK):
            part, who = slice(lo, lo + CHUNK), owner[lo:lo + CHUNK]
            matrix = np.stack([forms[i].matrix for i in who])
            try:
                status, basis = _dual_simplex(matrix, rhs[part], start[who], tau[who])
            except np.linalg.LinAlgError:  # a starting basis singular to round-off: HiGHS solves the chunk
                continue
            value[part] = _checked(matrix, rhs[part], status, basis, tau[who], caps[who])
        at = 0
        for g, f in members:
            got = value[at:at + len(f.kept)]
            at += len(f.kept)
            redo = np.isnan(got)
            if redo.any():
                got[redo] = solve(programs[g], directions[f.kept[redo]])
            out[g][f.kept] = got
    return out


def _dual_simplex(matrix: np.ndarray, rhs: np.ndarray, basis: np.ndarray, tau: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(status (m,): 1 optimal, 2 infeasible, 0 unfinished; final basis (m, n)) of the programs A (m, n, c),
    b (m, n) from the dual-feasible ``basis`` (m, n), cost on column ``tau`` (m,). The tableaux still running
    are compacted out of the stack as the others finish."""
    m, n, c = matrix.shape
    inv = np.linalg.inv(np.take_along_axis(matrix, basis[:, None, :], axis=2))
    table = np.concatenate([inv @ matrix, inv @ rhs[:, :, None]], axis=2)  # (m, n, c + 1): B^-1 [A | b]
    cost = np.zeros((m, c))
    cost[np.arange(m), tau] = 1.0  # reduced costs; y = 0 at the start
    status = np.zeros(m, np.int8)
    live, rows = np.arange(m), basis.copy()
    for _ in range(MAX_PIVOTS):
        r = np.arange(len(live))
        x = table[:, :, c]
        leave = np.argmin(x, axis=1)
        done = x[r, leave] >= -LP_TOL
        alpha = table[r, leave, :c]
        enter = alpha < -LP_PIVOT_TOL * np.abs(alpha).max(axis=1, keepdims=True)
        ratio = np.divide(cost, -alpha, out=np.full_like(cost, np.inf), where=enter)
        best = ratio.min(axis=1)
        tie = enter & (ratio <= best[:, None] + 1e-12 * np.abs(best[:, None]) + 1e-15)
        q = np.argmin(np.where(tie, alpha, 0.0), axis=1)  # the largest pivot among the least ratios
        pivot = alpha[r, q]
        dead = ~done & np.isinf(best)
        lost = ~done & ~dead & (~(pivot < 0) | np.isnan(best))  # round-off ran away: unfinished, for HiGHS
        status[live[done]], status[live[dead]] = 1, 2
        if (done | dead | lost).any():
            basis[live[done | dead]] = rows[done | dead]
            go = ~(done | dead | lost)
            live, table, rows, cost = live[go], table[go], rows[go], cost[go]
            leave, alpha, q, pivot = leave[go], alpha[go], q[go], pivot[go]
            r = np.arange(len(live))
            if not len(live):
                break
        cost -= (cost[r, q] / pivot)[:, None] * alpha
        cost[r, q] = 0.0
        row = table[r, leave] / pivot[:, None]
        column = table[r, :, q]
        column[r, leave] -= 1.0  # the pivot row becomes ``row``
        table -= column[:, :, None] * row[:, None, :]
        rows[r, leave] = q
    basis[live] = rows
    return status, basis


def _checked(matrix: np.ndarray, rhs: np.ndarray, status: np.ndarray, basis: np.ndarray, tau: np.ndarray,
             cap: np.ndarray) -> np.ndarray:
    """(m,) s of each program whose answer its basis proves from the original data; NaN for the others."""
    m, n, c = matrix.shape
    out = np.full(m, np.nan)
    b = np.take_along_axis(matrix, basis[:, None, :], axis=2)  # (m, n, n)
    try:
        lu = np.linalg.inv(b)
    except np.linalg.LinAlgError:
        return out
    x = np.einsum("mij,mj->mi", lu, rhs)
    on_tau = basis == tau[:, None]
    y = np.einsum("mji,mj->mi", lu, on_tau.astype(float))  # B^-T c_B
    reduced = -np.einsum("mij,mi->mj", matrix, y)
    reduced[np.arange(m), tau] += 1.0
    scale = 1.0 + np.abs(x).max(axis=1)
    # each basic value >= -LP_TOL on its own: one of the largest's round-off would let a small one be negative
    # enough to be another vertex (a program of slack ~4e3 took x = -1.8e-6 for 0: s 17.21, not 13.77 g)
    optimal = (status == 1) & (x.min(axis=1) >= -LP_TOL) & (reduced.min(axis=1) >= -LP_TOL) & _rows_hold(b, x, rhs)
    t = np.where(on_tau, x, 0.0).sum(axis=1) + 1.0 / cap
    out[optimal] = np.minimum(1.0 / t[optimal], cap[optimal])
    # infeasible: the row of B^-1 whose basic value is most negative, >= 0 on every column of A
    leave = np.argmin(x, axis=1)
    farkas = lu[np.arange(m), leave]  # (m, n)
    row = np.einsum("mi,mij->mj", farkas, matrix)
    # each column's own scale (round-off of the certificate x the column), not the table's largest entry
    size = np.abs(farkas).max(axis=1)[:, None] * np.abs(matrix).sum(axis=1)
    # but tau's, of -bounds (up to ~1e8 there): any y A_tau < 0 bounds s instead, tau >= (y b) / (y A_tau) so
    # s <= (y A_tau) / (y b), which must be below LP_TOL g (a bound of 1.7e8 N let 0 stand for 2e-6 g)
    r, yb = np.arange(m), x[np.arange(m), leave]
    clean = (row >= -FARKAS_TOL * size) | (np.arange(c) == tau[:, None])
    bounded = -row[r, tau] <= LP_TOL * -yb  # s <= LP_TOL, without dividing
    proven = (status == 2) & clean.all(axis=1) & (yb < -LP_TOL * scale) & bounded
    out[proven] = 0.0
    return out


def _rows_hold(basic: np.ndarray, x: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """(m,) whether the basic values ``x`` (m, n) of the bases ``basic`` (m, n, n), the negative ones and those
    within round-off of 0 (``LP_ROUNDOFF`` of the largest) set to 0, solve B x = b in every row to LP_TOL of that
    row's own terms |B_k| x + |b_k|, recomputed from the data: not implied by each x >= -LP_TOL. A slack of
    -5.6e-10 in a motor row of bound 0 whose terms were 5.6e-10 too (rows scaled by 1e-4, the wrench by 1e5) was
    a force the row forbids, and s 50 where no force balances the load; a bound of 8.6e12 left B^-1 b (B of
    condition ~1e29) off five rows by up to 5% of their terms, s 0.0138 where 0.0104 holds."""
    kept = np.where(x > LP_ROUNDOFF * np.abs(x).max(axis=1, keepdims=True), x, 0.0)
    residual = rhs - np.einsum("mij,mj->mi", basic, kept)
    return (np.abs(residual) <= LP_TOL * (np.einsum("mij,mj->mi", np.abs(basic), kept) + np.abs(rhs))).all(axis=1)
