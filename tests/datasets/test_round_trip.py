"""Every hand through every format and back: a small sweep of the box for
each hand, a shake trial and robust epsilon of each hand's best grasps, a
MuJoCo trial of each hand's two best (one of them tried by both engines), an
object whose mass and friction are not the registry's; then each export,
read back (ACRONYM by ``grasp import``, the others by the plain readers
below), gives the same value of every declared field the format carries,
the settled epsilon, the Panda's p_hold, the trial results and an imported file's labels included,
and the object's mass, friction and density. What each format carries is derived from the
declaration (:mod:`planner.record.fields`) and each format's own mapping;
:data:`NOT_CARRIED` says what each leaves out, so a new field that a format
drops fails here instead of vanishing."""

from __future__ import annotations

import csv
import json
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from helpers import grasp

from planner import api
from planner.calibration.model import LogisticModel
from planner.datasets import acronym, dexgraspnet, graspgen, moveit, table
from planner.datasets.exporter import FORMATS
from planner.db.store import open_db
from planner.plan.sweep import SweepSettings
from planner.record.field import Field
from planner.record.fields import by_name, getter, record_fields
from planner.specs.hands import hand_names, load_hand
from tests.datasets.support import export

#: Every hand, with two preshapes at most (the allegro's lateral pinch has its own tcp).
PRESHAPES = {"panda": ("wide",), "barrett": ("wrap", "pinch"), "allegro": ("lateral", "pinch"), "pr2": ("wide",)}
TINY = dict(approaches=3, rolls=1, reach_placements=0)
#: Not the box's registry values: an export that fell back on them would show.
MASS, FRICTION = 0.37, 0.83
#: The swept box's up: not its frame's +z, so that every format is seen to carry it.
UP = "-y"
#: Poses go through transforms @ inverse(export frame) or Euler angles and
#: are stored to 7 decimals; everything else comes back exactly.
POSE_TOL = 1e-6
#: The Panda's p_hold model in both databases (the source and the one ``grasp import`` fills):
#: on epsilon alone, which comes back exactly, so the importing store's p_hold is the source's.
MODEL = LogisticModel("panda", ("epsilon",), np.zeros(1), np.full(1, 0.05), np.ones(1), -1.0, 0.0, "round trip")
#: Renumbered by ``grasp import`` (the file keeps them in ``grasps/candidate``
#: and ``grasps/seed``): the import is one unit of its own, candidate = row.
RENUMBERED = {"id", "unit_id", "candidate", "seed"}
#: The declared record fields each format does not carry (read back).
NOT_CARRIED = {
    "acronym": RENUMBERED,
    "graspgen": {"id", "unit_id"},
    "parquet": set(),
    "csv": set(),
    "dexgraspnet": {"id", "unit_id", "object", "hand", "approach_point", "approach_dir", "open_joints", "contacts",
                    "table_plane", "local_sdf"},
}
#: Formats whose records are a fixed message (``moveit_msgs/Grasp``): they carry
#: what the message has a field for, not the measures or the object's physics.
MOVEIT_CARRIED = {"object", "hand", "rank", "score", "pose", "open_joints", "closed_joints"}
MESSAGES = {"moveit"}
#: The record fields of a format's files, by the file's own name for them.
ACRONYM_FILE = {**{key: column for key, column in acronym.DATASETS.items()}, "joints_open": "open_joints",
                "joints_closed": "closed_joints"}


