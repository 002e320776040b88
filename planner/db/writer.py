"""The single database writer: one transaction per unit of work."""

from __future__ import annotations

import json
import sqlite3
import time

import numpy as np

from planner.db.ranking import RERANK_SQL, RESCORE_SQL, RankingRule
from planner.db.store import Database
from planner.plan.unit import UnitResult


def _j(values: object) -> str:
    return json.dumps(values, separators=(",", ":"))


def _vec(a: np.ndarray, digits: int = 7) -> list[float]:
    return [round(float(v), digits) for v in np.ravel(a)]


def write_unit(db: Database, result: UnitResult, seconds: float, rule: RankingRule | None = None) -> None:
    """Store a finished (or failed) unit and its grasps atomically, then re-rank."""
    rule = rule or RankingRule.from_json(db.meta("ranking"))
    spec = result.spec
    obj = result.obj
    name = obj.name if obj is not None else (spec.label or spec.object_name)
    status = "failed" if result.error else "done"
    with db.transaction() as conn:
        conn.execute("DELETE FROM units WHERE object = ? AND hand = ? AND settings_hash = ? AND seed = ? AND chunk = ?",
                     (name, spec.hand, spec.settings.digest, spec.seed, spec.chunk))
        cur = conn.execute(
            "INSERT INTO units (object, hand, settings_hash, seed, chunk, settings, status, error, candidates, grasps,"
            " force_closure, rejected, seconds, finished_at) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
            (name, spec.hand, spec.settings.digest, spec.seed, spec.chunk, spec.settings.to_json(), status,
             result.error,
             result.candidates, len(result.grasps), result.force_closure, _j(dict(result.rejected)), seconds,
             time.strftime("%Y-%m-%dT%H:%M:%S")))
        unit_id = cur.lastrowid
        if obj is not None:
            conn.execute(
                "INSERT OR REPLACE INTO objects (name, source, scale, mesh_sha256, mass, friction, density, volume,"
                " com, inertia, torque_scale, extents) VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
                (name, obj.source_file, obj.file_scale, obj.mesh_hash, obj.mass, obj.friction, obj.density,
                 obj.volume, _j(_vec(obj.com)), _j(_vec(obj.inertia, 10)), obj.torque_scale,
                 _j(_vec(obj.mesh.extents))))
        conn.executemany(
            "INSERT INTO grasps (unit_id, object, hand, preshape, candidate, approach_point, approach_dir, roll,"
            " standoff, pose, open_joints, closed_joints, width, contacts, n_contacts, links_touching, epsilon,"
            " volume, force_closure, reachability, manipulability, seed, score)"
            " VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
            [(unit_id, name, spec.hand, g.preshape, g.candidate, _j(_vec(g.approach_point)),
              _j(_vec(g.approach_dir)), g.roll, g.standoff, _j(_vec(g.closed.pose)),
              _j(g.closed.open_joints), _j(g.closed.closed_joints), g.width, _j(g.closed.contacts.to_json()),
              len(g.closed.contacts), len(g.closed.contacts.touching_links), g.epsilon, g.volume,
              int(g.force_closure), g.reachability, g.manipulability, spec.seed,
              rule.score(g.epsilon, g.force_closure, g.reachability))
             for g in result.grasps])
        conn.execute(RERANK_SQL, (name, spec.hand))


def apply_rule(db: Database, rule: RankingRule, force: bool = False) -> bool:
    """Store ``rule``; if it differs from the stored one (or ``force``),
    re-score and re-rank every grasp in one transaction."""
    if db.meta("ranking") == rule.to_json() and not force:
        return False
    with db.transaction() as conn:
        db.set_meta(conn, "ranking", rule.to_json())
        rescore(conn, rule)
    return True


def rescore(conn: sqlite3.Connection, rule: RankingRule, obj: str | None = None, hand: str | None = None) -> None:
    """Recompute scores (all, or one object and hand) and re-rank, inside the caller's transaction."""
    expr, params = rule.sql()
    if obj is None:
        conn.execute(RESCORE_SQL.format(expr=expr, where="1"), params)
        pairs = conn.execute("SELECT DISTINCT object, hand FROM grasps").fetchall()
    else:
        conn.execute(RESCORE_SQL.format(expr=expr, where="object = ? AND hand = ?"), (*params, obj, hand))
        pairs = [(obj, hand)]
    for o, h in pairs:
        conn.execute(RERANK_SQL, (o, h))
