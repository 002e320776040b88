"""The grasp record: shapes checked, the JSON of ``grasp best --json``."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from helpers import made_up

from planner.record.fields import record_fields

#: The keys the README documents for ``grasp best --json``: every declared
#: field of the record, ``joints`` (the closed joints, their older name) and
#: ``end_kept`` (the squeeze's end stored beside it ranks for it).
DOCUMENTED = {f.name for f in record_fields()} | {"joints", "end_kept"}


def test_best_json_keys_and_values() -> None:
    g = replace(made_up(3, 0.05, reach=0.5), rank=1, score=0.04)
    data = json.loads(json.dumps(g.to_json()))
    assert set(data) == DOCUMENTED
    assert np.array(data["pose"]).shape == (4, 4) and data["joints"] == g.closed_joints
    assert data["contacts"][0] == {"point": [0.0, 0.02, 0.0], "normal": [0.0, -1.0, 0.0], "link": "left"}
    assert (data["rank"], data["score"], data["candidate"], data["force_closure"]) == (1, 0.04, 3, True)
    assert data["end_kept"] is False and json.loads(json.dumps(replace(g, end_kept=True).to_json()))["end_kept"] is True
    assert g.measures is None and data["resist_worst"] is None and data["feasibility"] is None  # not measured
    assert data["validation_success"] is None and data["robust_mean"] is None  # not validated
    assert {"resist_worst", "settled_epsilon", "validation_reason", "robust_quantile", "approach_dir"} <= set(data)


def test_shapes_are_checked() -> None:
    with pytest.raises(ValueError, match="pose must be"):
        replace(made_up(0, 0.0), pose=np.eye(3))
