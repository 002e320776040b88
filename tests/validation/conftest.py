"""The Panda and the box of the validation tests, and a firm grasp of it."""

from __future__ import annotations

import pytest

from planner.geometry.solid import load_object
from planner.plan.closing import Closed
from planner.record.grasp import Grasp
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes
from tests.validation.support import as_row, close


@pytest.fixture(scope="package")
def setup():  # type: ignore[no-untyped-def]
    hand = load_hand("panda")
    return hand, {p.name: p for p in load_preshapes(hand)}, load_object("box")


@pytest.fixture(scope="package")
def firm(setup) -> Grasp:  # type: ignore[no-untyped-def]
    """The box pinched from the top across its 4 cm faces."""
    closed = close(setup)
    assert isinstance(closed, Closed)
    return as_row(closed, "wide")
