"""Every stored field, declared once.

The record types declare their stored attributes (:func:`~planner.record.field.stored`
on :class:`~planner.record.grasp.Grasp`, :class:`~planner.record.grasp.Trial`,
:class:`~planner.record.grasp.RobustEpsilon`, :class:`~planner.record.grasp.FileLabel`,
:class:`~planner.record.measures.Measures`);
this module collects them, in record order, with the columns that are stored
but are not record attributes (``n_contacts``, the trial's ``seed``, the
objects' mass properties ...), as :data:`FIELDS`. Derived from it: the
store's column lists, inserts and decoding (:mod:`planner.db.store`), the
ranking's inputs (:func:`ranked_fields`, read by :func:`planner.db.ranking.rule_measures`),
every export's columns and qualities (:mod:`planner.datasets`), ``grasp best
--json`` (:meth:`Grasp.to_json`), ``grasp report``'s measures and the
README's column table (:func:`markdown_table`). The migrations that create
the columns stay hand-written (:mod:`planner.db.schema`); a test checks that
schema and migrations give exactly these columns.

Adding a measure: compute it (:mod:`planner.plan.measures`), declare it (one
``stored`` attribute of ``Measures``), migrate (:mod:`planner.db.schema`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from planner.record.field import Field, declared
from planner.record.grasp import FileLabel, Grasp, RobustEpsilon, Trial
from planner.record.measures import Measures


@dataclass(frozen=True)
class Group:
    """A part of the record stored in a table of its own (or with the grasps).

    cls: the type of its value; table: the table that stores it; prefix: of
    its flat names (``validation_success``); version: the schema version the
    table appeared in (older files lack it); engine: the simulator of a trial
    group (its docs name it); ranked: prefix of the names the ranking rule
    reads its ranked fields by (the PyBullet trial's ``success``, the MuJoCo
    trial's ``mujoco_success``).
    """

    cls: type
    table: str
    prefix: str
    version: int = 1
    engine: str = ""
    ranked: str = ""


#: Record attribute -> its group. Each dynamic protocol stores its verdicts apart
#: (``validation``: PyBullet, ``mujoco``: MuJoCo, :mod:`planner.validation.mujoco_trial`).
GROUPS: dict[str, Group] = {
    "validation": Group(Trial, "validation", "validation_", 2, "PyBullet"),
    "mujoco": Group(Trial, "mujoco", "mujoco_", 7, "MuJoCo", "mujoco_"),
    "robust": Group(RobustEpsilon, "robust", "robust_", 2),
    "file_label": Group(FileLabel, "file_labels", "file_label_", 16),
    "measures": Group(Measures, "grasps", ""),
}
#: The groups that hold a dynamic trial's verdict (a :class:`~planner.record.grasp.Trial`).
TRIALS = tuple(name for name, g in GROUPS.items() if g.cls is Trial)
#: Which trial's verdict a grasp's label and rank take where several tried it: the first of these
#: present. MuJoCo's first: against ACRONYM's FleX labels it agrees on 79.7% of 276 tuning poses and
#: 75.0% of 560 held-out ones, PyBullet's on 63.4% and 62.1%, and "held in both" on 64.5%
#: (bench/RESULTS.md): a verdict that needs both is as far from the reference as the worse one.
TRIAL_PRECEDENCE = ("mujoco", "validation")
#: The ranked names of :data:`TRIAL_PRECEDENCE`'s success fields, in that order.
TRIAL_SUCCESS = tuple(f"{GROUPS[name].ranked}success" for name in TRIAL_PRECEDENCE)


def _from_record(cls: type, table: str, prefix: str, group: str, engine: str = "", ranked: str = "",
                 version: int = 0) -> list[Field]:
    """The declared fields of a record type; a trial group's docs name its
    ``engine``, its ranked names take the prefix ``ranked`` and none is
    older than its table's ``version``."""
    out = []
    for f in dataclasses.fields(cls):
        meta = f.metadata.get("stored")
        if meta is None:
            continue
        column = meta["column"] or f.name
        doc = meta["doc"].replace("{engine}", engine) if engine else meta["doc"]
        out.append(declared(table, column, f"{group}.{f.name}" if group else f.name, meta["kind"], meta["unit"],
                            max(meta["version"], version), doc, name=prefix + column, required=meta["required"],
                            key=meta["key"], ranked=ranked + meta["ranked"] if meta["ranked"] else "",
                            shape=meta["shape"]))
    return out


def _grasps() -> list[Field]:
    """The ``grasps`` table: the record's own fields (contacts followed by its
    two counts), then its analytic measures."""
    out = []
    for f in _from_record(Grasp, "grasps", "", ""):
        out.append(f)
        if f.name == "contacts":
            out += [declared("grasps", "n_contacts", "contacts.count", "int", "", 1, "number of contacts"),
                    declared("grasps", "links_touching", "contacts.touching", "int", "", 1,
                             "number of hand links touching the object")]
    return out + _from_record(Measures, "grasps", "", "measures")


def _validation(group: str) -> list[Field]:
    """A validation table: the grasp it belongs to, the record's fields, and how they were made."""
    g = GROUPS[group]
    table, prefix, v = g.table, g.prefix, g.version
    return [declared(table, "grasp_id", "id", "int", "", v, "the grasp (`grasps.id`; the primary key)",
                     name=f"{prefix}grasp_id", key=True),
            *_from_record(g.cls, table, prefix, group, g.engine, g.ranked, v),
            declared(table, "seed", "", "int", "", v, "0: a file's label has no noise" if group == "file_label" else
                     "seed of the noise", name=f"{prefix}seed"),
            declared(table, "settings", "", "text", "", v, "JSON settings that made it", name=f"{prefix}settings")]


def _objects() -> list[Field]:
    def obj(column: str, kind: str, unit: str, doc: str, shape: tuple[int, ...] = (), version: int = 1) -> Field:
        return declared("objects", column, "", kind, unit, version, doc, name=f"object_{column}",
                        key=column == "name", shape=shape)

    return [obj("name", "text", "", "object name"),
            obj("source", "text", "", "the mesh or URDF file, or `primitive:<kind>`"),
            obj("scale", "real", "", "what turns `source` into metres"),
            obj("mesh_sha256", "text", "", "hash of the checked mesh the grasps were planned on"),
            obj("mass", "real", "kg", "mass"), obj("friction", "real", "", "friction coefficient used for the quality"),
            obj("density", "real", "kg/m^3", "uniform density"), obj("volume", "real", "m^3", "volume of the mesh"),
            obj("com", "vector", "m", "centre of mass, object frame: the one given (a sidecar's `com`, a URDF's "
                "`<inertial>`), else the mesh's at uniform density", (3,)),
            obj("inertia", "vector", "kg m^2", "inertia about the centre of mass, object axes: a URDF's where "
                "plausible, else the mesh's at uniform density", (3, 3)),
            obj("torque_scale", "real", "m", "torque scale of the wrenches"),
            obj("extents", "vector", "m", "bounding box extents", (3,)),
            obj("up", "text", "", "the object's up as it stands, an axis of the object frame (`+z`, `+y`, ...): "
                "`com_height`, `gravity_arm` and the MuJoCo trial's weight read it; `+z` for objects stored before",
                version=12),
            obj("geometry", "text", "", "the elements of a URDF file the object is made of, `collision` or `visual` "
                "(`collision` for objects stored before)", version=13)]


#: Every stored field of the record's tables, in record order.
FIELDS: tuple[Field, ...] = (*_grasps(), *_validation("validation"), *_validation("mujoco"), *_validation("robust"),
                             *_validation("file_label"), *_objects())
#: The tables these fields fill (``units`` and ``meta`` are the run's bookkeeping, not the record's).
TABLES = ("grasps", "validation", "mujoco", "robust", "file_labels", "objects")


def table(name: str) -> tuple[Field, ...]:
    """The declared fields of one table, in order."""
    return tuple(f for f in FIELDS if f.table == name)


def group(name: str) -> tuple[Field, ...]:
    """The fields of one record group (``measures``, ``validation``, ``mujoco``, ``robust``, ``file_label``) the
    record holds."""
    return tuple(f for f in FIELDS if f.attr.startswith(name + "."))


def record_fields() -> tuple[Field, ...]:
    """Every field a :class:`Grasp` holds (its own, counts, measures, trial, robust), flat names unique."""
    return tuple(f for f in FIELDS if f.table != "objects" and f.attr and not f.name.endswith("grasp_id"))


def ranked_fields() -> tuple[Field, ...]:
    """The fields the ranking rule reads, by the rule's names."""
    return tuple(f for f in FIELDS if f.ranked)


def by_name(name: str) -> Field:
    for f in FIELDS:
        if f.name == name:
            return f
    raise KeyError(f"no stored field '{name}'; fields: {', '.join(f.name for f in FIELDS)}")


def getter(f: Field) -> Callable[[Grasp], object]:
    """record -> the field's value (None where the record's group is absent)."""
    head, _, tail = f.attr.partition(".")
    if not tail:
        return lambda g: getattr(g, head)
    return lambda g: None if (part := getattr(g, head)) is None else getattr(part, tail)


def values(f: Field, grasps: Sequence[Grasp]) -> list:
    """The field's value of each record (None: absent)."""
    get = getter(f)
    return [get(g) for g in grasps]


def json_value(f: Field, value: object) -> object:
    """A value as ``grasp best --json`` prints it: vectors as nested lists,
    joints as objects, contacts as their items, an infinite margin and
    anything absent as null, reasons as a list."""
    if value is None:
        return None
    kind = f.kind
    if kind == "vector":
        return value.tolist()  # type: ignore[attr-defined]
    if kind == "joints":
        return dict(value)  # type: ignore[call-overload]
    if kind == "contacts":
        return value.to_json()  # type: ignore[attr-defined]
    if kind == "margin":
        return float(value) if math.isfinite(value) else None  # type: ignore[arg-type]
    if kind == "reasons":
        return list(value)  # type: ignore[call-overload]
    return value


def markdown_table(fields: Sequence[Field] = FIELDS) -> str:
    """The README's column table: one row per field."""
    rows = ["| field | table.column | type | unit | since | ranked | meaning |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    for f in fields:
        shape = "x".join(map(str, f.shape))
        rows.append(f"| `{f.name}` | `{f.table}.{f.column}` | {f.sql}{f' ({shape} {f.dtype})' if shape else ''} | "
                    f"{f.unit} | v{f.version} | {f.ranked and '`' + f.ranked + '`'} | {f.doc} |")
    return "\n".join(rows) + "\n"
