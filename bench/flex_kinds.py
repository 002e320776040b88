"""The poses the MuJoCo trial holds and FleX drops, sorted into kinds by FleX's own record (issue 26 item 3).

Tuning objects only: bench/trial_update.py's tried set (acronym_eval's 200-pose sample of the tuning files,
every closed pose tried in MuJoCo at the file's pose, its cached records; ``--code``: the re-scoring cache) and
FleX's record of each pose (``grasps/qualities/flex/object_motion_during_*``, read for this comparison only).
Printed, for "MuJoCo holds, FleX drops" against "both hold" and "both drop":

- the kinds: **flung** (FleX's object moved at least :data:`FLUNG` while FleX closed: at least 2.5 times the motion
  of FleX's own drop threshold, before any shake), **wide** (not flung, closed width at least :data:`WIDE`: the
  fingers across a whole body), **narrow** (the rest), each with FleX's and MuJoCo's median motions, where the
  contacts sit along the fingers and how FleX labels the pose's near-identical neighbours (other rows of the file
  whose tool centre point lies within :data:`NEAR` and whose hand turns by less than :data:`NEAR_ANGLE`, either
  finger first);
- how often each engine holds by closed width, and by the object's mass among wide grasps FleX did not fling
  (a drop by weight against a grip grows with the weight);
- FleX's share held approaching along the object's -y and +y, raw and at the width mix of both.

    python bench/flex_kinds.py --dev ../shared/labelled/acronym_dev --code 7e671bb8f46f
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import acronym_eval as ae  # noqa: E402
import trial_update as tu  # noqa: E402

#: [m], [rad] FleX's closing motion from which its object counts as flung (FleX's label drops at 2 cm / 0.2 rad of
#: shaking motion: bench/trial_inputs.py's FLEX_THRESHOLDS).
FLUNG = (0.05, 0.5)
#: [m] the closed width from which a grasp counts as wide.
WIDE = 0.05
#: [m], [rad] near-identical poses of a file: tool centre points this close, hands turned by less than this.
NEAR, NEAR_ANGLE = 0.005, np.radians(10.0)
WIDTHS = (0.0, 0.02, 0.035, 0.05, 0.065, 0.1)
MASSES = (0.0, 0.01, 0.02, 0.04, 0.1, 10.0)


def table(dev: Path, code: str) -> dict[str, np.ndarray]:
    """Per closed, tried pose: FleX's label and motions (n, 4), MuJoCo's verdict, record (n, 5), width [m],
    contact depth past the TCP [m], mass [kg], file, and FleX's mean label of its near-identical rows (nan: none)."""
    results, data, records = tu.tried_set(dev, False, 200, 200, 1, "mujoco", code, True)
    cols: dict[str, list] = {k: [] for k in ("fm", "width", "depth", "mass", "file", "near", "approach")}
    for r in results:
        with h5py.File(r.path, "r") as f:
            q = f["grasps/qualities/flex"]
            fm = np.column_stack([np.asarray(q[f"object_motion_during_{ph}_{k}"]).reshape(-1)
                                  for ph in ("closing", "shaking") for k in ("linear", "angular")])
            poses, labels = np.asarray(f["grasps/transforms"]), np.asarray(q["object_in_gripper"]).reshape(-1)
            mass = float(f["object/mass"][()])
        tcp = poses[:, :3, 3] + 0.1034 * poses[:, :3, 2]  # ACRONYM's Panda: the fingers' centre 10.34 cm out
        for g in r.grasps:
            row = int(r.rows[g.candidate])
            local = (np.asarray(g.contacts.points) - np.asarray(g.pose)[:3, 3]) @ np.asarray(g.pose)[:3, :3]
            cols["fm"].append(fm[row])
            cols["width"].append(g.width or np.nan)
            cols["depth"].append(float(np.mean(local[:, 2])) - 0.1034 if len(local) else np.nan)
            cols["mass"].append(mass)
            cols["file"].append(r.path.stem)
            cols["approach"].append(poses[row, :3, 2])
            cols["near"].append(near_label(poses, labels, tcp, row))
    out = {k: np.array(v) for k, v in cols.items()}
    out["flex"], out["held"] = data.labels.astype(int), data.verdicts.astype(int)
    out["mj"] = np.array([t[3:8] for t in records], float)
    return out


