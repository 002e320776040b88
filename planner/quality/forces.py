"""Grasping force optimisation (sec. 2.3.3): least-magnitude contact forces.

Find contact force components x (normal, then tangential along l_i, o_i, in
each contact frame {C}_i) that hold the object against an external wrench,

    minimise  sum_i |f_i|^2
    s.t.      G x + w_ext = 0                        (equilibrium, eq 2.5)
              sqrt(f_l^2 + f_o^2) <= mu_i f_n, f_n >= 0  (true cone, eq 2.6)

This is a small second-order cone program.  We solve it with SLSQP, the
cone written as mu f_n - sqrt(f_l^2 + f_o^2 + d^2) + d >= 0 (d =
CONE_SMOOTHING: smooth at f_t = 0, looser than the true cone by at most d)
next to the bound f_n >= 0.  The squared form mu^2 f_n^2 - |f_t|^2 >= 0
looks smoother but measured worse: on random 4-contact closure grasps SLSQP
failed ~15% of the time with it and returned a non-minimal answer ~45% of
the time, against 0% and 0% with this form.  Every answer is accepted only
after we check equilibrium and the cones ourselves (EQUILIBRIUM_TOL, CONE_TOL).
Near the edge of closure (large forces) SLSQP's line search can still fail
(10 of 3,463 random 4-contact closure grasps): it starts again from forces
inside the inscribed 8-edge pyramids (a linear program, HiGHS), and those
are returned, balanced and inside the cones but not least-magnitude, if it
fails again (0 of the 3,463 without forces).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize

from planner.errors import DegenerateGraspError
from planner.quality.contacts import SOFT, ModelArg, as_array, as_center, as_contacts, as_torque_scale
from planner.quality.grasp_matrix import partial_grasp_matrices, selection_lengths
from planner.quality.tolerances import CONE_SMOOTHING, CONE_TOL, EQUILIBRIUM_TOL, RANK_TOL


def contact_forces(points: ArrayLike, frames: ArrayLike, wrench: ArrayLike, *,
                   mu: ArrayLike, center: ArrayLike, model: ModelArg = "point",
                   torque_scale: float = 1.0) -> np.ndarray | None:
    """Least-magnitude contact forces (n, 3) [N] in the WORLD frame {W} that
    balance ``wrench`` (6,) = external (force [N], torque about p [N m]), or
    None when no forces inside the friction cones can.

    points : (n, 3) c_i [m]; frames : (n, 3, 3) R_i, columns (n_i, l_i, o_i);
    mu : scalar or (n,); model : "frictionless" / "point" (or n of them; soft
    fingers need a torsion limit and are not supported here); torque_scale :
    rho [m], only rescales the torque rows for conditioning.
    """
    contacts = as_contacts(points, frames, mu=mu, model=model)
    if (contacts.model == SOFT).any():
        raise DegenerateGraspError("contact_forces supports models 'frictionless' and 'point'")
    w_ext = as_array(wrench, "wrench", (6,))
    if len(contacts.points) == 0:
        return np.zeros((0, 3)) if not w_ext.any() else None
    scale = np.r_[np.ones(3), np.full(3, 1.0 / as_torque_scale(torque_scale))]
    lengths = selection_lengths(contacts)
    tilde = partial_grasp_matrices(contacts, as_center(center))
    with np.errstate(over="ignore", invalid="ignore"):
        grasp = scale[:, None] * np.concatenate([g[:, :k] for g, k in zip(tilde, lengths)], axis=1)
    if not np.isfinite(grasp).all():
        raise DegenerateGraspError("grasp matrix overflows: check torque_scale and the contact"
                                   " coordinates (metres)")
    size = max(float(np.linalg.norm(w_ext)), 1.0)
    target = -scale * w_ext / size                # solve a unit-size problem
    with np.errstate(all="ignore"):     # a wild iterate only fails the checks below
        x = _solve(grasp, target, lengths, contacts.mu)
        if x is None or not _feasible(grasp, target, x, lengths, contacts.mu):
            return None
    local = np.zeros((len(lengths), 3))
    starts = np.cumsum(lengths) - lengths
    for i, (s, k) in enumerate(zip(starts, lengths)):
        local[i, :k] = x[s:s + k]
    return size * np.einsum("nij,nj->ni", contacts.frames, local)


def _cone_rows(lengths: np.ndarray) -> np.ndarray:
    """Start index of each frictional contact's block in x."""
    starts = np.cumsum(lengths) - lengths
    return starts[lengths == 3]


