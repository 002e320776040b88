"""Recompute the split of the ACRONYM dev set and check it equals bench/acronym_split.toml.

The split was fixed on 2026-12-02 at ~01:35 UTC, BEFORE anything was tuned or measured against
these labels (issue 26). The unit is the object (the mesh id): an object seen at two scales is in
one side only. Within each category the objects are ordered by sha256(salt + ":" + id) and the
first third (rounded up, at least one) is held out: measured once at the end, never tuned on.
``--check`` exits 1 if the file differs; ``--dev DIR`` names the dev folder
(default ../shared/labelled/acronym_dev beside the repository).
"""

from __future__ import annotations

import argparse
import hashlib
import math
import sys
from collections import defaultdict
from pathlib import Path

import tomllib

FILE = Path(__file__).with_name("acronym_split.toml")
DEV = Path(__file__).resolve().parents[2] / "shared" / "labelled" / "acronym_dev"


def objects(dev: Path) -> dict[str, list[str]]:
    """Category -> sorted object ids found in ``dev/grasps``."""
    found: dict[str, set[str]] = defaultdict(set)
    for path in (dev / "grasps").glob("*.h5"):
        category, object_id, _scale = path.stem.split("_", 2)
        found[category].add(object_id)
    return {category: sorted(ids) for category, ids in sorted(found.items())}


def split(salt: str, by_category: dict[str, list[str]]) -> tuple[list[str], list[str]]:
    """(tuning, held_out) as sorted lists of ``Category_id``."""
    tuning, held = [], []
    for category, ids in by_category.items():
        order = sorted(ids, key=lambda i: hashlib.sha256(f"{salt}:{i}".encode()).hexdigest())
        n_held = max(1, math.ceil(len(order) / 3))
        held += [f"{category}_{i}" for i in order[:n_held]]
        tuning += [f"{category}_{i}" for i in order[n_held:]]
    return sorted(tuning), sorted(held)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--dev", type=Path, default=DEV)
    parser.add_argument("--write", action="store_true", help="write the file (done once, when the split was fixed)")
    args = parser.parse_args()
    salt = "grasp-planner acronym dev split 2026-12-02"
    tuning, held = split(salt, objects(args.dev))
    if args.write:
        FILE.write_text(
            "# The split of ../shared/labelled/acronym_dev (issue 26), fixed on 2026-12-02 ~01:35 UTC BEFORE\n"
            "# anything was tuned on these labels: per category, objects ordered by sha256(salt + ':' + id),\n"
            "# the first third (at least one) held out. Reproduce: python bench/acronym_split.py --check.\n"
            "# Never tune on `held_out`.\n"
            f'salt = "{salt}"\n'
            f"tuning = {tuning!r}\n".replace("'", '"')
            + f"held_out = {held!r}\n".replace("'", '"'))
    data = tomllib.loads(FILE.read_text())
    same = tuning == data["tuning"] and held == data["held_out"] and salt == data["salt"]
    print(f"tuning {len(tuning)} objects, held out {len(held)}: file {'matches' if same else 'DIFFERS'}")
    return 0 if same or not args.check else 1


if __name__ == "__main__":
    sys.exit(main())
