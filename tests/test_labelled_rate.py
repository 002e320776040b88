"""bench/labelled_rate.py's repeated runs: the least CPU of runs that found the same grasps, and an error where
they did not (the work must be the same every time) or where one failed."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from labelled_rate import _least, group_figures  # noqa: E402


def run(sweep: float, trial: float, fc: int = 10) -> dict:
    return {"candidates": 100, "grasps": 12, "fc": fc, "tested": 5, "held": 4, "sweep": sweep, "trial": trial,
            "error": None}


def test_the_least_cpu_of_runs_that_found_the_same() -> None:
    best = _least([run(2.0, 0.05), run(1.5, 0.07), run(1.8, 0.04)])
    assert (best["sweep"], best["trial"]) == (1.5, 0.04)
    assert best["sweeps"] == [2.0, 1.5, 1.8] and best["fc"] == 10
    assert group_figures([best])["FC/s"] == 10 / 1.5


def test_runs_that_disagree_or_fail_are_an_error() -> None:
    assert "different grasps" in _least([run(2.0, 0.05), run(1.5, 0.05, fc=11)])["error"]
    assert _least([run(2.0, 0.05), {"error": "child failed"}])["error"] == "child failed"
    assert group_figures([_least([run(2.0, 0.05), run(1.5, 0.05, fc=11)])]) == {}
