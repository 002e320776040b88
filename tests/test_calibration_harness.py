"""bench/calibration.py: it never touches the held-out objects unless told
it is the one final evaluation, and it calls the shake test the way
``grasp validate`` does (planner.validation.run), whatever the trial's
settings type is called."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomllib

BENCH = Path(__file__).resolve().parents[1] / "bench"


def harness():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("calibration", BENCH / "calibration.py")
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules.setdefault("calibration", module)  # its dataclasses look their module up
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def test_held_out_needs_the_explicit_final_flag(tmp_path: Path) -> None:
    out = tmp_path / "cal"
    run = subprocess.run([sys.executable, str(BENCH / "calibration.py"), "--set", "held_out", "--dir", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode != 0
    assert "--final-held-out" in run.stderr
    assert not out.exists()  # refused before anything was swept or written


def test_only_objects_of_the_chosen_set_and_no_tuning_on_held_out(tmp_path: Path) -> None:
    held = tomllib.loads((BENCH / "calibration_split.toml").read_text())["held_out"][0]
    base = [sys.executable, str(BENCH / "calibration.py"), "--dir", str(tmp_path / "cal")]
    run = subprocess.run([*base, "--set", "tuning", "--only", held], capture_output=True, text=True, timeout=120)
    assert run.returncode != 0 and "not in the tuning set" in run.stderr
    run = subprocess.run([*base, "--set", "held_out", "--final-held-out", "--cv"], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode != 0 and "tuning set only" in run.stderr


def test_the_trial_settings_are_the_validation_tasks_own() -> None:
    from planner.validation import run

    settings = harness().trial_settings()
    assert type(settings).__name__ in ("TrialSettings", "ShakeSettings")
    assert settings == type(settings)()  # the trial's defaults, as `grasp validate` uses them
    assert run.Task.__dataclass_fields__["trial"].type.split(" ")[0] == type(settings).__name__


def test_the_uniform_sample_is_seeded_and_the_right_size() -> None:
    h = harness()
    a, b = h.uniform_sample(300, 100, "panda", "box"), h.uniform_sample(300, 100, "panda", "box")
    assert (a == b).all() and a.sum() == 100
    assert not (a == h.uniform_sample(300, 100, "panda", "mug")).all()
    assert h.uniform_sample(40, 100, "panda", "box").all()  # all of them where fewer


def test_jittered_copies_move_by_the_asked_distance_and_angle_and_are_seeded() -> None:
    from scipy.spatial.transform import Rotation

    from planner.record.contacts import HandContacts
    from planner.record.grasp import Grasp

    h = harness()
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("xyz", [0.3, -0.2, 1.0]).as_matrix()
    pose[:3, 3] = [0.01, 0.02, 0.1]
    empty = HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ())
    g = Grasp(object="box", hand="barrett", preshape="wrap", candidate=7, seed=3, approach_point=np.zeros(3),
              approach_dir=np.array([0.0, 0.0, 1.0]), roll=0.0, standoff=0.0, pose=pose, open_joints={},
              closed_joints={}, width=None, contacts=empty, epsilon=0.0, volume=0.0, force_closure=False, id=11)
    copies = h.jittered(g, 5, 1.5, 2.0)
    assert len(copies) == 5 and all(c.id == 11 and c.validation is None for c in copies)
    for c in copies:
        assert np.linalg.norm(c.pose[:3, 3] - pose[:3, 3]) == pytest.approx(1.5e-3, rel=1e-9)
        turn = Rotation.from_matrix(c.pose[:3, :3] @ pose[:3, :3].T).magnitude()
        assert np.rad2deg(turn) == pytest.approx(2.0, rel=1e-6)
    again = h.jittered(g, 5, 1.5, 2.0)
    assert all(np.array_equal(a.pose, b.pose) for a, b in zip(copies, again))
    assert len({tuple(c.pose[:3, 3]) for c in copies}) == 5


def test_the_joint_cross_validation_finds_one_rule_that_ranks_both_hands() -> None:
    """Hand "a": held iff its settled epsilon is high (its planned epsilon is
    noise); hand "b": no settled epsilon, held iff its planned epsilon is high.
    The shared rule must weigh the settled epsilon and keep epsilon."""
    from planner.record.contacts import HandContacts
    from planner.record.grasp import Grasp, Trial
    from planner.record.measures import Measures

    h = harness()
    rng = np.random.default_rng(5)
    empty = HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ())

    def pool(hand: str, name: str) -> object:
        grasps = []
        for i in range(40):
            eps, settled = rng.uniform(0.0, 0.2), rng.uniform(0.0, 0.2)
            held = (settled if hand == "a" else eps) > 0.1
            m = Measures(2.0, 3.0, 0.01, 0.01, 1.0, (), settled if hand == "a" else None)
            grasps.append(Grasp(object=name, hand=hand, preshape="p", candidate=i, seed=0, approach_point=np.zeros(3),
                                approach_dir=np.array([0.0, 0.0, 1.0]), roll=0.0, standoff=0.0, pose=np.eye(4),
                                open_joints={}, closed_joints={}, width=None, contacts=empty, epsilon=eps, volume=0.0,
                                force_closure=eps > 0, id=i, validation=Trial(held, 2, 0, 0, 0, 0), measures=m))
        return h.Pool(name, grasps, np.zeros(40), np.ones(40, bool))

    by_hand = {hand: [pool(hand, f"o{k}") for k in range(10)] for hand in ("a", "b")}
    out = h.cross_validate_joint(by_hand, h.RankingRule(reach_weight=0.0, success_weight=0.0))
    assert len(out["chosen"]) == 5 and all(c["settled_weight"] >= 10.0 and c["eps_weight"] > 0 for c in out["chosen"])
    # pooled over folds whose rules differ (settled_weight 10 or 30 here), so below 1 for "a"
    assert out["a"]["auc"] > 0.85 and out["b"]["auc"] > 0.95
    assert out["a"]["top1"] == out["b"]["top1"] == 1.0
