"""bench/grip.py measures as a unit of work runs: with one BLAS thread."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import grip as grip_bench  # noqa: E402
from threadpoolctl import threadpool_info  # noqa: E402

from planner import api  # noqa: E402
from planner.plan import grip  # noqa: E402
from planner.specs.hands import load_hand  # noqa: E402
from planner.specs.preshapes import load_preshapes  # noqa: E402


def test_the_grip_is_measured_with_one_blas_thread(box_db: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """It measured with every core's BLAS thread, which a unit never has (`run_unit` holds one_blas_thread):
    under load the second thread's spinning overstated the Barrett's grip."""
    threads: list[int] = []
    measure = grip.measure

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        threads.append(max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"))
        return measure(*args, **kwargs)

    monkeypatch.setattr(grip, "measure", counted)
    hand = load_hand("panda")
    grasps = api.best("box", "panda", db_path=box_db, top=3)
    row = grip_bench.timed(hand, {s.name: s for s in load_preshapes(hand)}, "box", grasps)
    assert row["grasps"] == len(threads) >= 1 and set(threads) == {1}
