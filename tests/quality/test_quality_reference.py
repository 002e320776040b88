"""The fast paths against the plain qhull reference (planner.quality.reference)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from quality_support import REFERENCE, assert_close, box_grasp, seeds, sphere_grasp

from planner.quality import FORCE_CLOSURE_TOL, epsilon, evaluate, primitive_wrenches, volume
from planner.quality.reference import reference_epsilon, reference_linf_epsilon, reference_volume


def random_case(seed: int, n: int) -> tuple[np.ndarray, np.ndarray, dict]:
    rng = np.random.default_rng(seed)
    pts, frames = (box_grasp if rng.random() < 0.5 else sphere_grasp)(rng, n)
    args = {"mu": rng.uniform(0.05, 1.2), "center": rng.normal(size=3) * 0.01,
                "torque_scale": rng.uniform(0.02, 0.2), "cone_edges": int(rng.integers(4, 9))}
    return pts, frames, args


def compare(fast: float, ref: float) -> None:
    """Equal to REFERENCE relative when the reference holds a ball clearly
    larger than the closure tolerance; both ~0 otherwise."""
    if ref > 10 * FORCE_CLOSURE_TOL:
        assert_close(fast, ref, rel=REFERENCE, abs_=0.0)
    else:
        assert fast <= 10 * FORCE_CLOSURE_TOL


@given(seed=seeds, n=st.integers(2, 16))
@settings(max_examples=50, deadline=None)
def test_epsilon_and_evaluate_match_the_reference(seed: int, n: int) -> None:
    pts, frames, args = random_case(seed, n)
    wrenches, _ = primitive_wrenches(pts, frames, **args)
    ref = reference_epsilon(wrenches)
    compare(epsilon(pts, frames, **args), ref)
    quality = evaluate(pts, frames, **args)
    compare(quality.epsilon, ref)
    if quality.force_closure:
        assert_close(quality.volume, reference_volume(wrenches), rel=REFERENCE)
    assert_close(volume(pts, frames, **args), reference_volume(wrenches), rel=REFERENCE)


@given(seed=seeds)
@settings(max_examples=4, deadline=None)
def test_sixteen_contacts_match_the_reference(seed: int) -> None:
    pts, frames, args = random_case(seed, 16)
    wrenches, _ = primitive_wrenches(pts, frames, **args)
    compare(epsilon(pts, frames, **args), reference_epsilon(wrenches))


@given(seed=seeds, soft=st.booleans())
@settings(max_examples=15, deadline=None)
def test_linf_epsilon_matches_brute_force_minkowski_sum(seed: int, soft: bool) -> None:
    pts, frames, args = random_case(seed, 3)
    args = args | {"cone_edges": 4, "model": "soft" if soft else "point", "torsion": 0.004}
    wrenches, owner = primitive_wrenches(pts, frames, **args)
    compare(epsilon(pts, frames, **args, norm="Linf"), reference_linf_epsilon(wrenches, owner))