def _solve(grasp: np.ndarray, target: np.ndarray, lengths: np.ndarray,
           mu: np.ndarray) -> np.ndarray | None:
    starts = np.cumsum(lengths) - lengths
    cones, cone_mu = _cone_rows(lengths), mu[lengths == 3]
    normal = set(starts.tolist())
    bounds = [(0.0, None) if j in normal else (None, None) for j in range(grasp.shape[1])]

    def cone(x: np.ndarray) -> np.ndarray:
        spread = np.sqrt(x[cones + 1] ** 2 + x[cones + 2] ** 2 + CONE_SMOOTHING**2)
        return cone_mu * x[cones] - spread + CONE_SMOOTHING

    def cone_jac(x: np.ndarray) -> np.ndarray:
        spread = np.sqrt(x[cones + 1] ** 2 + x[cones + 2] ** 2 + CONE_SMOOTHING**2)
        jac = np.zeros((len(cones), len(x)))
        rows = np.arange(len(cones))
        jac[rows, cones] = cone_mu
        jac[rows, cones + 1], jac[rows, cones + 2] = -x[cones + 1] / spread, -x[cones + 2] / spread
        return jac

    # SLSQP needs independent equality rows: keep the range of G (what lies
    # outside it cannot be balanced, and _feasible rejects it afterwards).
    basis, sing, _ = np.linalg.svd(grasp, full_matrices=False)
    basis = basis[:, sing > RANK_TOL * max(sing.max(initial=0.0), 1.0)]
    eq_matrix, eq_target = basis.T @ grasp, basis.T @ target
    constraints = [{"type": "eq", "fun": lambda x: eq_matrix @ x - eq_target,
                    "jac": lambda x: eq_matrix}]
    if len(cones):
        constraints.append({"type": "ineq", "fun": cone, "jac": cone_jac})
    start = np.linalg.lstsq(grasp, target, rcond=None)[0]
    start[starts] = np.maximum(start[starts], 0.0) + 1.0   # begin strictly inside the cones

    def least(x0: np.ndarray) -> np.ndarray:
        return minimize(lambda x: 0.5 * x @ x, x0, jac=lambda x: x, method="SLSQP", bounds=bounds,
                        constraints=constraints, options={"ftol": 1e-12, "maxiter": 500}).x

    x = least(start)
    if np.isfinite(x).all() and _feasible(grasp, target, x, lengths, mu):
        return x
    # SLSQP's line search can fail on a grasp near the edge of closure (large forces): start it again from
    # forces that balance the load inside the inscribed pyramids (a linear program), and keep those if it fails
    inside = _pyramid_forces(eq_matrix, eq_target, lengths, mu)
    if inside is None:
        return x if np.isfinite(x).all() else None
    x = least(inside)
    return x if np.isfinite(x).all() and _feasible(grasp, target, x, lengths, mu) else inside


def _pyramid_forces(eq_matrix: np.ndarray, eq_target: np.ndarray, lengths: np.ndarray,
                    mu: np.ndarray) -> np.ndarray | None:
    """Contact forces x with ``eq_matrix @ x = eq_target``, each a non-negative combination of its contact's
    normal (frictionless) or of the 8 edges (1, mu cos t, mu sin t) of the pyramid inscribed in its cone
    (inside the true cone), the least total normal force; None if there are none (HiGHS, via linprog)."""
    from scipy.optimize import linprog

    angles = 2.0 * np.pi * np.arange(PYRAMID_EDGES) / PYRAMID_EDGES
    blocks, size = [], int(lengths.sum())
    for start, k, m in zip(np.cumsum(lengths) - lengths, lengths, mu):
        block = np.zeros((size, PYRAMID_EDGES if k == 3 else 1))
        block[start] = 1.0
        if k == 3:
            block[start + 1], block[start + 2] = m * np.cos(angles), m * np.sin(angles)
        blocks.append(block)
    edges = np.hstack(blocks)
    result = linprog(np.ones(edges.shape[1]), A_eq=eq_matrix @ edges, b_eq=eq_target, bounds=(0.0, None),
                     method="highs")
    return edges @ result.x if result.status == 0 else None


#: Edges of the pyramid inscribed in each friction cone of :func:`_pyramid_forces`.
PYRAMID_EDGES = 8


def _feasible(grasp: np.ndarray, target: np.ndarray, x: np.ndarray, lengths: np.ndarray,
              mu: np.ndarray) -> bool:
    if np.linalg.norm(grasp @ x - target) > EQUILIBRIUM_TOL * max(1.0, np.linalg.norm(target)):
        return False
    starts = np.cumsum(lengths) - lengths
    slack = CONE_TOL * max(1.0, float(np.linalg.norm(x)))
    if (x[starts] < -slack).any():
        return False
    cones = _cone_rows(lengths)
    tangential = np.hypot(x[cones + 1], x[cones + 2])
    return bool((tangential <= mu[lengths == 3] * x[cones] + slack).all())