def carried(fmt: str) -> set[str]:
    """The declared record fields a format carries, from the format's own mapping."""
    if fmt == "acronym":
        return acronym.carried() - RENUMBERED
    if fmt == "graspgen":
        return acronym.carried()
    if fmt in ("parquet", "csv"):
        return {source for _, _, source, _, _ in table._SPEC if source}
    return {*dexgraspnet.EXTRAS, "pose", "closed_joints"}


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> Path:
    db = tmp_path_factory.mktemp("round_trip") / "g.db"
    for hand in hand_names():
        summary = api.generate(["box"], hand, db_path=db, workers=1, up=UP,
                               settings=SweepSettings(preshapes=PRESHAPES[hand], **TINY))
        assert not summary.failed and summary.grasps > 0, hand
    # grasps planned on a table carry its plane
    summary = api.generate(["box"], "barrett", db_path=db, workers=1, on_table=1, up=UP,
                           settings=SweepSettings(preshapes=PRESHAPES["barrett"], **TINY))
    assert not summary.failed and summary.grasps > 0
    with open_db(db) as handle:
        handle.write_model(MODEL, "round trip", handle.rule())
    with sqlite3.connect(db) as conn:
        volume = conn.execute("SELECT volume FROM objects WHERE name = 'box'").fetchone()[0]
        conn.execute("UPDATE objects SET mass = ?, friction = ?, density = ? WHERE name = 'box'",
                     (MASS, FRICTION, MASS / volume))
        # the squeeze's force closure 0 comes back too (the Panda's box grasps are force closure as planned: 1)
        conn.execute("UPDATE grasps SET squeezed_force_closure = 0, squeeze_turn = 0.25 WHERE id = (SELECT MAX(id) "
                     "FROM grasps WHERE hand = 'panda')")
        # a squeeze's end comes back as one (the field set), beside grasps closed where planned (NULL)
        conn.execute("UPDATE grasps SET squeezed_from_turn = 0.375 WHERE id = (SELECT MIN(id) FROM grasps WHERE "
                     "hand = 'panda')")
        # an imported file's own labels, held and dropped, on every third grasp (the others have none)
        conn.execute("INSERT INTO file_labels SELECT id, id / 3 % 2, 'r3.h5 grasps/qualities/flex/object_in_gripper',"
                     " 0, '{}' FROM grasps WHERE id % 3 = 0")
    code, _, err = grasp("validate", "--db", str(db), "--top", "1", "--robust", "2", "--workers", "1",
                         "--engine", "pybullet")
    assert code == 0, err
    code, _, err = grasp("validate", "--db", str(db), "--top", "2", "--robust", "0", "--workers", "1",
                         "--engine", "mujoco")
    assert code == 0, err
    return db


def test_every_hand_is_swept_with_its_fields() -> None:
    assert set(PRESHAPES) == set(hand_names())


def test_each_format_says_what_it_carries() -> None:
    """The fields a format leaves out are exactly the ones named here."""
    every = {f.name for f in record_fields()}
    assert set(NOT_CARRIED) | MESSAGES == set(FORMATS)
    for fmt in set(FORMATS) - MESSAGES:
        assert every - carried(fmt) == NOT_CARRIED[fmt], fmt
        assert {"settled_epsilon", "p_hold", "validation_success", "validation_reason", "mujoco_success",
                "mujoco_reason", "robust_quantile"} <= carried(fmt)
    assert MOVEIT_CARRIED < every


def comparable(f: Field, value: object) -> object:
    """A value as the formats can give it back: absent (None, NaN, the
    neutral value of a field that may be absent) as None; joints as a dict,
    contacts as their items, vectors as arrays, reasons as a tuple."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if f.kind == "margin" and value == math.inf:  # no finger touches: JSON writes null
        return None
    if f.kind == "reasons":  # '' is feasible (every grasp of a fresh sweep is measured)
        return tuple(r for r in value.split(",") if r) if isinstance(value, str) else tuple(value)  # type: ignore[arg-type]
    absent_possible = f.nullable or "." in f.attr
    if absent_possible and f.kind in ("int", "bool", "text") and value == f.neutral:
        return None
    if f.kind == "joints":
        return dict(value)  # type: ignore[call-overload]
    if f.kind == "contacts":
        return value if isinstance(value, list) else value.to_json()  # type: ignore[attr-defined]
    if f.kind == "vector":
        array = np.array(value, float).reshape(f.shape)  # JSON's nulls: NaN
        return None if f.nullable and np.isnan(array).all() else array
    if f.kind == "bool":
        return bool(value)
    return value


def source(db: Path) -> tuple[dict, tuple]:
    """{(hand, rank): {field: value}} of every stored grasp, and the object's (mass, friction, density, up)."""
    with open_db(db, create=False, readonly=True) as handle:
        rows = {(g.hand, g.rank): {f.name: comparable(f, getter(f)(g)) for f in record_fields()}
                for hand in hand_names() for batch in handle.grasp_batches("box", hand) for g in batch}
        row = handle.object_row("box")
    assert row is not None
    return rows, (row.mass, row.friction, row.density, row.up)


def read_acronym(out: Path, tmp_path: Path) -> tuple[dict, tuple]:
    fresh = tmp_path / "imported.db"
    with open_db(fresh) as handle:
        handle.write_model(MODEL, "round trip", handle.rule())
    code, _, err = grasp("import", "--format", "acronym", *map(str, sorted(out.glob("*.h5"))), "--db", str(fresh))
    assert code == 0, err
    return source(fresh)


def read_graspgen(out: Path, tmp_path: Path) -> tuple[dict, tuple]:
    rows, physics = {}, None
    for hand in hand_names():
        data = json.loads((out / graspgen.relative_path("box", hand)).read_text())
        lists = data["grasps"]
        names = data["gripper"]["joint_names"]
        physics = tuple(data["object"][k] for k in ("mass", "friction", "density", "up"))
        columns = {column: lists[key.rsplit("/", 1)[-1]] for key, column in ACRONYM_FILE.items()}
        for i in range(len(lists["transforms"])):
            row = {column: _joints(names, values[i]) if column.endswith("_joints") else values[i]
                   for column, values in columns.items()}
            row.update(object=data["object"]["name"], hand=data["gripper"]["type"], n_contacts=len(row["contacts"]),
                       links_touching=len({c["link"] for c in row["contacts"]}))
            rows[(hand, row["rank"])] = _fields(row)
    return rows, physics  # type: ignore[return-value]


