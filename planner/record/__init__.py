"""The record floor: the value types a grasp takes from the sweep to the
database to every export, below every stage that makes or reads them.

- :mod:`planner.record.grasp`: the grasp record (:class:`~planner.record.grasp.Grasp`,
  its joints, its shake trial and robust epsilon);
- :mod:`planner.record.contacts`: the contacts record;
- :mod:`planner.record.measures`: the analytic measures record;
- :mod:`planner.record.fields`: every stored field, declared once (name,
  dtype, SQL type, unit, neutral value, schema version, whether the ranking
  reads it, one line of doc); the store, the ranking's inputs, every export
  and the README's column table are derived from it.

Nothing here imports a stage (``planner.plan``, ``db``, ``datasets`` ...):
the stages import the record.
"""
