"""Hand descriptions: ``hands/<name>/hand.toml`` plus a URDF, parsed once.

The TOML names the palm frame, the approach axis, the finger joints with
their closing synergy, and the contact-capable links with their contact
model. The URDF is parsed with yourdfpy (kinematics, limits, mimic joints);
PyBullet loads the very same file. A URDF that carries a whole robot is cut
down to the subtree below ``root_link`` (e.g. the Panda hand without the arm)
and written, with absolute mesh paths, into the cache. The specs it makes,
and their frames, are in :mod:`planner.specs.hand_spec`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner import assets
from planner.errors import ConfigError, UnknownNameError
from planner.specs.hand_spec import (
    BREAKAWAY_TOL,
    LOCAL_CELLS,
    STILL,
    Actuators,
    ArmSpec,
    ContactModel,
    FingerDof,
    HandSpec,
    JointSpec,
    LocalGrid,
    SettleDynamics,
)
from planner.specs.toml import Fields, read_toml
from planner.specs.urdf import cut_subtree, descendants, link_names, load_model, movable_joints

if TYPE_CHECKING:
    import yourdfpy

__all__ = ["BREAKAWAY_TOL", "CONTACT_MODELS", "DEFAULT_CLOSING_SPEED", "DEFAULT_DISTANCE_OFFSET",
           "DEFAULT_FINGER_FORCE", "LOCAL_CELLS", "SAMPLERS", "STILL", "Actuators", "ArmSpec", "ContactModel",
           "FingerDof", "HandFrame", "HandSpec", "JointSpec", "LocalGrid", "check_hand_name", "hand_frame",
           "hand_names", "hands_dir", "load_folder", "load_hand", "parallel_jaw", "roll_symmetry"]

CONTACT_MODELS = ("frictionless", "point", "soft")
#: Approach samplers (planner.plan.sampling): rays onto the surface, or antipodal pairs for parallel jaws.
SAMPLERS = ("surface", "box", "antipodal")
DEFAULT_FINGER_FORCE = 20.0  # [N or N m] per finger motor, when [dynamics] does not say
DEFAULT_CLOSING_SPEED = 0.5  # [m/s or rad/s] of a driven joint, when [dynamics] does not say
#: PyBullet inflates convex hull meshes, cylinders and triangle meshes by 1 mm
#: each, so a reported closest distance is the true gap minus 2 mm (measured
#: on a box). URDF <box> and <sphere> links are padded by less and unevenly:
#: a hand's cut URDF has them as meshes (:func:`planner.specs.urdf.cut_subtree`),
#: and the table is a hull too (:meth:`planner.sim.Sim.add_box`).
DEFAULT_DISTANCE_OFFSET = 0.002


def hands_dir() -> Path:
    return assets.project_dir("hands")


def hand_names() -> list[str]:
    return sorted(p.name for p in hands_dir().iterdir() if (p / "hand.toml").is_file())


def check_hand_name(name: str) -> Path:
    """The folder of hand ``name``; unknown names list the valid ones (no URDF is read)."""
    if "/" in name or "\\" in name or name.startswith("."):
        raise ConfigError(f"hand name '{name}' must be a folder name under {hands_dir()}")
    folder = hands_dir() / name
    if not (folder / "hand.toml").is_file():
        raise UnknownNameError("hand", name, hand_names())
    return folder


@dataclass(frozen=True)
class HandFrame:
    """What locating a grasp needs of a hand, read from hand.toml alone (no
    URDF: ``grasp best`` prints frames without loading the hand's model).

    Attributes:
        root_link: the hand frame's link; approach: (3,) unit, hand frame;
        tcp: (3,) [m] the tool centre point, hand frame.
    """

    root_link: str
    approach: np.ndarray
    tcp: np.ndarray


@cache
def hand_frame(name: str) -> HandFrame:
    """The :class:`HandFrame` of hand ``name`` (the same values :func:`load_hand` gives)."""
    path = check_hand_name(name) / "hand.toml"
    f = Fields(read_toml(path), str(path))
    approach = np.array(f.floats("approach", 3))
    return HandFrame(f.str("root_link"), approach / np.linalg.norm(approach), np.array(f.floats("tcp", 3)))


@cache
def load_hand(name: str) -> HandSpec:
    """Load ``hands/<name>/hand.toml``; unknown names list the valid ones."""
    return load_folder(check_hand_name(name))


def load_folder(folder: Path) -> HandSpec:
    path = folder / "hand.toml"
    f = Fields(read_toml(path), str(path))
    source = assets.resolve(f.str("urdf"), folder, f"{path} field 'urdf'")
    root_link = f.str("root_link")
    urdf = cut_subtree(source, root_link, f"{path} field 'root_link'")
    model = load_model(urdf)
    links = link_names(model)
    joints = tuple(_joint(model, source, jf) for jf in f.tables("joints"))
    approach = np.array(f.floats("approach", 3))
    if np.linalg.norm(approach) < 1e-9:
        raise ConfigError(f"{path} field 'approach': must be a non-zero vector")
    contact_links = tuple(f.strs("contact_links"))
    for link in contact_links:
        if link not in links:
            raise ConfigError(f"{path} field 'contact_links': unknown link '{link}'; links: {', '.join(links)}")
    contacts = _contact_models(f, contact_links)
    spec = HandSpec(
        name=folder.name, folder=folder, description=f.get("description", ""), urdf=urdf,
        root_link=root_link, approach=approach / np.linalg.norm(approach), tcp=np.array(f.floats("tcp", 3)),
        joints=joints, contact_links=contact_links, contacts=contacts, centering=f.bool("centering", False),
        distance_offset=f.float("distance_offset", DEFAULT_DISTANCE_OFFSET),
        roll_symmetry=roll_symmetry(f),
        links=tuple(links), arm=_arm(f, folder), export_frame=_export_frame(f),
        actuators=_actuators(f.table("dynamics", {})),
        link_inertia=_link_inertia(f.table("dynamics", {}), model),
        sampler=_sampler(f, joints),
        settle=f.bool("settle", False),
        settle_dynamics=_settle_dynamics(f),
        local_grid=_local_grid(f),
        width_links=_width_links(f, model),
    )
    f.check_unknown()
    return spec


def _local_grid(f: Fields) -> LocalGrid | None:
    """``[local_sdf]``, if given: a box (low < high on every axis) and points per axis whose product is
    :data:`~planner.specs.hand_spec.LOCAL_CELLS` (the stored measure's length)."""
    if not f.has("local_sdf"):
        return None
    t = f.table("local_sdf")
    low, high = tuple(t.floats("low", 3)), tuple(t.floats("high", 3))
    counts = t.floats("counts", 3)
    if any(a >= b for a, b in zip(low, high)):
        raise ConfigError(f"{t.where} fields 'low', 'high': low must be below high on every axis")
    if any(c != int(c) or c < 1 for c in counts) or int(np.prod(counts)) != LOCAL_CELLS:
        raise ConfigError(f"{t.where} field 'counts': whole numbers of points per axis, >= 1, whose product is "
                          f"{LOCAL_CELLS}")
    return LocalGrid(low, high, tuple(int(c) for c in counts))  # type: ignore[arg-type]


def _width_links(f: Fields, model: yourdfpy.URDF) -> tuple[str, str] | None:
    """``width_links``, if given: two different links of the hand, each with collision geometry (the pads whose
    gap is the grasp's width)."""
    if not f.has("width_links"):
        return None
    names = f.strs("width_links")
    if len(names) != 2 or names[0] == names[1]:
        raise ConfigError(f"{f.where} field 'width_links': needs two different links (the pads), got {names}")
    for name in names:
        if name not in model.link_map or not model.link_map[name].collisions:
            raise ConfigError(f"{f.where} field 'width_links': '{name}' is not a link of the hand with collision "
                              f"geometry; links with it: "
                              f"{', '.join(k for k, v in model.link_map.items() if v.collisions)}")
    return names[0], names[1]


def _settle_dynamics(f: Fields) -> SettleDynamics | None:
    """``[settle_dynamics]``, if given: every field positive, at least one step of closing and of rest."""
    if not f.has("settle_dynamics"):
        return None
    t = f.table("settle_dynamics")
    out = SettleDynamics(t.float("steps_per_second", positive=True), t.float("close_time", positive=True),
                         t.float("rest_time", positive=True))
    for key in ("close_time", "rest_time"):
        if getattr(out, key) * out.steps_per_second < 1.0:
            raise ConfigError(f"{t.where} field '{key}': shorter than one step (1 / steps_per_second)")
    return out


def _actuators(f: Fields) -> Actuators:
    """``[dynamics]``: the motors; ``effort`` defaults to ``finger_force``."""
    effort = f.float("effort", f.float("finger_force", DEFAULT_FINGER_FORCE, positive=True), positive=True)
    return Actuators(effort, f.float("closing_speed", DEFAULT_CLOSING_SPEED, positive=True),
                     f.bool("backdrivable", True), f.get("source", "not given"))


def _link_inertia(f: Fields, model) -> dict[str, tuple[float, float, float]]:  # type: ignore[no-untyped-def]
    """``[dynamics.link_inertia]``, if given: {link of the hand: its three principal moments [kg m^2]}, each
    positive and each at most the sum of the other two (a rigid body's; MuJoCo refuses any other), of a link
    whose URDF gives it a mass (the moments replace its URDF's; the trials give a massless link none)."""
    if not f.has("link_inertia"):
        return {}
    t = f.table("link_inertia")
    links = link_names(model)
    out = {}
    for link in t.names():
        if link not in links:
            raise ConfigError(f"{t.where} field '{link}': unknown link; links: {', '.join(links)}")
        inertial = model.link_map[link].inertial
        if inertial is None or inertial.mass is None or inertial.mass <= 0:
            raise ConfigError(f"{t.where} field '{link}': its URDF gives the link no <inertial> mass: moments "
                              "replace a placeholder's of a link with one (give it <inertial> in the URDF)")
        a, b, c = t.floats(link, 3)
        if min(a, b, c) <= 0 or 2 * max(a, b, c) > a + b + c:
            raise ConfigError(f"{t.where} field '{link}': principal moments must be positive, each at most the "
                              f"sum of the other two, got {[a, b, c]}")
        out[link] = (a, b, c)
    return out


def _sampler(f: Fields, joints: tuple[JointSpec, ...]) -> str:
    name = f.str("sampler", "surface")
    if name not in SAMPLERS:
        raise ConfigError(f"{f.where} field 'sampler': unknown sampler '{name}'; use {', '.join(SAMPLERS)}")
    if name == "antipodal" and not parallel_jaw(f.bool("centering", False), joints):
        raise ConfigError(f"{f.where} field 'sampler': the antipodal sampler needs a self-centring parallel jaw "
                          "(centering = true, two prismatic fingers, one mimicking the other); use surface or box")
    return name


def parallel_jaw(centering: bool, joints: tuple[JointSpec, ...]) -> bool:
    """A self-centring parallel jaw: two prismatic finger joints, one the other's mimic."""
    prismatic = [j for j in joints if j.kind == "prismatic"]
    return centering and len(prismatic) == 2 and sum(j.mimic is not None for j in prismatic) == 1


def roll_symmetry(f: Fields) -> int:
    """The field ``roll_symmetry`` of a hand or a preshape (default 1)."""
    value = f.get("roll_symmetry", 1)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"{f.where} field 'roll_symmetry': must be a whole number >= 1")
    return value


def _joint(model: yourdfpy.URDF, source: Path, f: Fields) -> JointSpec:
    """One ``[[joints]]`` entry, its kinematics from the URDF (``source`` names
    the user's file in messages, not the cut copy)."""
    name = f.str("name")
    node = model.joint_map.get(name)
    if node is None:
        raise ConfigError(f"{f.where} field 'name': joint '{name}' is not in {source.name}; "
                          f"movable joints: {', '.join(movable_joints(model))}")
    kind = node.type or ""
    if kind not in ("revolute", "prismatic"):
        raise ConfigError(f"{f.where}: joint '{name}' is {kind}; finger joints must be revolute or prismatic")
    limit = node.limit
    lower = f.float("lower", limit.lower if limit is not None and limit.lower is not None else 0.0)
    upper = f.float("upper", limit.upper if limit is not None and limit.upper is not None else 0.0)
    if upper < lower:
        raise ConfigError(f"{f.where}: joint '{name}' has lower limit {lower} above upper {upper}")
    mimic = node.mimic
    mimic_of = f.get("mimic", mimic.joint if mimic is not None else None)
    if mimic_of is not None and mimic_of not in model.joint_map:
        raise ConfigError(f"{f.where} field 'mimic': joint '{mimic_of}' is not in {source.name}")
    multiplier = f.float("multiplier", mimic.multiplier if mimic is not None else 1.0)
    offset = f.float("offset", mimic.offset if mimic is not None else 0.0)
    breakaway = f.bool("breakaway", False)
    if breakaway and mimic_of is not None:
        raise ConfigError(f"{f.where} field 'breakaway': joint '{name}' is a mimic; set it on the driven joint "
                          f"'{mimic_of}' (its mimics close on alone once it is stopped)")
    return JointSpec(name=name, kind=kind, lower=lower, upper=upper, close=f.float("close", 0.0), mimic=mimic_of,
                     multiplier=multiplier, offset=offset, child=node.child,
                     moves=tuple(descendants(model, node.child)), breakaway=breakaway)


def _contact_models(f: Fields, links: tuple[str, ...]) -> dict[str, ContactModel]:
    table = f.table("contact", {})
    default = _contact_model(table.table("default", {"model": "point"}))
    per_link = table.table("links", {})
    models = {link: default for link in links}
    for link, spec in zip(per_link.names(), per_link.data.values()):
        if link not in links:
            raise ConfigError(f"{per_link.where}: link '{link}' is not in contact_links")
        models[link] = _contact_model(per_link.child(spec, f"{per_link.where}[{link}]"))
    return models


def _contact_model(f: Fields) -> ContactModel:
    model = f.str("model", "point")
    if model not in CONTACT_MODELS:
        raise ConfigError(f"{f.where} field 'model': unknown contact model '{model}'; use {', '.join(CONTACT_MODELS)}")
    if f.has("torsion"):
        raise ConfigError(f"{f.where} field 'torsion': replaced by 'torsion_radius' [m], the contact patch's "
                          "mean distance from its centre (the pad resists mu x torsion_radius x normal force)")
    radius = f.float("torsion_radius", 0.0)
    if model == "soft" and radius <= 0:
        raise ConfigError(f"{f.where} field 'torsion_radius': a soft contact needs a positive torsion_radius [m]")
    if radius < 0:
        raise ConfigError(f"{f.where} field 'torsion_radius': must be >= 0 [m], got {radius}")
    return ContactModel(model, radius)


def _export_frame(f: Fields) -> np.ndarray:
    """``[export] xyz, rpy``: the dataset gripper frame in the hand frame."""
    e = f.table("export", {})
    return _pose(e.floats("xyz", 3, [0, 0, 0]), e.floats("rpy", 3, [0, 0, 0]))


def _arm(f: Fields, folder: Path) -> ArmSpec | None:
    if not f.has("arm"):
        return None
    a = f.table("arm")
    mount = np.eye(4)
    if a.has("mount_xyz") or a.has("mount_rpy"):
        mount = _pose(a.floats("mount_xyz", 3, [0, 0, 0]), a.floats("mount_rpy", 3, [0, 0, 0]))
    return ArmSpec(assets.resolve(a.str("urdf"), folder, f"{a.where} field 'urdf'"), a.str("ee_link"), mount)


def _pose(xyz: list[float], rpy: list[float]) -> np.ndarray:
    """4x4 frame from a translation [m] and URDF-style roll, pitch, yaw [rad]."""
    from scipy.spatial.transform import Rotation

    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    pose[:3, 3] = xyz
    return pose
