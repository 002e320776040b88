"""The store's writes: a unit with its object and grasps, trial results, a
p_hold model, the ranking rule and meta values, each in one transaction
that re-scores and re-ranks what it touched (:class:`Writing`, the part of
:class:`~planner.db.store.Database` that writes). Scores are never computed
in SQL: the hand's p_hold model and the ranking rule make them here, from
the measures the SQL below reads.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.calibration import features
from planner.calibration.model import LogisticModel
from planner.db.columns import (
    _ALIAS,
    _FILE_LABEL,
    _FILE_LABEL_COLUMNS,
    _GRASP_COLUMNS,
    _GRASPS,
    _MUJOCO,
    _MUJOCO_COLUMNS,
    _OBJECT_COLUMNS,
    _OBJECTS,
    _ROBUST,
    _ROBUST_COLUMNS,
    _TRIAL,
    _UNIT_COLUMNS,
    _VALIDATION_COLUMNS,
    _insert,
    _json,
    _row,
    _sql,
)
from planner.db.failures import write_failed
from planner.db.ranking import FORMULA, ORDER_BY, RankingRule, first_measures, rank_order, ranks_first, rule_measures
from planner.db.rows import UnitRow, Validated
from planner.db.schema import transaction
from planner.errors import DatabaseError, InputError
from planner.record import fields
from planner.record.field import same_inertial
from planner.record.grasp import Grasp

if TYPE_CHECKING:
    from planner.geometry.solid import PreparedObject


def now_text() -> str:
    """Now as ``units.finished_at`` and ``calibration.created_at`` keep it: UTC with its offset, ISO 8601, to the
    microsecond, the same instant wherever the database is read (rows written before 2026-12-05: local time
    without offset, to the second); :func:`datetime.datetime.fromisoformat` reads both."""
    return datetime.now(timezone.utc).isoformat(timespec="microseconds")


#: What the ranking rule reads, by the rule's names.
_RANKED = ", ".join(f"{_ALIAS[f.table]}.{f.column} AS {f.ranked}" for f in fields.ranked_fields())
#: The stored columns a p_hold model reads (:data:`planner.calibration.features.COLUMNS`), as ``m_<column>``.
_MODEL_INPUTS = ", ".join(f"g.{fields.by_name(name).column} AS m_{name}" for name in features.COLUMNS)
_MEASURES = f"""
SELECT g.id, g.object, g.hand, {_RANKED}{{inputs}}
FROM grasps g LEFT JOIN validation v ON v.grasp_id = g.id LEFT JOIN mujoco mj ON mj.grasp_id = g.id
LEFT JOIN robust r ON r.grasp_id = g.id
"""
_RERANK = f"""
WITH ranked AS (
    SELECT id, ROW_NUMBER() OVER (ORDER BY {ORDER_BY}) AS r FROM grasps WHERE object = ? AND hand = ?
)
UPDATE grasps SET rank = ranked.r FROM ranked WHERE grasps.id = ranked.id
"""


def p_hold_of(col: dict, models: dict[str, LogisticModel | None]) -> tuple[list[float | None], list[float | None]]:
    """(p_hold, p_hold_trial) of stored grasps rows (columns ``col``:
    ``hand``, the model inputs of :data:`_MODEL_INPUTS`, named
    ``m_<column>``, and the trials' ranked verdicts) by each row's hand's
    model; None where the hand has none (and p_hold_trial None where no
    trial with an update tried the grasp)."""
    n = len(col["hand"])
    p_hold: list[float | None] = [None] * n
    p_trial: list[float | None] = [None] * n
    for hand in sorted(set(col["hand"])):
        model = models.get(hand)
        if model is None:
            continue
        rows = [i for i, h in enumerate(col["hand"]) if h == hand]
        sub = {k: [col["m_" + k][i] for i in rows] for k in features.COLUMNS}
        p = model.predict(features.of_columns(sub))
        q = model.given_trial(p, verdicts({name: [col[name][i] for i in rows] for name in fields.TRIAL_SUCCESS}))
        for i, a, b in zip(rows, p.tolist(), q.tolist()):
            p_hold[i], p_trial[i] = a, None if b != b else b
    return p_hold, p_trial


def verdicts(ranked: Mapping[str, Sequence | np.ndarray]) -> dict[str, np.ndarray]:
    """Trial group -> (n,) verdicts (NaN: not tried) from the rule's ranked success columns."""
    return {group: np.array([np.nan if v is None else v for v in ranked[name]], float)
            for group, name in zip(fields.TRIAL_PRECEDENCE, fields.TRIAL_SUCCESS)}


class Writing:
    """The writes of :class:`~planner.db.store.Database` (which holds the
    connection and answers the reads declared below), each one transaction,
    and the scores and ranks they re-make."""

    path: Path
    _conn: sqlite3.Connection

    if TYPE_CHECKING:  # the reads of planner.db.store.Database
        def meta(self, key: str) -> str | None: ...

        def rule(self) -> RankingRule: ...

        def pairs(self) -> list[tuple[str, str]]: ...

        def model(self, hand: str) -> LogisticModel | None: ...

        def _models(self, hands: Iterable[str]) -> dict[str, LogisticModel | None]: ...

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """One atomic write (:func:`planner.db.schema.transaction`); a write
        that fails says in one line why, and that what was committed before
        it is kept."""
        try:
            with transaction(self._conn, self.path) as conn:
                yield conn
        except DatabaseError as exc:
            if not isinstance(exc.__cause__, sqlite3.Error):
                raise
            raise DatabaseError(write_failed(self.path, exc.__cause__, self._units_kept())) from exc.__cause__

    def _units_kept(self) -> int | None:
        try:
            return int(self._conn.execute("SELECT COUNT(*) FROM units WHERE status = 'done'").fetchone()[0])
        except sqlite3.Error:
            return None

    def set_meta(self, key: str, value: str) -> None:
        with self._transaction() as conn:
            self._set_meta(conn, key, value)

    @staticmethod
    def _set_meta(conn: sqlite3.Connection, key: str, value: str) -> None:
        conn.execute("INSERT INTO meta (key, value) VALUES (?, ?)"
                     " ON CONFLICT(key) DO UPDATE SET value = excluded.value", (key, value))

    def write_unit(self, unit: UnitRow, obj: PreparedObject | None, grasps: Sequence[Grasp],
                   rule: RankingRule) -> int:
        """Store a finished (or failed) unit, its object and its grasps
        atomically, then re-rank the object's grasps; returns the unit's id."""
        key = (unit.object, unit.hand, unit.settings_hash, unit.seed, unit.chunk)
        status = "failed" if unit.error else "done"
        scores, p_hold, p_trial = self._scores(grasps, unit.hand, rule)
        with self._transaction() as conn:
            conn.execute("DELETE FROM units WHERE object = ? AND hand = ? AND settings_hash = ? AND seed = ?"
                         " AND chunk = ?", key)
            unit_id = conn.execute(_insert("units", _UNIT_COLUMNS), (
                *key, unit.settings, status, unit.error, unit.candidates, len(grasps),
                sum(g.force_closure for g in grasps), _json(unit.rejected), unit.seconds,
                now_text())).lastrowid
            if obj is not None:
                stored = conn.execute("SELECT mesh_sha256, up, com, inertia FROM objects WHERE name = ?",
                                      (unit.object,)).fetchone()
                if stored is not None and stored[0] and stored[0] != obj.mesh_hash:
                    raise InputError(f"object '{unit.object}' is stored in {self.path} from another mesh than this "
                                     "unit's: its grasps were planned on the stored one; nothing of this unit written")
                if stored is not None and stored[1] != obj.spec.up:
                    raise InputError(f"object '{unit.object}' is stored in {self.path} with up {stored[1]}, this "
                                     f"unit's is {obj.spec.up}: its grasps were measured about the stored one; nothing "
                                     "of this unit written")
                if stored is not None and not same_inertial(obj.com, obj.inertia, json.loads(stored[2]),
                                                            json.loads(stored[3])):
                    raise InputError(f"object '{unit.object}' is stored in {self.path} with another centre of mass or "
                                     f"inertia than this unit's (centre {stored[2]} m; now "
                                     f"{np.round(obj.com, 7).tolist()}): its grasps were measured about the stored "
                                     "ones; nothing of this unit written")
                if stored is None:  # a stored row stays as it is: its source is where its first grasps came from
                    conn.execute(_insert("objects", _OBJECT_COLUMNS), _object_row(unit.object, obj))
            conn.executemany(_insert("grasps", _GRASP_COLUMNS),
                             [_grasp_row(g, unit_id, score, p, q)
                              for g, score, p, q in zip(grasps, scores.tolist(), p_hold, p_trial)])
            labelled = [g for g in grasps if g.file_label is not None]  # an import's: its file's labels
            if labelled:
                ids = {(c, bool(end)): i for i, c, end in conn.execute(
                    "SELECT id, candidate, squeezed_from_turn IS NOT NULL FROM grasps WHERE unit_id = ?", (unit_id,))}
                conn.executemany(_insert("file_labels", _FILE_LABEL_COLUMNS), [
                    (ids[g.candidate, g.squeezed_from_turn is not None], *_row(_FILE_LABEL, g.file_label), 0,
                     _json({"imported": unit.settings})) for g in labelled])
            conn.execute(_RERANK, (unit.object, unit.hand))
            known = json.loads(self.meta("p_hold_models") or "{}")
            if grasps and unit.hand not in known:  # a hand's first grasps, scored just now by its model
                known[unit.hand] = self._model_hash(unit.hand)  # (else the next run re-scores them all once)
                self._set_meta(conn, "p_hold_models", json.dumps(known, sort_keys=True))
        return int(unit_id)  # type: ignore[arg-type]

    def up_told(self, obj: str, hand: str, settings_hash: str) -> None:
        """``obj``'s import units for ``hand`` of the file ``settings_hash`` (its digest) that took the object's up
        untold (their settings' ``up_taken``): told now (the same file imported again with --up or beside a
        sidecar's up; the up is the stored one, else the import is refused), their settings without it."""
        rows = self._conn.execute("SELECT id, settings FROM units WHERE object = ? AND hand = ? AND settings_hash = ? "
                                  "AND settings LIKE '%\"up_taken\"%'", (obj, hand, settings_hash)).fetchall()
        if not rows:  # nothing written
            return
        with self._transaction() as conn:
            for unit_id, settings in rows:
                kept = {k: v for k, v in json.loads(settings).items() if k != "up_taken"}
                conn.execute("UPDATE units SET settings = ? WHERE id = ?", (json.dumps(kept, sort_keys=True), unit_id))

    def remove_sweep(self, obj: str, hand: str, seed: int, settings: str) -> int:
        """Remove every unit of ``obj`` for ``hand`` with ``seed`` and
        ``settings`` (JSON, as stored), their grasps and the grasps' trials
        (foreign keys cascade), and re-rank the rest, in one transaction;
        returns the number of grasps removed."""
        with self._transaction() as conn:
            where = "FROM units WHERE object = ? AND hand = ? AND seed = ? AND settings = ?"
            key = (obj, hand, seed, settings)
            count = conn.execute(f"SELECT COALESCE(SUM(grasps), 0) {where}", key).fetchone()[0]
            conn.execute(f"DELETE {where}", key)
            conn.execute(_RERANK, (obj, hand))
        return int(count)

    def _scores(self, grasps: Sequence[Grasp], hand: str, rule: RankingRule) -> tuple[np.ndarray, list, list]:
        """(n,) scores, the n p_hold and the n p_hold_trial values (None: no
        model, no trial with an update) of grasps of ``hand`` as
        :meth:`write_unit` stores them."""
        measures = rule_measures(grasps)
        model = self.model(hand)
        p_hold: list = [None] * len(grasps)
        p_trial: list = [None] * len(grasps)
        measures["p_hold"] = measures["p_hold_trial"] = np.full(len(grasps), np.nan)  # the model's, not the record's
        if model is not None and grasps:  # the hand's model, on the records' measures; the rule reads it
            # as stored (pose and contacts rounded): from the unrounded record, p_hold was up to 1e-5 off what the
            # stored grasp gives, so a re-score (`grasp calibrate`, an import of its export) changed it and its rank
            measures["p_hold"] = model.predict(features.of_grasps([g.as_stored() for g in grasps]))
            measures["p_hold_trial"] = model.given_trial(measures["p_hold"], verdicts(measures))
            p_hold = measures["p_hold"].tolist()
            p_trial = [None if v != v else v for v in measures["p_hold_trial"].tolist()]
        return rule.scores(measures), p_hold, p_trial

    def scored(self, grasps: Sequence[Grasp], hand: str) -> list[Grasp]:
        """Grasps not stored (planned by a query) with the score and p_hold
        this database would give them (its rule, the hand's model), best
        first as it would rank them (:func:`planner.db.ranking.rank_order`;
        ties in the given order); ``rank`` stays None."""
        if not grasps:
            return []
        scores, p_hold, p_trial = self._scores(grasps, hand, self.rule())
        out = [replace(g, score=float(s), p_hold=p, p_hold_trial=q)
               for g, s, p, q in zip(grasps, scores.tolist(), p_hold, p_trial)]
        return [out[i] for i in rank_order(scores, ranks_first(first_measures(grasps)))]

    # -- ranking ---------------------------------------------------------------
    def apply_rule(self, rule: RankingRule, force: bool = False) -> bool:
        """Store ``rule``; if it differs from the stored one, or a hand's p_hold
        model is not the one its scores were made with (a new shipped model),
        or ``force``, re-score and re-rank every grasp in one transaction."""
        models = self._models_key()
        if self.meta("ranking") == rule.to_json() and self.meta("p_hold_models") == models and not force:
            return False
        with self._transaction() as conn:
            self._set_meta(conn, "ranking", rule.to_json())
            self._set_meta(conn, "p_hold_models", models)
            self._rescore(conn, rule)
        return True

    def rank_anew(self) -> bool:
        """Re-score and re-rank every grasp by the stored rule's weights where the stored ranks predate this
        version's rank order (``meta.ranking``'s formula is another): what each write does first
        (:func:`~planner.db.store.open_for_writing`), so that the pairs it re-ranks and those it leaves follow one
        order, the one the records read back tell (:func:`~planner.db.ranking.ranked_with_ends`)."""
        stored = self.meta("ranking")
        return stored is not None and json.loads(stored).get("formula") != FORMULA and self.apply_rule(self.rule())

    def _models_key(self) -> str:
        """Which p_hold model scores each stored hand (JSON, hashes of the
        models): scores made with other models are re-made by the next write."""
        hands = sorted({h for _, h in self.pairs()})
        return json.dumps({h: self._model_hash(h) for h in hands}, sort_keys=True)

    def _model_hash(self, hand: str) -> str | None:
        return None if (m := self.model(hand)) is None else hashlib.sha256(m.to_json().encode()).hexdigest()[:16]

    def _rescore(self, conn: sqlite3.Connection, rule: RankingRule, pair: tuple[str, str] | None = None,
                 hand: str | None = None) -> None:
        """Scores from the rule (all grasps, one object and hand, or one hand)
        and ranks, inside the caller's transaction."""
        where, params = ("", ()) if pair is None else (" WHERE g.object = ? AND g.hand = ?", pair)
        if hand is not None:
            where, params = " WHERE g.hand = ?", (hand,)
        hands = [r["hand"] for r in conn.execute("SELECT DISTINCT g.hand FROM grasps g" + where, params)]
        models = self._models(hands)
        inputs = ", " + _MODEL_INPUTS if any(m is not None for m in models.values()) else ""
        rows = conn.execute(_MEASURES.format(inputs=inputs) + where, params).fetchall()
        if not rows:
            return
        col = dict(zip(rows[0].keys(), zip(*rows)))
        col["p_hold"], col["p_hold_trial"] = p_hold_of(col, models)  # the model's, not the stored: it may be new
        scores = rule.scores({f.ranked: col[f.ranked] for f in fields.ranked_fields()})
        conn.executemany("UPDATE grasps SET score = ?, p_hold = ?, p_hold_trial = ? WHERE id = ?",
                         zip(scores.tolist(), col["p_hold"], col["p_hold_trial"], col["id"]))
        ranked = set(zip(col["object"], col["hand"]))
        for o, h in sorted(ranked):
            conn.execute(_RERANK, (o, h))
        self._set_unranked(conn, self._unranked() - ranked)

    def write_model(self, model: LogisticModel, source: str, rule: RankingRule) -> None:
        """Store ``model`` as its hand's p_hold model (replacing any), then
        re-score and re-rank that hand's grasps, in one transaction."""
        with self._transaction() as conn:
            conn.execute(_insert("calibration", ("hand", "model", "source", "created_at"), "INSERT OR REPLACE"),
                         (model.hand, model.to_json(), source, now_text()))
            self._rescore(conn, rule, hand=model.hand)
        self.set_meta("p_hold_models", self._models_key())

    def write_validation(self, obj: str, hand: str, results: Sequence[Validated], rule: RankingRule,
                         rescore: bool = True) -> None:
        """Store trial (PyBullet, MuJoCo) and robust-epsilon results of grasps
        of one (object, hand), then (``rescore``) re-score and re-rank it, in
        one transaction. A caller that writes many batches of one pair passes
        False but for the last and calls :meth:`rescore` if it stops early:
        re-ranking costs time linear in the pair's grasps, per batch."""
        with self._transaction() as conn:
            for v in results:
                if v.trial is not None:
                    t = v.trial
                    conn.execute(_insert("validation", _VALIDATION_COLUMNS, "INSERT OR REPLACE"),
                                 (v.grasp_id, *_row(_TRIAL, t), v.seed, v.trial_settings))
                if v.mujoco is not None:
                    conn.execute(_insert("mujoco", _MUJOCO_COLUMNS, "INSERT OR REPLACE"),
                                 (v.grasp_id, *_row(_MUJOCO, v.mujoco), v.seed, v.mujoco_settings))
                if v.robust is not None:
                    r = v.robust
                    conn.execute(_insert("robust", _ROBUST_COLUMNS, "INSERT OR REPLACE"),
                                 (v.grasp_id, *_row(_ROBUST, r), v.seed, v.robust_settings))
            if rescore:
                self._rescore(conn, rule, (obj, hand))
            else:
                self._set_unranked(conn, self._unranked() | {(obj, hand)})

    def rescore(self, obj: str, hand: str, rule: RankingRule) -> None:
        """Re-score and re-rank the grasps of one (object, hand) from what is stored."""
        with self._transaction() as conn:
            self._rescore(conn, rule, (obj, hand))

    def unranked(self) -> list[tuple[str, str]]:
        """The (object, hand) pairs whose verdicts were written without a re-rank
        (a ``grasp validate`` killed before it re-ranked them)."""
        return sorted(self._unranked())

    def _unranked(self) -> set[tuple[str, str]]:
        return {(o, h) for o, h in json.loads(self.meta(UNRANKED) or "[]")}

    def _set_unranked(self, conn: sqlite3.Connection, pairs: set[tuple[str, str]]) -> None:
        if pairs != self._unranked():
            self._set_meta(conn, UNRANKED, json.dumps(sorted(pairs)))


def _object_row(name: str, obj: PreparedObject) -> tuple:
    """The objects row of a prepared object (:data:`_OBJECT_COLUMNS`)."""
    given = {"name": name, "source": obj.source_file, "scale": obj.file_scale, "mesh_sha256": obj.mesh_hash,
             "extents": obj.mesh.extents, "up": obj.spec.up, "geometry": obj.spec.geometry}
    return tuple(_sql(f, given[f.column] if f.column in given else getattr(obj, f.column)) for f in _OBJECTS)


def _grasp_row(g: Grasp, unit_id: int, score: float, p_hold: float | None, p_trial: float | None) -> tuple:
    """The insert values of a record (:data:`_GRASP_COLUMNS`): what the store
    made of it (the unit, the rule's score, the hand's model's p_hold and
    p_hold_trial) and the record's own values."""
    given = {"unit_id": unit_id, "score": score, "p_hold": p_hold, "p_hold_trial": p_trial}
    return tuple(given[f.column] if f.column in given else _sql(f, get(g)) for f, get in _INSERTED)


#: The meta key of the (object, hand) pairs with verdicts written but not yet re-ranked (JSON list).
UNRANKED = "unranked"

_INSERTED = [(f, fields.getter(f)) for f in _GRASPS if f.column in _GRASP_COLUMNS]
