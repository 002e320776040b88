"""bench/settle_rank.py ranks as the database does: force closure as planned or once squeezed first."""

import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from settle_rank import ranked  # noqa: E402

from planner.record.measures import Measures  # noqa: E402
from tests.helpers import made_up  # noqa: E402


def test_a_grasp_force_closure_once_squeezed_ranks_with_the_force_closure_ones() -> None:
    held = Measures(3.0, 4.0, 0.01, 0.01, 1.0, ())
    weak = Measures(0.0, 0.0, 0.01, 0.01, 0.1, ())
    grasps = [replace(made_up(0, 0.0, fc=False), measures=replace(held, squeezed_force_closure=False)),  # top score
              replace(made_up(1, 0.0, fc=False), measures=replace(weak, squeezed_force_closure=True)),
              replace(made_up(2, 0.01), measures=weak)]
    assert ranked(grasps) == [2, 1, 0]  # planned force closure alone ranked 0 second
