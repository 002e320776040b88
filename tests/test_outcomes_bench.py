"""bench/outcomes.py: every candidate of a unit counted under exactly one outcome, the grasps the sweep's own."""

import sys
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

from outcomes import outcome, profile_unit  # noqa: E402

from planner.plan import unit  # noqa: E402
from planner.plan.sweep import SweepSettings  # noqa: E402
from planner.plan.unit import BUDGET, UnitSpec, run_unit  # noqa: E402


def test_an_outcome_from_the_counters_and_the_grasps() -> None:
    fc, other = SimpleNamespace(force_closure=True), SimpleNamespace(force_closure=False)
    assert outcome(Counter(a=1), Counter(a=1), [other, fc], 1) == "FC"
    assert outcome(Counter(), Counter(), [fc, other], 1) == "closed_notFC"
    assert outcome(Counter(overlap=3), Counter(overlap=4, cone=1), [], 0) == "none"
    assert outcome(Counter(overlap=3), Counter(overlap=4), [fc], 1) == "rej:overlap"
    assert outcome(Counter(overlap=3), Counter(overlap=4, budget=90), [], 0) == "rej:overlap"  # the last tried


def test_the_budget_reason_is_the_unit_modules() -> None:
    assert outcome.__globals__["BUDGET"] == BUDGET


def test_every_candidate_counted_once_and_the_sweep_unchanged() -> None:
    tried = unit._tried
    row = profile_unit("box", "panda", 4)
    assert unit._tried is tried  # the instrumentation is gone
    assert sum(row["count"].values()) == row["candidates"] > 0
    assert row["count"].get("FC", 0) == row["fc"] > 0
    assert {k[4:]: v for k, v in row["count"].items() if k.startswith("rej:")} == row["rejected"]
    plain = run_unit(UnitSpec("box", "panda", SweepSettings(approaches=4, chunk=0, reach_placements=0), 0))
    assert (plain.candidates, len(plain.grasps), plain.force_closure) == (row["candidates"], row["grasps"], row["fc"])


def test_stages_and_query_kinds_of_a_mesh_file_at_a_given_mass(tmp_path: Path) -> None:
    """A mesh file (the peer's object is one) at a given mass and friction: every stage timed, every query of
    the object's mesh counted by the stage that asked, and the instrumentation gone afterwards."""
    from planner.plan.contact_reading import ContactReading
    from planner.sim import Sim

    path = tmp_path / "brick.obj"
    trimesh.creation.box((0.05, 0.03, 0.08)).export(path)
    touching, rows = ContactReading._touching, Sim._rows
    row = profile_unit(str(path), "panda", 4, tmp_path / "stats", mass=0.5, friction=0.5)
    assert ContactReading._touching is touching and Sim._rows is rows
    assert row["fc"] > 0 and (tmp_path / "stats" / "brick_panda.prof").is_file()
    assert {"closing", "contact query", "patches", "epsilon", "grip", "local_sdf", "resistance"} <= set(row["stages"])
    kinds = {kind.split(":")[0] for kind in row["queries"] if ": mesh" in kind}
    assert kinds == {"closing", "contact query"}
    assert all(n > 0 and cpu >= 0.0 for n, _, cpu in row["queries"].values())
