"""Recompute the calibration split and check it equals bench/calibration_split.toml.

The split was fixed before any score was tuned (issue 15): 100 objects, the 7
built-ins and random_000..random_092, ordered by sha256(salt + ":" + name);
the first 50 are the held-out set.  ``--check`` exits 1 if the file differs.

A second held-out set, ``held_out_2``, was fixed at 2026-11-23 ~11:00 UTC,
after the first held-out set had been evaluated once and BEFORE the second
round of tuning (Barrett): 50 objects of random_093..random_999 ordered by
sha256(salt_2 + ":" + name). No object of it was ever swept before.

A third held-out set, ``held_out_3``, was fixed at 2026-11-23 ~14:05 UTC,
after ``held_out_2`` had been evaluated once and BEFORE the third round of
tuning (the settled epsilon): 50 objects of random_093..random_999 not in
``held_out_2``, ordered by sha256(salt_3 + ":" + name).

A fourth held-out set, ``held_out_4``, was fixed at 2026-12-05 ~04:30 UTC,
BEFORE any of its objects was swept, to widen the independent-protocol check
of issue 26 (bench/mujoco_protocols.py --split held_out_4): 50 objects of
random_093..random_999 in no earlier list and none of the objects the
Barrett's rule was tuned on (random_300..random_323) or the protocol check
began with (random_100..random_107), ordered by sha256(salt_4 + ":" + name).
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import tomllib

FILE = Path(__file__).with_name("calibration_split.toml")
BUILTINS = ("mug", "duck", "teddy", "bunny", "box", "cylinder", "sphere")
RANDOM = 93
HELD_OUT = 50
RANDOM_2 = range(RANDOM, 1000)


def split(salt: str) -> tuple[list[str], list[str]]:
    names = [*BUILTINS, *(f"random_{i:03d}" for i in range(RANDOM))]
    order = sorted(names, key=lambda n: hashlib.sha256(f"{salt}:{n}".encode()).hexdigest())
    return sorted(order[HELD_OUT:]), sorted(order[:HELD_OUT])


def split_2(salt: str) -> list[str]:
    names = [f"random_{i:03d}" for i in RANDOM_2]
    return sorted(sorted(names, key=lambda n: hashlib.sha256(f"{salt}:{n}".encode()).hexdigest())[:HELD_OUT])


def split_3(salt: str, taken: list[str]) -> list[str]:
    names = [f"random_{i:03d}" for i in RANDOM_2 if f"random_{i:03d}" not in taken]
    return sorted(sorted(names, key=lambda n: hashlib.sha256(f"{salt}:{n}".encode()).hexdigest())[:HELD_OUT])


#: Objects chosen on or looked at before ``held_out_4`` was drawn: the Barrett rule's tuning objects
#: (bench/barrett_rule.py) and the first objects of bench/mujoco_protocols.py.
USED_4 = tuple(f"random_{i}" for i in (*range(300, 324), *range(100, 108)))


def split_4(salt: str, taken: list[str]) -> list[str]:
    return split_3(salt, [*taken, *USED_4])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args()
    data = tomllib.loads(FILE.read_text())
    tuning, held = split(data["salt"])
    held_2 = split_2(data["salt_2"])
    held_3 = split_3(data["salt_3"], held_2)
    held_4 = split_4(data["salt_4"], [*held_2, *held_3])
    same = (tuning == data["tuning"] and held == data["held_out"] and held_2 == data["held_out_2"]
            and held_3 == data["held_out_3"] and held_4 == data["held_out_4"])
    print(f"tuning {len(tuning)} objects, held out {len(held)}, second held out {len(held_2)}, "
          f"third held out {len(held_3)}, fourth held out {len(held_4)}: "
          f"file {'matches' if same else 'DIFFERS'}")
    return 0 if same or not args.check else 1


if __name__ == "__main__":
    sys.exit(main())
