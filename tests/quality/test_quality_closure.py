"""Force closure: analytic cases, certificates, agreement with epsilon > 0."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from quality_support import (
    EXACT,
    antipodal_box_case,
    assert_close,
    box_grasp,
    equator_grasp,
    frames_from_normals,
    seeds,
    sphere_grasp,
)

from planner.quality import FORCE_CLOSURE_TOL, epsilon, evaluate, force_closure, metrics, primitive_wrenches
from planner.quality.closure import SIMPLEX, check_closure, quick_reject
from planner.quality.reference import reference_epsilon
from planner.quality.tolerances import FACET_TOL

R = 0.05   # sphere radius and torque scale [m]


def kw(mu: float = 0.5, **extra: object) -> dict:
    return {"mu": mu, "center": np.zeros(3), "torque_scale": R} | extra


def test_regular_simplex_directions() -> None:
    assert SIMPLEX.shape == (7, 6)
    assert_close(np.linalg.norm(SIMPLEX, axis=1), np.ones(7))
    gram = SIMPLEX @ SIMPLEX.T
    assert_close(gram[~np.eye(7, dtype=bool)], np.full(42, -1 / 6), abs_=EXACT)
    assert_close(SIMPLEX.sum(0), np.zeros(6), abs_=EXACT)


@given(seed=seeds, n=st.integers(1, 6), box=st.booleans())
@settings(max_examples=60, deadline=None)
def test_frictionless_grasps_with_fewer_than_7_contacts_are_never_closure(
        seed: int, n: int, box: bool) -> None:
    rng = np.random.default_rng(seed)
    pts, frames = (box_grasp if box else sphere_grasp)(rng, n)
    args = kw(model="frictionless")
    assert not force_closure(pts, frames, **args)
    assert epsilon(pts, frames, **args) == 0.0


@given(mu=st.floats(1e-4, 10))
@settings(max_examples=40, deadline=None)
def test_three_equatorial_contacts_at_120_degrees_hold_for_every_mu(mu: float) -> None:
    # Checked numerically before asserting: the out-of-plane friction
    # components give the force along z and the torques about in-plane axes;
    # in-plane friction gives the torque about z.  epsilon ~ 0.45 mu here.
    pts, frames = equator_grasp(3)
    assert force_closure(pts, frames, **kw(mu))
    assert epsilon(pts, frames, **kw(mu)) > 0.4 * mu


def test_three_equatorial_contacts_without_friction_do_not_hold() -> None:
    pts, frames = equator_grasp(3)
    assert not force_closure(pts, frames, **kw(0.0))
    assert epsilon(pts, frames, **kw(0.0)) == 0.0


@given(mu=st.floats(1e-3, 3), torsion=st.floats(1e-4, 0.05))
@settings(max_examples=30, deadline=None)
def test_antipodal_pair_needs_soft_fingers(mu: float, torsion: float) -> None:
    pts = np.array([[R, 0, 0], [-R, 0, 0]])
    frames = frames_from_normals(-pts)
    assert not force_closure(pts, frames, **kw(mu))
    assert epsilon(pts, frames, **kw(mu, norm="Linf")) == 0.0
    soft = kw(mu, model="soft", torsion=torsion)
    assert force_closure(pts, frames, **soft)
    assert epsilon(pts, frames, **soft) > 0.0


@st.composite
def grasps(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, dict]:
    """Random grasps biased towards the edge of closure: zero and tiny
    friction, tiny torsion, repeated, coplanar and antipodal contacts."""
    rng = np.random.default_rng(draw(seeds))
    n = draw(st.integers(1, 7))
    pts, frames = (box_grasp if draw(st.booleans()) else sphere_grasp)(rng, n)
    shape = draw(st.sampled_from(["plain", "repeat", "planar", "antipodal"]))
    if shape == "repeat":
        idx = rng.integers(0, n, n + 2)
        pts, frames = pts[idx], frames[idx]
    elif shape == "planar":
        normals = frames[:, :, 0].copy()
        pts[:, 2], normals[:, 2] = 0.0, 0.0
        normals[np.linalg.norm(normals, axis=1) < 1e-3] = [1.0, 0.0, 0.0]
        frames = frames_from_normals(normals)
    elif shape == "antipodal":
        pts = np.vstack([pts, -pts])
        frames = frames_from_normals(np.vstack([frames[:, :, 0], -frames[:, :, 0]]))
    mu = draw(st.sampled_from([0.0, 1e-12, 1e-9, 1e-6, 0.05, 0.3, 1.0]))
    torsion = draw(st.sampled_from([0.0, 1e-11, 1e-9, 1e-6, 1e-3]))
    model = draw(st.sampled_from(["point", "soft", "frictionless", "mixed"]))
    if model == "mixed":
        model = list(rng.choice(["point", "soft", "frictionless"], len(pts)))
    return pts, frames, kw(mu, model=model, torsion=torsion, cone_edges=draw(st.integers(3, 8)))


@given(grasp=grasps())
@example(grasp=antipodal_box_case())      # nearly coincident wrenches: every qhull option stopped
@settings(max_examples=2000, deadline=None)
def test_force_closure_agrees_with_epsilon(grasp: tuple[np.ndarray, np.ndarray, dict]) -> None:
    pts, frames, args = grasp
    closure = force_closure(pts, frames, **args)
    quality = evaluate(pts, frames, **args)
    assert closure == (epsilon(pts, frames, **args) > 0) == quality.force_closure
    assert closure == (quality.epsilon > 0)
    if len(pts) <= 3:
        assert closure == (epsilon(pts, frames, **args, norm="Linf") > 0)


@given(seed=seeds, n=st.integers(2, 8))
@settings(max_examples=60, deadline=None)
def test_certificates_bound_the_reference_epsilon(seed: int, n: int) -> None:
    pts, frames = sphere_grasp(np.random.default_rng(seed), n)
    wrenches, _ = primitive_wrenches(pts, frames, **kw(0.3))
    check, ref = check_closure(wrenches), reference_epsilon(wrenches)
    if check.verdict is True:
        assert FORCE_CLOSURE_TOL < check.lower <= ref * (1 + 1e-9)
    elif check.verdict is False:
        assert ref <= FORCE_CLOSURE_TOL


def test_a_gws_thinner_than_tol_is_rejected_without_a_hull() -> None:
    # mu = torsion = 1e-9: the GWS is ~5e-9 thick along two directions (smallest
    # singular value 4.6e-9 > TOL), on which qhull 'Q0' stops; the least
    # singular direction still bounds it within TOL (h = 9.8e-10).
    pts, frames = equator_grasp(6)
    args = kw(1e-9, model="soft", torsion=1e-9, cone_edges=7)
    wrenches, _ = primitive_wrenches(pts, frames, **args)
    assert check_closure(wrenches).verdict is False
    assert reference_epsilon(wrenches) <= FORCE_CLOSURE_TOL
    assert epsilon(pts, frames, **args) == 0.0


@given(grasp=grasps())
@settings(max_examples=300, deadline=None)
def test_a_quick_rejection_is_the_certificates_verdict(grasp: tuple[np.ndarray, np.ndarray, dict]) -> None:
    pts, frames, args = grasp
    wrenches, _ = primitive_wrenches(pts, frames, **args)
    if quick_reject(wrenches):
        assert check_closure(wrenches).verdict is False


def _from_certificates(gws: metrics._Gws) -> float:
    """``epsilon`` of an L1 GWS the way it was before the active set came first."""
    lower = metrics._closure_lower(gws)
    return 0.0 if lower <= 0.0 else max(metrics._l1_epsilon(gws), lower)


@given(seed=seeds, n=st.integers(3, 9), mu=st.sampled_from([0.05, 0.3, 1.0]), box=st.booleans())
@settings(max_examples=200, deadline=None)
def test_the_active_set_first_gives_the_certificates_epsilon(seed: int, n: int, mu: float, box: bool) -> None:
    """Where the active set answers alone (> FULL_HULL_MAX_POINTS generators, not rejected, epsilon clear of
    the tolerance), its epsilon is the certificates' path's to its error, FACET_TOL * scale, and it
    answers 0.0 only for a grasp that is not force closure."""
    pts, frames = (box_grasp if box else sphere_grasp)(np.random.default_rng(seed), n)
    gws = metrics._gws(pts, frames, mu, np.zeros(3), R, 8, "point", "L1", 0.0)
    first, want = metrics._active_set_first(gws), _from_certificates(gws)
    if first is None:
        assert len(gws.union) <= metrics.FULL_HULL_MAX_POINTS or want <= FORCE_CLOSURE_TOL * 2
        return
    assert_close(first, want, rel=0.0, abs_=FACET_TOL * gws.scale)
    assert (first > 0) == (want > 0)