def read_table(out: Path, fmt: str) -> tuple[dict, tuple]:
    if fmt == "parquet":
        import pyarrow.parquet as pq

        records = pq.read_table(out / "grasps.parquet").to_pylist()
    else:
        with open(out / "grasps.csv", newline="", encoding="utf-8") as fh:
            records = [{k: _csv_value(k, v) for k, v in r.items()} for r in csv.DictReader(fh)]
    rows = {}
    for r in records:
        row = {}
        for column, _, name, index, f in table._SPEC:
            if not name:
                continue
            if index:
                row.setdefault(name, np.zeros(f.shape))[index] = r[column]  # type: ignore[union-attr]
            else:
                row[name] = json.loads(r[column]) if f.kind in ("joints", "contacts") else r[column]  # type: ignore[union-attr]
        rows[(r["hand"], r["rank"])] = _fields(row)
    first = records[0]
    return rows, (first["object_mass"], first["object_friction"], first["object_density"], first["object_up"])


def _csv_value(column: str, text: str) -> object:
    kind = next((kind for name, kind, *_ in table._SPEC if name == column), "string")
    if kind == "string":
        return text
    if text == "":
        return None
    return int(text) if kind == "int64" else float(text)


def read_dexgraspnet(out: Path) -> tuple[dict, tuple]:
    rows, physics = {}, None
    for hand in hand_names():
        names = [j.name for j in load_hand(hand).joints]
        for item in np.load(out / dexgraspnet.relative_path("box", hand), allow_pickle=True):
            row = {k: item[k] for k in dexgraspnet.EXTRAS}
            row["pose"] = dexgraspnet.pose_from_qpos(item["qpos"])
            row["closed_joints"] = {k: item["qpos"][k] for k in names if k in item["qpos"]}
            rows[(hand, row["rank"])] = _fields(row)
            physics = tuple(item[k] for k in dexgraspnet.PHYSICS)
    return rows, physics  # type: ignore[return-value]


def _joints(names: list[str], values: list) -> dict:
    return {k: v for k, v in zip(names, values) if v is not None}


def _fields(row: dict) -> dict:
    return {name: comparable(by_name(name), value) for name, value in row.items()}


def same(f: Field, a: object, b: object) -> bool:
    if f.kind == "vector" and a is not None and b is not None:
        return bool(np.allclose(a, b, atol=POSE_TOL, rtol=0))  # type: ignore[arg-type]
    return bool(a == b)


@pytest.mark.parametrize("fmt", sorted(set(FORMATS) - MESSAGES))
def test_every_hand_comes_back_through_every_format(fmt: str, swept: Path, tmp_path: Path) -> None:
    out = export(swept, fmt, tmp_path / fmt)
    expected, physics = source(swept)
    readers = {"acronym": lambda: read_acronym(out, tmp_path), "graspgen": lambda: read_graspgen(out, tmp_path),
               "parquet": lambda: read_table(out, "parquet"), "csv": lambda: read_table(out, "csv"),
               "dexgraspnet": lambda: read_dexgraspnet(out)}
    back, back_physics = readers[fmt]()
    assert set(back) == set(expected)
    assert np.allclose(back_physics[:3], physics[:3], rtol=1e-12, atol=0) and physics[:2] == (MASS, FRICTION)
    assert back_physics[3] == physics[3] == UP  # the object's up, read back by import from ACRONYM's object/up
    names = carried(fmt)
    for key, row in expected.items():
        for name in names:
            f = by_name(name)
            want = row[name]
            if fmt == "graspgen" and name.endswith("_joints"):  # (N, J) matrices: the mimics too (an import names
                # the joints each record named: *_given)
                want = load_hand(key[0]).posture(want)
                assert {k: back[key][name][k] for k in row[name]} == row[name]
            assert same(f, back[key][name], want), (fmt, key, name, back[key][name], want)
    # the trials and the Barrett's settled epsilon are there to come back
    assert sum(row["validation_success"] is not None for row in expected.values()) == len(hand_names())
    assert sum(row["mujoco_success"] is not None for row in expected.values()) >= len(hand_names())
    settled = [row["settled_epsilon"] is not None for (hand, _), row in expected.items()
               if hand == "barrett" and row["force_closure"]]  # only force-closure grasps settle
    assert settled and all(settled)
    assert all((row["p_hold"] is not None) == (hand == "panda") for (hand, _), row in expected.items())
    # an imported file's labels, held and dropped, beside grasps without one
    assert {row["file_label_success"] for row in expected.values()} == {True, False, None}
    # the squeeze's force closure: 1 and 0 of the Panda's, NULL of the hands that do not squeeze
    squeezed = {(hand, row["squeezed_force_closure"]) for (hand, _), row in expected.items()}
    assert {("panda", True), ("panda", False), ("barrett", None), ("allegro", None)} <= squeezed, squeezed
    ends = sorted((row["squeezed_from_turn"] is None, hand) for (hand, _), row in expected.items())
    assert ends[0] == (False, "panda") and ends[1][0] and "squeezed_from_turn" in names, ends[:2]


