"""A grasp's ``width`` [m]: how far apart the fingers are at its closed joints.

A hand that declares ``width_links`` (hand.toml: the PR2's ``left_tip`` and
``right_tip``) gets the gap between those two links' collision shapes, read
in the hand's own frame (the same wherever the hand is) with python-fcl
(:class:`planner.sim.fcl.LinkGap`), negative where the pads overlap (the
PR2's at joints 0, -10 mm). The real PR2's gripper command takes the gap
between its pads, which a linkage keeps parallel; the URDF's fingers are
plain hinges whose pads turn with them, so the gap is the pads' closest
approach, at their inner ends: an object held at the fingertips is thicker
there (box and duck, 2026-12-06: by a median 12-13 mm, up to 27 mm).
A self-centring parallel jaw (the Panda) that declares none gets its opening
(:meth:`~planner.specs.hand_spec.HandSpec.opening`, the sum of its prismatic
joints); any other hand None.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from pathlib import Path

from planner.specs.hand_spec import HandSpec
from planner.specs.urdf import LinkChain, link_chain, load_model


def closed_width(hand: HandSpec, closed_joints: Mapping[str, float]) -> float | None:
    """[m] the width of a grasp closed at ``closed_joints`` {joint: rad or m} (mimics left out follow their
    coupling): the gap between the hand's ``width_links``, else a self-centring jaw's opening, else None."""
    if hand.width_links is not None:
        return pad_gap(hand, closed_joints)
    return hand.opening(closed_joints) if hand.centering else None


def pad_gap(hand: HandSpec, joints: Mapping[str, float]) -> float:
    """[m] the signed gap between the collision shapes of ``hand.width_links`` at ``joints`` (negative:
    overlap); the hand must declare them."""
    if hand.width_links is None:
        raise ValueError(f"hand '{hand.name}' declares no width_links")
    return _pads(hand.urdf, *hand.width_links)(hand.posture(joints))


class _Pads:
    """Two links' chains from the hand's root and the gap between their shapes."""

    def __init__(self, urdf: Path, a: str, b: str) -> None:
        from planner.sim.fcl import LinkGap  # python-fcl loads only for the hands that declare pads

        model = load_model(urdf)
        self.chains: tuple[LinkChain, LinkChain] = (link_chain(model, a), link_chain(model, b))
        self.gap = LinkGap(urdf, a, b)

    def __call__(self, joints: Mapping[str, float]) -> float:
        frame_a, frame_b = (chain.frame(joints) for chain in self.chains)
        return self.gap(frame_a, frame_b)


@cache
def _pads(urdf: Path, a: str, b: str) -> _Pads:
    """The :class:`_Pads` of a hand (built once per process: its hulls and chains)."""
    return _Pads(urdf, a, b)

