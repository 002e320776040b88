"""The force each finger presses with in the MuJoCo trial (``mujoco.mj_contactForce``, the normal force of
the finger's contacts with the object, summed per finger), against the motor's effort: a revolute finger's
effort [N m] is a torque at its hinge, so its pad force is the effort over the hinge-to-contact lever.

For each hand, a small sweep of each object (as bench/mujoco_protocols.py's, into ``--db-dir`` unless the
database exists), then the ``--top`` best grasps of each object trialled in MuJoCo at the trial's defaults,
every step read. Printed per hand: the effort, and over the grasps whose fingers all touch once closed, the
median (and range) of each finger's steady force (the last ``STEADY`` s before gravity comes on), of its peak
while closing (the impact), of the steady motor force, and the lever effort / steady force it implies.

    python bench/pad_forces.py [--hands panda barrett allegro pr2] [--objects box] [--top 10]
    python bench/pad_forces.py --hands pr2 --set effort_scale=0.1 timestep=0.0005   # other trial settings
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from mujoco_protocols import database, top_grasps  # noqa: E402

#: [s] the steady force: the mean over this long before gravity comes on (the end of the settle).
STEADY = 0.02


class Recorder:
    """Per step of the trial's world: each finger's summed normal force [N] and each driven joint's motor force."""

    def __init__(self, world, fingers, driven) -> None:  # type: ignore[no-untyped-def]
        self.world, self.fingers, self.driven = world, fingers, driven
        self.rows: list[tuple[bool, np.ndarray, np.ndarray]] = []

    def __call__(self, m, d) -> None:  # type: ignore[no-untyped-def]
        if m is not self.world.model:
            return
        per_link = self.world.contact_force()
        forces = np.array([sum(per_link.get(link, 0.0) for link in f) for f in self.fingers])
        motors = np.array([self.world.motor_force(j) for j in self.driven])
        self.rows.append((bool(np.any(m.opt.gravity != 0.0)), forces, motors))


def trialled(hand_name: str, db: Path, objects: list[str], top: int, changes: dict[str, float]) -> list[dict]:
    from dataclasses import replace

    from planner.specs.hands import load_hand
    from planner.validation import fingers as fg
    from planner.validation import mujoco_trial
    from planner.validation.mujoco_settings import MujocoSettings
    from planner.validation.mujoco_worlds import world_for

    hand = load_hand(hand_name)
    s = replace(MujocoSettings(), **changes)
    step = mujoco.mj_step
    out = []
    for name, obj, grasps in top_grasps(db, hand_name, objects, top):
        world = world_for(hand, obj, s, obj.mass)
        for g in grasps:
            rates = fg.closing_rates(hand, g.preshape)
            driven = [j.name for j in hand.driven if rates[j.name] != 0.0]
            rec = Recorder(world, fg.fingers(hand, rates), driven)

            def recording(m, d, rec=rec):  # type: ignore[no-untyped-def]
                step(m, d)
                rec(m, d)

            mujoco.mj_step = recording
            try:
                t = mujoco_trial.trials(hand, obj, [g], s)[0]
            finally:
                mujoco.mj_step = step
            closing = [r for r in rec.rows if not r[0]]
            if not closing:
                continue
            n = max(1, int(round(STEADY / s.timestep)))
            forces = np.array([r[1] for r in closing])
            motors = np.array([r[2] for r in closing])
            out.append({"object": name, "rank": g.rank, "reason": t.reason,
                        "steady": forces[-n:].mean(0), "peak": forces.max(0), "motor": np.abs(motors[-n:]).mean(0)})
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hands", nargs="*", default=["panda", "barrett", "allegro", "pr2"])
    parser.add_argument("--objects", nargs="*", default=["box"])
    parser.add_argument("--top", type=int, default=10)
    parser.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE",
                        help="MujocoSettings fields (numbers) other than the defaults, e.g. effort_scale=0.1 "
                             "timestep=0.0005")
    parser.add_argument("--db-dir", type=Path, default=Path("out"))
    args = parser.parse_args()
    from planner.specs.hands import load_hand

    print("| hand | effort | grasps (all fingers touching) | steady force per finger [N] | peak while closing [N] "
          "| steady motor force | mean motor force / steady force | verdicts |")
    print("|---|---|---|---|---|---|---|---|")
    for hand in args.hands:
        db = database(hand, tuple(args.objects), args.db_dir)
        changes = {k: float(v) for k, v in (a.split("=", 1) for a in args.set)}
        rows = trialled(hand, db, args.objects, args.top, changes)
        reasons = {k: sum(r["reason"] == k for r in rows) for k in sorted({r["reason"] for r in rows})}
        every_peak = np.concatenate([r["peak"] for r in rows]) if rows else np.zeros(1)
        touching = [r for r in rows if np.all(r["steady"] > 0.0)]
        if not touching:
            print(f"| {hand} | | 0 of {len(rows)} | | {np.median(every_peak):.3g} (all grasps) | | | {reasons} |")
            continue
        steady = np.concatenate([r["steady"] for r in touching])
        peak = np.concatenate([r["peak"] for r in touching])
        motor = np.concatenate([r["motor"] for r in touching])
        effort = load_hand(hand).actuators.effort * changes.get("effort_scale", 1.0)
        unit = "N m" if any(j.kind == "revolute" for j in load_hand(hand).driven) else "N"
        lever = np.concatenate([r["motor"].mean() / r["steady"] for r in touching])

        def med(a: np.ndarray) -> str:
            return f"{np.median(a):.3g} ({np.min(a):.3g}-{np.max(a):.3g})"

        print(f"| {hand} | {effort:.3g} {unit} | {len(touching)} of {len(rows)} | {med(steady)} | {med(peak)} | "
              f"{med(motor)} | {med(lever)} | {reasons} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
