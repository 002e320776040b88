"""Read an export folder exactly the way each peer's own reader does.

The tests' stand-ins for ACRONYM's ``acronym_tools``, GraspGen's JSON dataset
reader and DexGraspNet's loaders (issue 12). Our own code, written from
reading the peers' readers; no peer code is copied. Each function names the
peer function it mimics and the source (repository, path, commit) so a test
built on it can cite what it checks. Nothing here imports ``planner``.

Faithfulness rule: where a peer does something surprising (no cast of the
success labels, integer-vs-boolean indexing, ``os.path.join`` with an absolute
path, ``trimesh.load`` returning a Scene, a stale mapping file winning over a
scan), the mimic does the same thing, so a test sees what the peer's user would
see. Checks the peer does *not* make are kept apart, in functions whose names
start with ``check_`` and which say so.

Dependencies: numpy, h5py, trimesh, scipy (all core packages of the project).
transforms3d (DexGraspNet's Euler library) is not installed; its ``sxyz``
convention is reproduced with scipy (see :func:`dexgraspnet_euler2mat`).
"""

from __future__ import annotations

import glob
import json
import os
from collections import defaultdict
from typing import Any

import h5py
import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

# --------------------------------------------------------------------------
# ACRONYM: NVlabs/acronym, acronym_tools/acronym.py
#   latest stored version: commit 7ea782afa7ea3c74dc65c2ed5c809388c37f4189
#   (an older one, 583cbe47..., lacks the ``.decode('utf-8')`` in load_mesh)
# --------------------------------------------------------------------------

ACRONYM_TRANSFORMS = "grasps/transforms"
ACRONYM_SUCCESS = "grasps/qualities/flex/object_in_gripper"
ACRONYM_MESH_FILE = "object/file"
ACRONYM_MESH_SCALE = "object/scale"


def acronym_load_grasps(filename: str) -> tuple[np.ndarray, np.ndarray]:
    """Mimic ``acronym_tools.load_grasps(filename)``.

    ACRONYM picks the branch by file ending (``.json`` / ``.h5``, anything else
    raises ``RuntimeError``). For HDF5 it returns
    ``np.array(data["grasps/transforms"])`` and
    ``np.array(data["grasps/qualities/flex/object_in_gripper"])`` with *no*
    cast: the success array keeps the file's dtype (int64 0/1 in ACRONYM's own
    files). Its scripts then select with ``success == 1`` / ``success == 0``.
    The JSON branch reads the flat keys ``transforms`` and
    ``quality_flex_object_in_gripper`` (ACRONYM's old JSON layout, not
    GraspGen's).
    """
    if filename.endswith(".json"):
        with open(filename) as fh:
            data = json.load(fh)
        return np.array(data["transforms"]), np.array(data["quality_flex_object_in_gripper"])
    if filename.endswith(".h5"):
        with h5py.File(filename, "r") as data:
            return np.array(data[ACRONYM_TRANSFORMS]), np.array(data[ACRONYM_SUCCESS])
    raise RuntimeError("Unknown file ending:", filename)


def acronym_mesh_path(filename: str, mesh_root_dir: str) -> str:
    """The path ``acronym_tools.load_mesh`` opens for an ``.h5`` file.

    ``data["object/file"][()]`` is bytes under h5py >= 3 (variable-length and
    fixed-length strings alike), and ACRONYM's latest ``load_mesh`` calls
    ``.decode('utf-8')`` on it (under h5py < 3 a variable-length string came
    back as ``str`` and that call failed: NVlabs/acronym issue #9). The result
    is joined with ``os.path.join(mesh_root_dir, mesh_fname)``: an *absolute*
    ``object/file`` silently ignores ``mesh_root_dir``.
    """
    with h5py.File(filename, "r") as data:
        raw = data[ACRONYM_MESH_FILE][()]
    mesh_fname = raw.decode("utf-8")  # AttributeError on str, as in ACRONYM
    return os.path.join(mesh_root_dir, mesh_fname)


