"""Draw chosen poses of one ACRONYM grasp file with the hand closed, titled with FleX's own record (issue 26 item 3).

Where the MuJoCo trial and FleX disagree, look before calling either engine wrong: each row of the picture is
one pose of the file (``--rows``, rows of the file), the hand at the file's pose (what FleX simulated) with its
fingers where the planner's closing stops them (``grasp import --rescore``), the view cropped about the
contacts; the title gives FleX's label and its record of the object's motion while closing and while shaking
(``grasps/qualities/flex/object_motion_during_*``), the closed width, where the contacts sit along the fingers
(mm past the tool centre point towards the tips) and the approach in the object's frame; with ``--mujoco`` the
MuJoCo trial's verdict and motions at that pose (the file's mass and friction, default MujocoSettings).
Tuning objects only (bench/acronym_split.toml); the pictures show the dev meshes: write them outside the
repository.

    python bench/flex_pose.py Mug_5b515d0b0c6740d5c5fe7f65b41f3b19_0.0165 --rows 503 1718 --mujoco --out /tmp/a.png
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import acronym_eval as ae  # noqa: E402
import acronym_mujoco as am  # noqa: E402

from planner.datasets import importer  # noqa: E402
from planner.present.render import View, grasp_views, save_sheet  # noqa: E402
from planner.validation import mujoco_trial  # noqa: E402
from planner.validation.mujoco_settings import MujocoSettings  # noqa: E402

#: [px] the least half side of a cropped view, and the crop's half side per pixel from the contacts' centre to
#: the farthest contact or the centre of mass (the object and the pads in view, the rest of the hand cut).
MIN_HALF, SPREAD = 110, 2.2
#: (w, h) [px] of a view before cropping (the whole hand in view, so the object is small in it).
RENDER_SIZE = (1280, 1040)
AXES = ("+x", "-x", "+y", "-y", "+z", "-z")


def tuning_file(dev: Path, name: str) -> Path:
    """The tuning file whose stem starts with ``name`` (exactly one); held-out objects are refused."""
    files = [p for p in ae.dev_files(dev, False, None) if p.stem.startswith(name)]
    if len(files) != 1:
        raise SystemExit(f"flex_pose: {name!r} names {len(files)} tuning files (held-out objects are refused); "
                         f"give more of the file's stem")
    return files[0]


def flex_record(path: Path, rows: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """(labels (k,), motions (k, 4): closing linear [m], angular [rad], shaking linear, angular) of ``rows``."""
    with h5py.File(path, "r") as f:
        q = f["grasps/qualities/flex"]
        labels = np.asarray(q["object_in_gripper"]).reshape(-1)[rows]
        motions = np.column_stack([np.asarray(q[f"object_motion_during_{ph}_{k}"]).reshape(-1)[rows]
                                   for ph in ("closing", "shaking") for k in ("linear", "angular")])
    return labels, motions


def dominant_axis(v: np.ndarray) -> str:
    """The object-frame axis (e.g. ``-y``) nearest the direction ``v`` (3,)."""
    k = int(np.argmax(np.abs(v)))
    return AXES[2 * k + (0 if v[k] > 0 else 1)]


def contact_depth(grasp, tcp: np.ndarray) -> float:  # type: ignore[no-untyped-def]
    """[m] mean position of the contacts along the approach past the tool centre point (+: towards the tips)."""
    pose = np.asarray(grasp.pose, float)
    local = (np.asarray(grasp.contacts.points, float) - pose[:3, 3]) @ pose[:3, :3]
    return float(np.mean(local[:, 2]) - tcp[2]) if len(local) else float("nan")


def cropped(view: View) -> View:
    """The view cut to a square about the contacts (and the centre of mass), pixel marks moved with it."""
    marks = np.vstack([view.contacts, view.com])
    if not len(marks):
        return view
    centre = view.contacts.mean(0) if len(view.contacts) else view.com[0]
    half = int(max(MIN_HALF, SPREAD * float(np.max(np.linalg.norm(marks - centre, axis=1)))))
    h, w = view.image.shape[:2]
    x0, y0 = int(np.clip(centre[0] - half, 0, w - 1)), int(np.clip(centre[1] - half, 0, h - 1))
    x1, y1 = min(w, x0 + 2 * half), min(h, y0 + 2 * half)
    shift = np.array([x0, y0], float)
    return View(view.image[y0:y1, x0:x1], view.contacts - shift, view.com - shift)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file", help="the grasp file's stem, or enough of it to name one tuning file")
    ap.add_argument("--rows", type=int, nargs="+", required=True, help="rows of the file (0..1999)")
    ap.add_argument("--dev", type=Path, default=ae.DEV)
    ap.add_argument("--mujoco", action="store_true", help="also run the MuJoCo trial at each pose")
    ap.add_argument("--out", type=Path, required=True, help="PNG to write (outside the repository)")
    a = ap.parse_args()
    path = tuning_file(a.dev, a.file)
    hand, obj, poses = am._prepared(path)
    spec = importer.read_for_rescoring(path)[1]
    outcome = importer.rescore_poses(importer.RescoreUnit(0, 0, poses[a.rows], hand, spec))
    closed = {g.candidate: g for g in outcome.grasps}  # candidate: the position in --rows
    labels, motions = flex_record(path, a.rows)
    panels = []
    for k, row in enumerate(a.rows):
        if k not in closed:
            print(f"row {row}: the planner's closing rejects it ({dict(outcome.rejected)})", file=sys.stderr)
            continue
        grasp = replace(closed[k], pose=poses[row])  # the file's pose, the planner's closed fingers
        c, s = motions[k, :2], motions[k, 2:]
        text = (f"{path.stem[:44]} row {row}: FleX {'holds' if labels[k] else 'drops'} (object moved "
                f"{100 * c[0]:.1f} cm / {c[1]:.2f} rad closing, {100 * s[0]:.1f} cm / {s[1]:.2f} rad shaking)\n"
                f"width {1000 * (grasp.width or 0.0):.1f} mm, contacts {1000 * contact_depth(grasp, hand.tcp):+.1f}"
                f" mm past the TCP, approach along {dominant_axis(poses[row][:3, :3] @ hand.approach)}, "
                f"mass {1000 * obj.mass:.1f} g")
        if a.mujoco:
            t = mujoco_trial.trials(hand, obj, [grasp], MujocoSettings())[0]
            text += (f"; MuJoCo {t.reason} ({1000 * t.closing_linear:.1f} mm / {t.closing_angular:.2f} rad closing,"
                     f" {1000 * t.shaking_linear:.1f} mm / {t.shaking_angular:.2f} rad shaking)")
        panels.append(([cropped(v) for v in grasp_views(hand, obj, grasp, RENDER_SIZE)], text))
    if not panels:
        raise SystemExit("flex_pose: no pose closed; nothing drawn")
    save_sheet(panels, a.out)
    print(f"wrote {a.out} ({len(panels)} poses)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