def near_label(poses: np.ndarray, labels: np.ndarray, tcp: np.ndarray, row: int) -> float:
    """FleX's mean label of the rows near-identical to ``row`` (nan: none); a hand turned by half a turn about
    its approach is the same grasp (the fingers swapped)."""
    near = np.flatnonzero(np.linalg.norm(tcp - tcp[row], axis=1) < NEAR)
    near = near[near != row]
    if not len(near):
        return float("nan")
    rel = np.einsum("ji,njk->nik", poses[row, :3, :3], poses[near, :3, :3])  # (k, 3, 3) R_row^T R_j
    trace = np.trace(rel, axis1=1, axis2=2)
    swapped = trace - 2 * (rel[:, 0, 0] + rel[:, 1, 1])  # trace of rel @ diag(-1, -1, 1)
    angle = np.arccos(np.clip((np.maximum(trace, swapped) - 1) / 2, -1, 1))
    near = near[angle < NEAR_ANGLE]
    return float(labels[near].mean()) if len(near) else float("nan")


def rate(x: np.ndarray, m: np.ndarray) -> str:
    return f"{x[m].mean():.2f} ({int(m.sum())})" if m.any() else "- (0)"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dev", type=Path, default=ae.DEV)
    ap.add_argument("--code", default=None, help="acronym_eval's cache key of the re-scoring code")
    a = ap.parse_args()
    t = table(a.dev, a.code or ae.source_hash())
    flex, held, fm, mj, w = t["flex"], t["held"], t["fm"], t["mj"], t["width"]
    flung = (fm[:, 0] >= FLUNG[0]) | (fm[:, 1] >= FLUNG[1])
    wide = w >= WIDE
    outcomes = {"MuJoCo holds, FleX drops": (held == 1) & (flex == 0), "both hold": (held == 1) & (flex == 1),
                "both drop": (held == 0) & (flex == 0)}
    print(f"{len(flex)} tried poses; MuJoCo's verdict agrees with FleX on {np.mean(held == flex):.4f}")
    for name, o in outcomes.items():
        print(f"{name}: {int(o.sum())}")
        for kind, k in (("flung", flung), ("wide", ~flung & wide), ("narrow", ~flung & ~wide)):
            m = o & k
            near = m & ~np.isnan(t["near"])
            near_rate = float(np.mean(t["near"][near])) if near.any() else float("nan")
            print(f"  {kind:6s} {int(m.sum()):5d}: FleX closing {100 * np.median(fm[m, 0]):.1f} cm "
                  f"{np.median(fm[m, 1]):.2f} rad, shaking {100 * np.median(fm[m, 2]):.1f} cm "
                  f"{np.median(fm[m, 3]):.2f} rad; MuJoCo closing {1000 * np.median(mj[m, 0]):.1f} mm, shaking "
                  f"{1000 * np.median(mj[m, 2]):.1f} mm; width {1000 * np.median(w[m]):.0f} mm; contacts "
                  f"{1000 * np.median(t['depth'][m]):+.1f} mm past the TCP; mass "
                  f"{1000 * np.median(t['mass'][m]):.0f} g; near-identical rows held in FleX {near_rate:.2f} "
                  f"({int(near.sum())} poses)")
    print("held by closed width (FleX / MuJoCo, poses), FleX's object not flung:")
    for lo, hi in zip(WIDTHS[:-1], WIDTHS[1:]):
        m = ~flung & (w >= lo) & (w < hi)
        print(f"  {1000 * lo:3.0f}-{1000 * hi:3.0f} mm: {rate(flex, m)} / {rate(held, m)}")
    print("wide grasps FleX did not fling, held by the object's mass (FleX / MuJoCo):")
    for lo, hi in zip(MASSES[:-1], MASSES[1:]):
        m = ~flung & wide & (t["mass"] >= lo) & (t["mass"] < hi)
        print(f"  {1000 * lo:4.0f}-{1000 * hi:5.0f} g: {rate(flex, m)} / {rate(held, m)}")
    ay = t["approach"][:, 1]
    down, up = ay < -0.7, ay > 0.7
    mixed = []
    for side in (down, up):  # each side's rate per width band, weighted by both sides' poses in the band
        bands = [((w >= lo) & (w < hi)) for lo, hi in zip(WIDTHS[:-1], WIDTHS[1:])]
        weights = [int(((down | up) & b).sum()) if (side & b).any() else 0 for b in bands]
        mixed.append(sum(n * flex[side & b].mean() for n, b in zip(weights, bands) if n) / sum(weights))
    print(f"FleX holds approaching along -y {rate(flex, down)}, +y {rate(flex, up)}; at the width mix of both: "
          f"{mixed[0]:.2f} / {mixed[1]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