def acronym_load_mesh(filename: str, mesh_root_dir: str, scale: float | None = None) -> Any:
    """Mimic ``acronym_tools.load_mesh(filename, mesh_root_dir, scale=None)`` for ``.h5``.

    ``trimesh.load(os.path.join(mesh_root_dir, object/file))`` then
    ``.apply_scale(object/scale)`` (or the ``scale`` argument when given, as
    ``acronym_generate_scene.py --support_scale`` does). No ``force="mesh"``:
    a file trimesh reads as several geometries comes back as a ``trimesh.Scene``,
    which ACRONYM's ``Scene.add_object``/collision manager cannot use; the
    caller gets whatever trimesh returns, as with ACRONYM.
    ACRONYM's JSON branch (``data["object"].decode('utf-8')``) fails on Python 3
    strings and is not reproduced.
    """
    if not filename.endswith(".h5"):
        raise RuntimeError("Unknown file ending:", filename)
    path = acronym_mesh_path(filename, mesh_root_dir)
    if scale is None:
        with h5py.File(filename, "r") as data:
            scale = data[ACRONYM_MESH_SCALE][()]
    mesh = trimesh.load(path)
    return mesh.apply_scale(scale)


def acronym_split(T: np.ndarray, success: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Successful and failed grasps as ACRONYM's scripts select them.

    ``scripts/acronym_generate_scene.py``: ``T[success == 1]``;
    ``scripts/acronym_visualize_grasps.py``: ``np.where(success == 1)`` and
    ``np.where(success == 0)`` (and ``np.random.choice`` over them, which raises
    when a class is empty).
    """
    return T[success == 1], T[success == 0]


def acronym_gripper_marker_points() -> np.ndarray:
    """Segment end points of ``create_gripper_marker`` (gripper frame, metres).

    Read off the code, for frame checks: base stem from the origin along +z to
    z = 0.066; cross bar at z = 0.066 from x = -0.041 to +0.041; fingers at
    x = +-0.041 from z = 0.066 to z = 0.11217 (fingertips). So: +z is the
    approach direction, fingers open along x, the frame origin is the hand base
    (the Panda hand's flange side), fingertips 0.11217 m ahead.
    """
    return np.array([
        [0.0, 0.0, 0.0], [0.0, 0.0, 0.066],                     # stem
        [-0.041, 0.0, 0.066], [0.041, 0.0, 0.066],              # cross bar
        [0.041, 0.0, 0.066], [0.041, 0.0, 0.11217],             # finger +x
        [-0.041, 0.0, 0.066], [-0.041, 0.0, 0.11217],           # finger -x
    ])


def check_acronym_file(filename: str, mesh_root_dir: str) -> list[str]:
    """Problems ACRONYM would NOT report but that make its reading wrong (ours).

    - ``object/file`` absolute, or escaping ``mesh_root_dir`` (join ignores the root);
    - the loaded mesh not a ``trimesh.Trimesh``;
    - success labels not integer 0/1 (bool also compares equal to 1/0, but
      ACRONYM's own files are int64);
    - transforms not (N, 4, 4) with bottom row [0, 0, 0, 1].
    """
    problems: list[str] = []
    with h5py.File(filename, "r") as data:
        mesh_fname = data[ACRONYM_MESH_FILE][()].decode("utf-8")
    if os.path.isabs(mesh_fname):
        problems.append(f"object/file is absolute: {mesh_fname}")
    root = os.path.realpath(mesh_root_dir)
    joined = os.path.realpath(os.path.join(mesh_root_dir, mesh_fname))
    if os.path.commonpath([root, joined]) != root:
        problems.append(f"object/file leaves mesh_root_dir: {mesh_fname}")
    T, success = acronym_load_grasps(filename)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        problems.append(f"transforms shape {T.shape}")
    elif len(T) and not np.allclose(T[:, 3], [0.0, 0.0, 0.0, 1.0]):
        problems.append("transforms bottom row is not [0, 0, 0, 1]")
    if success.shape != (len(T),):
        problems.append(f"success shape {success.shape} for {len(T)} transforms")
    if success.dtype.kind not in "iu" or not np.isin(success, [0, 1]).all():
        problems.append(f"success labels are not integer 0/1 (dtype {success.dtype})")
    if os.path.exists(joined):
        mesh = acronym_load_mesh(filename, mesh_root_dir)
        if not isinstance(mesh, trimesh.Trimesh):
            problems.append(f"trimesh.load returned {type(mesh).__name__}, not Trimesh")
    else:
        problems.append(f"mesh not found: {joined}")
    return problems


# --------------------------------------------------------------------------
# GraspGen: NVlabs/GraspGen, grasp_gen/dataset/dataset_utils.py
#   (GraspJsonDatasetReader, load_object_grasp_datapoint_objaverse,
#    load_object_grasp_data); read from the fork Kashu7100/GraspGen at commit
#   a6900321fc57ec8fb96c4a0c879e94f958693513 (the NVlabs copy of that file is
#   not stored in the index; NVlabs' dataset.py at 14d42f2e imports the same names).
#   Documented minimal reader: docs/GRASP_DATASET_FORMAT.md (positives
#   ``grasps[grasp_mask]``, negatives ``grasps[~grasp_mask]``).
# --------------------------------------------------------------------------

GRASPGEN_MAPPING = "map_uuid_to_path.json"
GRASPGEN_MIN_POSITIVES_GENERATOR = 5


def graspgen_read_splits(split_file: str) -> list[str]:
    """Mimic ``load_scenes_from_text_file``: stripped, non-empty lines.

    ``PickDataset`` reads ``{root_dir}/{split}.txt`` (train / valid); each line
    is an object key: "a uuid ... or a relative path to the object mesh
    (obj/stl) file (relative to the root of the object dataset)".
    """
    with open(split_file, encoding="utf-8") as fh:
        return [line.strip() for line in fh if line.strip()]


def graspgen_index(grasp_root_dir: str, write_mapping: bool = False) -> dict[str, str]:
    """Mimic ``GraspJsonDatasetReader.__init__``: object key -> JSON basename.

    If ``{grasp_root_dir}/map_uuid_to_path.json`` exists it is loaded and used
    as is (no scan: a stale or foreign mapping file wins). Otherwise every
    ``glob(grasp_root_dir/*.json)`` (top level only, not recursive) except the
    mapping file is opened and keyed by ``grasps_dict["object"]["file"]``;
    later files silently overwrite earlier ones with the same key (glob order
    is the directory's order, i.e. arbitrary). Files without ``object.file``
    (or not JSON) are skipped with a warning. GraspGen then *writes* the
    mapping into the grasp folder; pass ``write_mapping=True`` to do the same.
    """
    mapping_path = os.path.join(grasp_root_dir, GRASPGEN_MAPPING)
    if os.path.exists(mapping_path):
        with open(mapping_path) as fh:
            return json.load(fh)
    index: dict[str, str] = {}
    for json_file in glob.glob(os.path.join(grasp_root_dir, "*.json")):
        if json_file.endswith(GRASPGEN_MAPPING):
            continue
        try:
            with open(json_file) as fh:
                grasps_dict = json.load(fh)
        except Exception:  # GraspGen logs a warning and goes on
            continue
        if "object" in grasps_dict and "file" in grasps_dict["object"]:
            index[grasps_dict["object"]["file"]] = os.path.basename(json_file)
    if write_mapping:
        with open(mapping_path, "w") as fh:
            json.dump(index, fh, indent=2)
    return index


def check_graspgen_key_collisions(grasp_root_dir: str) -> dict[str, list[str]]:
    """Object keys (``object.file``) claimed by more than one JSON file (ours).

    GraspGen does not report these: :func:`graspgen_index` keeps one file per key.
    """
    owners: dict[str, list[str]] = defaultdict(list)
    for json_file in sorted(glob.glob(os.path.join(grasp_root_dir, "*.json"))):
        if json_file.endswith(GRASPGEN_MAPPING):
            continue
        with open(json_file) as fh:
            data = json.load(fh)
        if isinstance(data, dict) and "file" in data.get("object", {}):
            owners[data["object"]["file"]].append(os.path.basename(json_file))
    return {key: files for key, files in owners.items() if len(files) > 1}


def graspgen_object_file(object_id: str, object_root_dir: str) -> str:
    """Mimic the mesh lookup of ``load_object_grasp_datapoint_objaverse``.

    ``os.path.join(object_root_dir, object_id)``; if that does not exist,
    ``object_root_dir/map_uuid_to_path_simplified.json`` (else
    ``map_uuid_to_path.json``) maps the id to a path relative to the root;
    neither file present: ``FileNotFoundError``; id not in the map or mapped
    file missing: GraspGen returns an error code (here ``FileNotFoundError``).
    Note the fallback reads a file named like the *grasp* folder's mapping: if
    grasp and object roots are the same folder, that map (object key -> JSON
    basename) is consulted as an object map.
    """
    object_file = os.path.join(object_root_dir, object_id)
    if os.path.exists(object_file):
        return object_file
    mapping = os.path.join(object_root_dir, "map_uuid_to_path_simplified.json")
    if not os.path.exists(mapping):
        mapping = os.path.join(object_root_dir, GRASPGEN_MAPPING)
    if not os.path.exists(mapping):
        raise FileNotFoundError(f"Could not find mapping file at {mapping}")
    with open(mapping) as fh:
        uuid_to_path = json.load(fh)
    if object_id not in uuid_to_path:
        raise FileNotFoundError(f"UUID_NOT_FOUND_IN_MAPPING: {object_id}")
    object_file = os.path.join(object_root_dir, uuid_to_path[object_id])
    if not os.path.exists(object_file):
        raise FileNotFoundError(f"OBJECT_MESH_NOT_FOUND: {object_file}")
    return object_file


def graspgen_load(
    object_id: str,
    grasp_root_dir: str,
    object_root_dir: str,
    load_discriminator_dataset: bool = True,
    offset_transform: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, trimesh.Trimesh]:
    """Mimic ``load_object_grasp_data`` -> ``load_object_grasp_datapoint_objaverse`` (v2, JSON).

    1. ``GraspJsonDatasetReader(grasp_root_dir).read_grasps_by_uuid(object_id)``
       (:func:`graspgen_index`); unknown id: GRASPS_FILE_NOT_FOUND (here KeyError).
    2. mesh path: :func:`graspgen_object_file`.
    3. ``grasp_poses = np.array(grasps["transforms"])``,
       ``grasp_mask = np.array(grasps["object_in_gripper"])``,
       ``positive = grasp_poses[grasp_mask]`` (an int 0/1 list indexes rows 0
       and 1 over and over, silently), ``negative = grasp_poses[np.logical_not(grasp_mask)]``.
    4. generator dataset (``load_discriminator_dataset=False``): fewer than 5
       positives -> INSUFFICIENT_GRASPS_FOR_GENERATOR_DATASET (here ValueError).
    5. optional ``contact_locations``: positives with a NaN contact are dropped.
    6. ``trimesh.load(object_file)``; a Scene is concatenated; ``apply_scale(object.scale)``.
    7. every pose is right-multiplied by the gripper config's
       ``transform_offset_from_asset_to_graspgen_convention`` (identity when
       the YAML has none; pass ``offset_transform`` to mimic a gripper that has one).
    """
    index = graspgen_index(grasp_root_dir)
    if object_id not in index:
        raise KeyError(f"GRASPS_FILE_NOT_FOUND: {object_id}")
    with open(os.path.join(grasp_root_dir, index[object_id])) as fh:
        grasps_dict = json.load(fh)
    object_file = graspgen_object_file(object_id, object_root_dir)
    object_scale = grasps_dict["object"]["scale"]
    grasps = grasps_dict["grasps"]
    grasp_poses = np.array(grasps["transforms"])
    grasp_mask = np.array(grasps["object_in_gripper"])
    positive = grasp_poses[grasp_mask]
    negative = grasp_poses[np.logical_not(grasp_mask)]
    if not load_discriminator_dataset and positive.shape[0] < GRASPGEN_MIN_POSITIVES_GENERATOR:
        raise ValueError("INSUFFICIENT_GRASPS_FOR_GENERATOR_DATASET")
    if "contact_locations" in grasps:
        contacts = np.array(grasps["contact_locations"])[grasp_mask]
        bad = np.any(np.isnan(contacts), axis=1)
        if contacts.shape[-1] == 3:
            bad = np.any(bad, axis=1)
        positive = positive[np.logical_not(bad)]
    mesh = trimesh.load(object_file)
    if isinstance(mesh, trimesh.Scene):
        mesh = mesh.to_mesh()
    mesh.apply_scale(object_scale)
    offset = np.eye(4) if offset_transform is None else np.asarray(offset_transform)
    positive = np.array([g @ offset for g in positive]) if len(positive) else positive
    negative = np.array([g @ offset for g in negative]) if len(negative) else negative
    return positive, negative, mesh


def graspgen_split_documented(json_path: str) -> tuple[np.ndarray, np.ndarray]:
    """The reader GraspGen's docs/GRASP_DATASET_FORMAT.md prints, verbatim in behaviour.

    ``grasps[grasp_mask]`` and ``grasps[~grasp_mask]``: with a 0/1 integer
    list, ``~`` gives -1/-2 (rows counted from the end) and the positives are
    copies of rows 0 and 1; both silently. Only a JSON boolean list
    (``true``/``false``) reads right. An empty list becomes a float array and
    raises IndexError.
    """
    with open(json_path) as fh:
        grasps_dict = json.load(fh)
    grasps = np.array(grasps_dict["grasps"]["transforms"])
    grasp_mask = np.array(grasps_dict["grasps"]["object_in_gripper"])
    return grasps[grasp_mask], grasps[~grasp_mask]


def check_graspgen_file(json_path: str) -> list[str]:
    """Conditions GraspGen's own test_dataset_format.py asserts, plus the bool check (ours).

    Its test accepts ``dtype == bool or isin(mask, [0, 1])`` -- but integer
    masks are misread by its loader, so here only bool passes.
    """
    problems: list[str] = []
    with open(json_path) as fh:
        d = json.load(fh)
    for section, keys in (("object", ("file", "scale")), ("grasps", ("transforms", "object_in_gripper"))):
        for key in keys:
            if key not in d.get(section, {}):
                problems.append(f"missing {section}.{key}")
    if problems:
        return problems
    transforms = np.array(d["grasps"]["transforms"])
    mask = np.array(d["grasps"]["object_in_gripper"])
    if transforms.ndim != 3 or transforms.shape[1:] != (4, 4):
        problems.append(f"transforms shape {transforms.shape}")
    if len(mask) != len(transforms):
        problems.append("mask length differs from number of grasps")
    if mask.dtype != bool:
        problems.append(f"object_in_gripper is {mask.dtype}, not a JSON boolean list")
    scale = d["object"]["scale"]
    if not (isinstance(scale, (int, float)) and scale > 0):
        problems.append(f"scale {scale!r} is not a positive number")
    if os.path.isabs(d["object"]["file"]):
        problems.append("object.file is absolute")
    return problems


# --------------------------------------------------------------------------
# DexGraspNet: PKU-EPIC/DexGraspNet, commit 91a49a4446ad0ce90ba4ce3c5b00fc3683b15ec5
#   grasp_generation/main.py (writer), tests/visualize_result.py (reader),
#   utils/object_model.py (mesh lookup), scripts/validate_grasps.py
#   (commit 1c127ab4f225d01fc025769f5a34bcea2eca033d), utils/isaac_validator.py,
#   asset_process/README.md + normalize.py + decompose.py (meshdata layout).
# --------------------------------------------------------------------------

DEXGRASPNET_TRANSLATION_NAMES = ("WRJTx", "WRJTy", "WRJTz")
DEXGRASPNET_ROT_NAMES = ("WRJRx", "WRJRy", "WRJRz")
#: The 22 Shadow-hand joints DexGraspNet hard-codes (MJCF shadow_hand_wrist_free.xml,
#: OpenAI naming: J3 = knuckle abduction, J2/J1/J0 = proximal/middle/distal flexion;
#: LFJ4 little-finger metacarpal; THJ4..THJ0 thumb), in the order of hand_pose[9:].
SHADOW_JOINT_NAMES = (
    "robot0:FFJ3", "robot0:FFJ2", "robot0:FFJ1", "robot0:FFJ0",
    "robot0:MFJ3", "robot0:MFJ2", "robot0:MFJ1", "robot0:MFJ0",
    "robot0:RFJ3", "robot0:RFJ2", "robot0:RFJ1", "robot0:RFJ0",
    "robot0:LFJ4", "robot0:LFJ3", "robot0:LFJ2", "robot0:LFJ1", "robot0:LFJ0",
    "robot0:THJ4", "robot0:THJ3", "robot0:THJ2", "robot0:THJ1", "robot0:THJ0",
)


def dexgraspnet_mesh_path(mesh_root: str, object_code: str) -> str:
    """``ObjectModel.initialize``: ``{data_root_path}/{object_code}/coacd/decomposed.obj``."""
    return os.path.join(mesh_root, object_code, "coacd", "decomposed.obj")


def dexgraspnet_load(path: str, mesh_root: str) -> tuple[list[tuple[float, dict]], trimesh.Trimesh]:
    """Mimic DexGraspNet's reading of one result file and its object mesh.

    ``visualize_result.py`` / ``validate_grasps.py``: the object code is the
    file name (they open ``os.path.join(result_path, object_code + '.npy')``);
    ``np.load(..., allow_pickle=True)`` gives an object array of dicts; each
    is read with ``data_dict['qpos']`` and ``data_dict['scale']`` (other keys,
    e.g. ``energy``/``E_fc``/``E_pen``/``qpos_st``, are optional for the
    visualiser). ``ObjectModel`` loads
    ``tm.load(mesh_root/<code>/coacd/decomposed.obj, force="mesh", process=False)``
    and multiplies the *vertices* by ``scale`` (``get_plotly_data``:
    ``mesh.vertices * model_scale``; ``cal_distance`` divides the query points
    by it); the hand is not scaled. The mesh is returned as loaded (unscaled).
    """
    object_code = os.path.basename(path)[: -len(".npy")] if path.endswith(".npy") else os.path.basename(path)
    data = np.load(path, allow_pickle=True)
    grasps = [(d["scale"], d["qpos"]) for d in data]
    mesh = trimesh.load(dexgraspnet_mesh_path(mesh_root, object_code), force="mesh", process=False)
    return grasps, mesh


def dexgraspnet_euler2mat(rx: float, ry: float, rz: float) -> np.ndarray:
    """transforms3d ``euler2mat(rx, ry, rz)`` with its default axes ``'sxyz'``.

    Static (extrinsic) x, then y, then z: R = Rz(rz) @ Ry(ry) @ Rx(rx), which is
    scipy's lower-case ``'xyz'``. DexGraspNet writes the angles with
    ``transforms3d.euler.mat2euler(rot, axes='sxyz')`` (main.py) and reads them
    with ``euler2mat(*[qpos[name] for name in rot_names])`` (visualize_result.py)
    or ``euler2quat`` (validate_grasps.py, w-first quaternion).
    """
    return Rotation.from_euler("xyz", [rx, ry, rz]).as_matrix()


def dexgraspnet_wrist_pose(qpos: dict) -> np.ndarray:
    """(4, 4) pose of the hand root body (``robot0:palm`` in the wrist-free MJCF)
    in the (scaled) object frame, from WRJT*/WRJR*."""
    pose = np.eye(4)
    pose[:3, :3] = dexgraspnet_euler2mat(*[qpos[n] for n in DEXGRASPNET_ROT_NAMES])
    pose[:3, 3] = [qpos[n] for n in DEXGRASPNET_TRANSLATION_NAMES]
    return pose


def dexgraspnet_hand_pose(qpos: dict, joint_names: tuple[str, ...] = SHADOW_JOINT_NAMES) -> np.ndarray:
    """Mimic the ``hand_pose`` vector of visualize_result.py / validate_grasps.py.

    ``[WRJTx, WRJTy, WRJTz] + rot[:, :2].T.ravel() (rot6d: first two columns)
    + [qpos[name] for name in joint_names]`` -> (3 + 6 + 22,). A qpos without
    the Shadow joint names raises KeyError, as DexGraspNet does; extra keys are
    ignored silently.
    """
    rot = dexgraspnet_euler2mat(*[qpos[n] for n in DEXGRASPNET_ROT_NAMES])
    rot6d = rot[:, :2].T.ravel().tolist()
    return np.array([qpos[n] for n in DEXGRASPNET_TRANSLATION_NAMES] + rot6d + [qpos[n] for n in joint_names],
                    dtype=np.float32)


def check_dexgraspnet_validation_inputs(path: str, mesh_root: str) -> list[str]:
    """What ``scripts/validate_grasps.py`` needs beyond the visualiser (ours).

    It reads ``data_dict[i]["E_pen"]`` for every grasp (KeyError otherwise),
    the 22 Shadow joint names, and loads the object for Isaac Gym from
    ``mesh_path/<code>/coacd/coacd.urdf``; it also only simulates full batches
    of ``--val_batch`` (500) grasps (``range(batch_size // val_batch)``).
    """
    problems: list[str] = []
    object_code = os.path.basename(path)[: -len(".npy")]
    data = np.load(path, allow_pickle=True)
    if any("E_pen" not in d for d in data):
        problems.append("some grasps have no E_pen (validate_grasps.py raises KeyError)")
    missing = {n for d in data for n in SHADOW_JOINT_NAMES if n not in d["qpos"]}
    if missing:
        problems.append(f"qpos lacks Shadow joints: {sorted(missing)[:3]}... ({len(missing)})")
    urdf = os.path.join(mesh_root, object_code, "coacd", "coacd.urdf")
    if not os.path.exists(urdf):
        problems.append(f"no {urdf}")
    if not os.path.exists(dexgraspnet_mesh_path(mesh_root, object_code)):
        problems.append(f"no {dexgraspnet_mesh_path(mesh_root, object_code)}")
    return problems
