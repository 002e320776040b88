"""bench/calibration.py: it never touches the held-out objects unless told
it is the one final evaluation, and it calls the shake test the way
``grasp validate`` does (planner.validation.run), whatever the trial's
settings type is called."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

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
