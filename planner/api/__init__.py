"""The Python API, the one facade of the project: the ``grasp`` CLI only
wraps these functions (and the names re-exported here).

- building: :func:`generate` (sweep objects for a hand into a database), in
  :mod:`~planner.api.building`;
- querying: :func:`best` (:mod:`~planner.api.querying`), :func:`best_at`
  (grasps an arm reaches now, :mod:`~planner.api.reaching`),
  :func:`best_on_table` (:mod:`~planner.api.on_table`), :func:`show`
  (:mod:`~planner.api.presenting`), each naming the object as
  :func:`resolve_object` reads it (:mod:`~planner.api.resolving`);
- validating: :func:`validate`, :func:`report`;
- calibrating: :func:`calibrate` (p_hold fitted to labelled grasp files),
  in :mod:`~planner.api.calibrating` with :func:`report`;
- datasets: :func:`export`, :func:`import_files`;
- descriptions: :func:`hands`, :func:`hand`, :func:`objects`,
  :func:`stored_objects` (:mod:`~planner.api.describing`);
- maintenance: :func:`check_db`.

This module defines nothing else: every function lives in one of the
modules named above and is re-exported here, so ``api.X`` is the one way in.

Heavy libraries (trimesh, PyBullet, scipy, h5py, pyarrow, the exporters) are
imported by the functions that use them, and the names re-exported from
their modules are loaded on first use (:data:`_LAZY`): importing the API, and
so starting the ``grasp`` command, costs numpy and the specs alone.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from planner.api.building import (  # noqa: F401 - re-exported
    UNIT_TIMEOUT_GRACE,
    GenerateProgress,
    Summary,
    generate,
    plan_units,
    table_supports,
    unit_row,
)
from planner.api.calibrating import (
    calibrate,
    calibration_errors,
    fitted_on,
    in_sample,
    in_sample_grasps,
    report,
    report_and_errors,
    shipped_figures,
)
from planner.api.describing import check_db, default_workers, hand, hands, objects, stored_objects
from planner.api.on_table import (  # noqa: F401 - re-exported
    TABLE_AT,
    TableGrasps,
    best_on_table,
    planned_on_table,
    table_command,
)
from planner.api.presenting import coverage, show, view  # noqa: F401 - re-exported
from planner.api.querying import (  # noqa: F401 - re-exported
    DIVERSE_BATCH,
    best,
    hand_changed,
    hand_edited,
    mesh_modified,
    object_up,
    p_hold_model,
    p_hold_outside,
    ranking_rule,
    ranks_stale,
    stored_names,
    untold_ups,
)
from planner.api.reaching import (  # noqa: F401 - re-exported
    CANDIDATE_BATCH,
    MAX_CANDIDATES,
    PLAN_NOW,
    PLAN_NOW_BUDGET,
    ReachableGrasp,
    _preferred,
    best_at,
    plan_now_settings,
)
from planner.api.resolving import (  # noqa: F401 - re-exported
    DEFAULT_DB,
    LISTED_NAMES,
    PROPERTY_RTOL,
    QUATERNION_NORM,
    generate_command,
    object_pose_matrix,
    resolve_object,
)
from planner.db.ranking import RankingRule
from planner.errors import InputError  # noqa: F401 - re-exported
from planner.plan.sweep import SAMPLER_DEFAULTS, SweepSettings
from planner.record.grasp import Grasp
from planner.specs.hands import SAMPLERS
from planner.specs.inputs import MANIFEST_LINE
from planner.specs.objects import DEFAULT_FRICTION, DEFAULT_MASS, RANDOM_COUNT, RANDOM_MASS, RANDOM_PREFIX
from planner.specs.physical import GEOMETRIES

if TYPE_CHECKING:
    from planner.datasets.exporter import FORMATS as EXPORT_FORMATS
    from planner.datasets.exporter import ExportSummary, export
    from planner.datasets.importer import FORMATS as IMPORT_FORMATS
    from planner.datasets.importer import ImportResult, import_files
    from planner.plan.unit import UnitResult
    from planner.validation.run import ValidationSummary, validate

__all__ = [
    "DEFAULT_DB", "DEFAULT_FRICTION", "DEFAULT_MASS", "EXPORT_FORMATS", "GEOMETRIES", "IMPORT_FORMATS", "MANIFEST_LINE",
    "RANDOM_COUNT", "RANDOM_MASS", "RANDOM_PREFIX",
    "ExportSummary", "Grasp",
    "GenerateProgress", "ImportResult", "RankingRule", "ReachableGrasp", "SAMPLERS", "SAMPLER_DEFAULTS", "Summary",
    "SweepSettings", "UnitResult", "ValidationSummary",
    "best", "best_at", "calibrate", "calibration_errors", "check_db", "default_workers", "export", "fitted_on",
    "generate", "hand", "hands", "import_files", "in_sample", "in_sample_grasps", "objects", "plan_units", "report",
    "report_and_errors", "resolve_object", "shipped_figures", "show", "stored_names",
    "stored_objects", "validate",
]

#: Names of this module loaded from their modules on first use: name -> (module, attribute).
_LAZY = {
    "EXPORT_FORMATS": ("planner.datasets.exporter", "FORMATS"),
    "ExportSummary": ("planner.datasets.exporter", "ExportSummary"),
    "export": ("planner.datasets.exporter", "export"),
    "IMPORT_FORMATS": ("planner.datasets.importer", "FORMATS"),
    "ImportResult": ("planner.datasets.importer", "ImportResult"),
    "import_files": ("planner.datasets.importer", "import_files"),
    "UnitResult": ("planner.plan.unit", "UnitResult"),
    "UnitSpec": ("planner.plan.unit", "UnitSpec"),
    "run_unit": ("planner.plan.unit", "run_unit"),
    "ValidationSummary": ("planner.validation.run", "ValidationSummary"),
    "validate": ("planner.validation.run", "validate"),
}


def __getattr__(name: str) -> Any:
    """A name of :data:`_LAZY`, imported now and kept (so a test may patch it)."""
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = _LAZY[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value
