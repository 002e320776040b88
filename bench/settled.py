"""Does the grasp the squeeze settles into predict the shake test? (issue 15)

The analytic measures describe the planned contacts; the shake test closes
the fingers dynamically on a free object, which then moves (for the Barrett
more than 1 cm in about half of the tuning trials) before any load. This
bench re-runs the shake test on the labelled uniform sample of a calibration
database (``bench/calibration.py --set tuning``), reads the contacts the
object settled into once the fingers closed (PyBullet's points, before any
load: ``planner.validation.shake.trials(on_settled=...)``), computes their
Ferrari-Canny epsilon with the hand's contact models, and prints the ROC AUC
against the shake test of the planned epsilon and of the settled epsilon,
over all grasps and over those not squeezed out while closing.

Tuning objects only: it reads ``DIR/tuning_<hand>.db``.

    python bench/settled.py --dir DIR [--hands barrett panda] [--objects 10]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

from planner.db.store import open_db
from planner.geometry.solid import load_object
from planner.plan.settle import epsilon_of
from planner.present.report import roc_auc
from planner.record.contacts import HandContacts
from planner.record.grasp import Grasp
from planner.specs.hands import load_hand
from planner.validation.shake import ShakeSettings, trials

HERE = Path(__file__).resolve().parent


def calibration():  # type: ignore[no-untyped-def]
    """bench/calibration.py as a module (its split and uniform sample)."""
    spec = importlib.util.spec_from_file_location("calibration", HERE / "calibration.py")
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules.setdefault("calibration", module)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def _keeper(seen: dict[int, HandContacts]):  # type: ignore[no-untyped-def]
    def keep(grasp: Grasp, contacts: HandContacts) -> None:
        seen[id(grasp)] = contacts
    return keep


def measure(db: Path, hand_name: str, names: list[str], per_object: int) -> np.ndarray:
    """Rows (stored label, re-run verdict, squeezed out, planned epsilon, settled epsilon)."""
    cal = calibration()
    hand = load_hand(hand_name)
    rows = []
    for name in names:
        with open_db(db, create=False, readonly=True) as store:
            grasps = sorted((g for batch in store.grasp_batches(name, hand_name) for g in batch),
                            key=lambda g: g.candidate)
        if not grasps:
            continue
        uniform = cal.uniform_sample(len(grasps), per_object, hand_name, name)
        picked = [g for g, u in zip(grasps, uniform) if u and g.validation is not None]
        obj = load_object(name)
        seen: dict[int, HandContacts] = {}
        t = time.perf_counter()
        verdicts = trials(hand, obj, picked, ShakeSettings(), on_settled=_keeper(seen))
        for g, v in zip(picked, verdicts):
            settled = seen.get(id(g), HandContacts(np.zeros((0, 3)), np.zeros((0, 3)), ()))
            rows.append((float(g.validation.success), float(v.success), float(v.reason == "squeezed_out"),  # type: ignore[union-attr]
                         g.epsilon, epsilon_of(settled, hand, obj)))
        print(f"  {hand_name} {name}: {len(picked)} grasps, {time.perf_counter() - t:.0f} s", flush=True)
    return np.array(rows, float).reshape(-1, 5)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dir", type=Path, required=True, help="the calibration DIR of a --set tuning run")
    ap.add_argument("--hands", nargs="+", default=["barrett", "panda"])
    ap.add_argument("--objects", type=int, default=10, help="the first N tuning objects")
    ap.add_argument("--per-object", type=int, default=60, help="as the calibration run's --per-object")
    args = ap.parse_args()
    names = calibration().split("tuning")[: args.objects]
    print("| hand | grasps | re-run agrees with label | AUC planned epsilon | AUC settled epsilon "
          "| not squeezed out: grasps | AUC planned | AUC settled |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for hand in args.hands:
        db = args.dir / f"tuning_{hand}.db"
        if not db.exists():
            raise SystemExit(f"no {db}: run bench/calibration.py --set tuning --dir {args.dir} first")
        r = measure(db, hand, names, args.per_object)
        kept = r[:, 2] == 0
        print(f"| {hand} | {len(r)} | {np.mean(r[:, 0] == r[:, 1]):.3f} | {roc_auc(r[:, 0], r[:, 3]):.3f} | "
              f"{roc_auc(r[:, 0], r[:, 4]):.3f} | {int(kept.sum())} | {roc_auc(r[kept, 0], r[kept, 3]):.3f} | "
              f"{roc_auc(r[kept, 0], r[kept, 4]):.3f} |", flush=True)


if __name__ == "__main__":
    main()
