"""The grasp columns: one helper from records to columns, absent values as NaN / -1."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
from helpers import assert_close, made_up

from planner.datasets.columns import grasp_columns, joint_matrix
from planner.record.grasp import RobustEpsilon, Trial


def test_columns_of_records_with_and_without_stored_results() -> None:
    plain = made_up(4, 0.05, reach=0.5)
    stored = replace(made_up(7, 0.02), id=11, unit_id=3, score=0.01, rank=2,
                     validation=Trial(True, 2, 0.001, 0.01, 0.002, 0.02), robust=RobustEpsilon(0.03, 0.01, 10))
    c = grasp_columns([plain, stored])
    assert c["pose"].shape == (2, 4, 4) and c["approach_point"].shape == (2, 3)
    assert_close(c["pose"][1], stored.pose)
    assert c["candidate"].tolist() == [4, 7] and c["preshape"] == ["wide", "wide"]
    assert c["rank"].tolist() == [-1, 2] and c["id"].tolist()[1] == 11
    assert np.isnan(c["reachability"][1]) and c["reachability"][0] == 0.5
    assert c["validation_success"].tolist() == [-1, 1] and c["validation_fingers_in_contact"].tolist() == [-1, 2]
    assert np.isnan(c["validation_shaking_angular"][0]) and c["validation_shaking_angular"][1] == 0.02
    assert np.isnan(c["robust_mean"][0]) and c["robust_samples"].tolist() == [-1, 10]
    assert c["n_contacts"].tolist() == [2, 2] and c["links_touching"].tolist() == [2, 2]
    assert json.loads(c["contacts"][0]) == plain.contacts.to_json()
    assert c["closed_joints"] == ['{"j":0.02}', '{"j":0.02}']


def test_joint_matrix_orders_by_name_and_marks_absent_joints() -> None:
    m = joint_matrix(['{"a": 1.0, "b": 2.0}', '{"b": 3.0}'], ["b", "a"])
    assert m.shape == (2, 2) and m[0].tolist() == [2.0, 1.0] and m[1, 0] == 3.0 and np.isnan(m[1, 1])
