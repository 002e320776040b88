"""The files a hand is made of, each with a digest of its content: what a
database records of the hand its grasps were made with (``meta.hand_files``,
checked by :mod:`planner.db.hand_files`), so that grasps of an edited hand
are not stored, validated or imported beside those of the hand as it was.

The files: ``hands/<name>/hand.toml`` and ``preshapes/<name>.toml`` as
parsed (comments, layout, ``4e-2`` for ``0.04``, ``70`` for ``70.0`` and the
text fields ``description``, ``taxonomy`` and ``source`` do not count), each
preshape apart (a preshape added is not an edit of the others); the URDF
that ``hand.toml`` names as parsed XML (comments, blank text and line ends
do not count) and the collision meshes of its links by their bytes (line
ends do not count); and the arm's URDF and collision meshes when the hand
has an arm (reachability). Visual meshes are left out: they draw pictures,
no stored value depends on them.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from planner import assets
from planner.errors import ConfigError
from planner.specs.hands import check_hand_name
from planner.specs.toml import read_toml
from planner.specs.urdf import mesh_path, urdf_xml

#: Hex digits of each file's sha256 kept (64 bits: a collision by chance is not a concern).
DIGEST_CHARS = 16


def hand_files(name: str) -> dict[str, str]:
    """{file label: digest} of hand ``name``'s files, labels sorted: see :func:`_label`
    (``hands/panda/hand.toml``, ``pybullet_data:franka_panda/panda.urdf``);
    one per preshape (``preshapes/panda.toml [wide]``)."""
    folder = check_hand_name(name)
    toml_path = folder / "hand.toml"
    data = read_toml(toml_path)
    out = {f"hands/{name}/hand.toml": _parsed_digest(data)}
    preshapes = assets.project_dir("preshapes") / f"{name}.toml"
    if preshapes.is_file():
        table = read_toml(preshapes)
        out[f"preshapes/{name}.toml"] = _parsed_digest({k: v for k, v in table.items() if k != "preshape"})
        for shape in table.get("preshape", []) if isinstance(table.get("preshape"), list) else []:
            if isinstance(shape, dict):
                out[f"preshapes/{name}.toml [{shape.get('name')}]"] = _parsed_digest(shape)
    urdfs = [assets.resolve(str(data["urdf"]), folder, f"{toml_path} field 'urdf'")]
    arm = data.get("arm")
    if isinstance(arm, dict) and "urdf" in arm:
        urdfs.append(assets.resolve(str(arm["urdf"]), folder, f"{toml_path} field 'arm.urdf'"))
    for urdf in urdfs:
        out[_label(urdf, name, folder)] = _xml_digest(urdf)
        for mesh in _collision_meshes(urdf):
            out[_label(mesh, name, folder)] = _bytes_digest(mesh)
    return dict(sorted(out.items()))


#: The project's own changes to a shipped hand's file that leave the hand what it was (no stored grasp's
#: geometry, joints or contacts changes; a measure or a trial of the hand's motors may): label -> (the file's
#: digest as shipped now, {an earlier shipped digest: what changed}). A database made before such a change
#: reads, shows and validates as before (its sweep is still another: ``ALGORITHM_VERSION``; verdicts record the
#: motors they were made with, so those made before are tried again); the file edited any further is an edit again.
SAME_HAND: dict[str, tuple[str, dict[str, str]]] = {
    "hands/allegro/hand.toml": ("f3604b80daac7acf", {
        "5386eec9e1cb2ab7": "2026-12-06: settle = true (a force-closure grasp's settled epsilon, for ranking); "
                            "and closing_speed 0.5 -> 7 rad/s (the settle's closing: its settled epsilons, "
                            "scores and ranks stored before are of the slower hand; its verdicts made before are "
                            "tried again; finger_force, never read, dropped)",
        "6806297ce4d71df3": "2026-12-06: closing_speed 0.5 -> 7 rad/s, the joint velocity limit of Wonik's "
                            "description (the settle's closing: its settled epsilons, scores and ranks stored "
                            "before are of the slower hand; its verdicts made before are tried again; "
                            "finger_force, never read, dropped)"}),
    "hands/allegro/allegro.urdf": ("022b5a0a47b605ce", {
        "4d5a553ee1ac0fac": "2026-12-06: the joints' velocity limit 6 -> 7 rad/s (Wonik's description; read by "
                            "nothing: hand.toml's closing_speed is the trials')"}),
    "hands/pr2/hand.toml": ("9e884185902b2d8a", {
        "5f6f243e9fb20f0e": "2026-12-06: effort 30 -> 3.15 N m (30 N at the pads) and the fingers' own inertia "
                            "([dynamics.link_inertia]): its weight resistance stored before is of the stronger "
                            "model; its verdicts made before are tried again; and width_links: its grasps stored "
                            "before have no width",
        "5782d429c3d41b3b": "2026-12-06: width_links (a grasp's width is the gap between the fingertip pads): "
                            "its grasps stored before have no width"}),
}


def changed(stored: dict[str, str], now: dict[str, str]) -> list[str]:
    """Labels of ``stored`` whose file (or preshape) is now another or gone, sorted: the edits that would mix
    two hands under one name (a file or preshape added is not one; a change of :data:`SAME_HAND` is not one)."""
    def same(label: str) -> bool:
        shipped, earlier = SAME_HAND.get(label, ("", {}))
        return stored[label] == now.get(label) or (now.get(label) == shipped and stored[label] in earlier)

    return sorted(k for k in stored if not same(k))


def declared(stored: dict[str, str], now: dict[str, str]) -> list[str]:
    """What changed, as :data:`SAME_HAND` says it, in each file of ``stored`` that the project changed since
    (an earlier shipped digest, the file as shipped now), sorted by label."""
    out = []
    for label in sorted(stored):
        shipped, earlier = SAME_HAND.get(label, ("", {}))
        if now.get(label) == shipped and stored[label] in earlier:
            out.append(f"{label}, {earlier[stored[label]]}")
    return out


def _collision_meshes(urdf: Path) -> list[Path]:
    """The mesh files of the URDF's links' ``<collision>`` elements, read with lxml (not yourdfpy, which loads
    trimesh and scipy: ``grasp best`` checks the hand's files and starts in a fraction of a second)."""
    from lxml import etree

    try:
        robot = etree.fromstring(urdf_xml(urdf))  # checked well formed, its XML declaration dropped
    except ConfigError:
        return []  # the hand's loader says what is wrong with it
    names = {m.get("filename") for m in robot.iterfind("link/collision/geometry/mesh") if m.get("filename")}
    paths = {mesh_path(urdf, n) for n in names}
    return sorted(p for p in paths if p.is_file())  # a missing mesh is the hand loader's error to give


#: Text fields that describe and do not configure (hand.toml's, a preshape's, [dynamics]').
TEXT_FIELDS = ("description", "taxonomy", "source")


def _canonical(value: object) -> object:
    """``value`` with its text fields dropped and every number a float (``70`` and ``70.0`` are one value)."""
    if isinstance(value, dict):
        return {k: _canonical(v) for k, v in value.items() if k not in TEXT_FIELDS}
    if isinstance(value, list):
        return [_canonical(v) for v in value]
    if isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def _parsed_digest(data: dict) -> str:
    text = json.dumps(_canonical(data), sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:DIGEST_CHARS]


def _bytes_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes().replace(b"\r\n", b"\n")).hexdigest()[:DIGEST_CHARS]


def _xml_digest(path: Path) -> str:
    """The URDF as parsed: without comments and blank text, canonical XML (line ends and attribute order do not
    count); its bytes if it does not parse (the hand's loader says why)."""
    from lxml import etree

    try:
        tree = etree.fromstring(path.read_bytes(), etree.XMLParser(remove_comments=True, remove_blank_text=True))
        data = etree.tostring(tree, method="c14n")
    except (etree.XMLSyntaxError, ValueError):
        return _bytes_digest(path)
    return hashlib.sha256(data).hexdigest()[:DIGEST_CHARS]


def _label(path: Path, name: str, folder: Path) -> str:
    """A file's label: under the hand's folder (as named, whatever it links to), ``pybullet_data`` or the
    project; else its absolute path."""
    path = path.resolve()
    for root, prefix in ((folder.resolve(), f"hands/{name}/"),
                         (assets.pybullet_data_root().resolve(), assets.PYBULLET_DATA_PREFIX),
                         (assets.PROJECT_ROOT, "")):
        if path.is_relative_to(root):
            return prefix + path.relative_to(root).as_posix()
    return str(path)
