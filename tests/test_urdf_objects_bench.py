"""bench/urdf_objects.py on a small URDF: its row holds what the committed bench/urdf_objects.json holds, the stored
source relative to the folder the files are read from (pybullet_data's), not this machine's path to it."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import urdf_objects  # noqa: E402

BOX = """<robot name="block"><link name="base"><contact><lateral_friction value="0.8"/></contact>
<inertial><mass value="0.15"/></inertial>
<collision><geometry><box size="0.03 0.04 0.05"/></geometry></collision></link></robot>"""


def test_a_row_names_its_file_as_the_committed_rows_do(tmp_path: Path) -> None:
    (tmp_path / "toys").mkdir()
    (tmp_path / "toys" / "block.urdf").write_text(BOX)
    row = urdf_objects.one(tmp_path, "toys/block.urdf", ())
    assert row["code"] == 0, row
    assert row["stored"] == {"mass": 0.15, "friction": 0.8, "scale": 1.0, "source": "toys/block.urdf"}
    assert row["urdf"] == {"mass": 0.15, "friction": 0.8} and row["extents_mm"] == [30.0, 40.0, 50.0]
