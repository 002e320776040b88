from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from planner import api
from planner.cli import main
from planner.plan.sweep import SweepSettings
from planner.present import report


def test_report_html_and_markdown(validated_db: Path, tmp_path: Path) -> None:
    html = report.write(validated_db, tmp_path / "r.html")
    text = html.read_text()
    assert "hand panda" in text and "data:image/png;base64," in text and "Spearman(epsilon, success)" in text
    md = report.write(validated_db, tmp_path / "r")
    body = md.read_text()
    assert "top-1 grasp succeeds, final ranking (objects)" in body and "| box |" in body
    assert (tmp_path / "r" / "deciles_panda.png").stat().st_size > 1000


def test_deciles_and_spearman_known_answers() -> None:
    eps = np.arange(100, dtype=float)
    ok = (eps >= 50).astype(float)
    bins = report.deciles(eps, ok)
    assert len(bins) == 10 and [b[2] for b in bins] == [0.0] * 5 + [1.0] * 5
    assert report.spearman(eps, eps) == pytest.approx(1.0)
    assert report.spearman(eps, -eps) == pytest.approx(-1.0)


def test_report_without_validation_is_a_clear_error(tmp_path: Path) -> None:
    db = tmp_path / "plain.db"
    api.generate(["box"], "panda", db_path=db, settings=SweepSettings(approaches=2, rolls=1, reach_placements=0))
    result = CliRunner().invoke(main, ["report", "--db", str(db), "--out", str(tmp_path / "x.html")])
    assert result.exit_code == 2 and "run `grasp validate" in result.stderr