def read_moveit(out: Path) -> dict:
    """{(hand, rank): fields} from the MoveIt YAML: the hand pose is the end
    effector's times the hand's mount; joints from the two postures."""
    import yaml

    from planner.geometry.quaternion import canonical_xyzw

    rows = {}
    for hand in hand_names():
        spec = load_hand(hand)
        for msg in yaml.safe_load((out / moveit.relative_path("box", hand)).read_text()):
            obj, name, rank = msg["id"].split("/")
            p, o = msg["grasp_pose"]["pose"]["position"], msg["grasp_pose"]["pose"]["orientation"]
            ee = np.eye(4)
            ee[:3, 3] = [p["x"], p["y"], p["z"]]
            ee[:3, :3] = _matrix(np.array([o["x"], o["y"], o["z"], o["w"]]))
            assert np.allclose(canonical_xyzw(ee[:3, :3]), [o["x"], o["y"], o["z"], o["w"]], atol=1e-9)
            pose = ee @ (np.eye(4) if spec.arm is None else spec.arm.mount)
            joints = [dict(zip(msg[k]["joint_names"], msg[k]["points"][0]["positions"]))
                      for k in ("pre_grasp_posture", "grasp_posture")]
            assert msg["grasp_pose"]["header"]["frame_id"] == obj == "box"
            rows[(hand, int(rank))] = _fields({"object": obj, "hand": name, "rank": int(rank),
                                               "score": msg["grasp_quality"], "pose": pose,
                                               "open_joints": joints[0], "closed_joints": joints[1]})
    return rows


def _matrix(q: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(q).as_matrix()


#: moveit_msgs/Grasp, field by field (ROS 2 types as plain YAML): what a node
#: filling the message from this file finds.
MOVEIT_MESSAGE = {"id": str, "pre_grasp_posture": dict, "grasp_posture": dict, "grasp_pose": dict,
                  "grasp_quality": float, "pre_grasp_approach": dict, "post_grasp_retreat": dict,
                  "post_place_retreat": dict, "max_contact_force": float, "allowed_touch_objects": list}


def test_every_hand_comes_back_through_moveit(swept: Path, tmp_path: Path) -> None:
    out = export(swept, "moveit", tmp_path / "moveit")
    expected, _ = source(swept)
    back = read_moveit(out)
    ranked = {key: row for key, row in expected.items() if key[1] is not None}
    assert set(back) == set(ranked)
    for key, row in ranked.items():
        spec = load_hand(key[0])
        for name in MOVEIT_CARRIED:
            f = by_name(name)
            want = spec.posture(row[name]) if name.endswith("_joints") else row[name]
            assert same(f, back[key][name], want), ("moveit", key, name, back[key][name], want)
            if name.endswith("_joints"):  # the stored joints exactly, the mimics at their coupling
                assert {k: back[key][name][k] for k in row[name]} == row[name]
    import yaml

    for hand in hand_names():
        spec = load_hand(hand)
        messages = yaml.safe_load((out / moveit.relative_path("box", hand)).read_text())
        assert [int(m["id"].split("/")[2]) for m in messages] == sorted(r for h, r in ranked if h == hand)
        for m in messages:
            assert {k: type(m[k]) for k in MOVEIT_MESSAGE} == MOVEIT_MESSAGE and set(m) == set(MOVEIT_MESSAGE)
            approach = m["pre_grasp_approach"]
            frame = spec.arm.ee_link if spec.arm is not None else spec.root_link
            assert approach["direction"]["header"]["frame_id"] == frame
            v = np.array([approach["direction"]["vector"][a] for a in "xyz"])
            retreat = np.array([m["post_grasp_retreat"]["direction"]["vector"][a] for a in "xyz"])
            assert np.isclose(np.linalg.norm(v), 1.0) and np.allclose(retreat, -v)
            assert approach["desired_distance"] > approach["min_distance"] > 0
            assert m["grasp_posture"]["points"][0]["time_from_start"] == {"sec": 0, "nanosec": 500_000_000}
