import sqlite3
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from planner import api
from planner.cli import main
from planner.plan.sweep import SweepSettings
from planner.present import report


@pytest.fixture(scope="module")
def validated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    db = tmp_path_factory.mktemp("rep") / "g.db"
    api.generate(["box", "sphere"], "panda", db_path=db, settings=SweepSettings(approaches=6, rolls=2,
                 preshapes=("wide",), reach_placements=1), workers=1)
    result = CliRunner().invoke(main, ["validate", "--db", str(db), "--top", "3", "--robust", "2", "--workers", "1"])
    assert result.exit_code == 0, result.stderr
    return db


def test_validate_stores_trials_and_reranks(validated: Path) -> None:
    with sqlite3.connect(validated) as conn:
        rows = conn.execute("SELECT g.score, g.epsilon, g.reachability, v.success, r.samples FROM grasps g "
                            "JOIN validation v ON v.grasp_id = g.id JOIN robust r ON r.grasp_id = g.id").fetchall()
        ranks = conn.execute("SELECT object, rank, score FROM grasps ORDER BY object, rank").fetchall()
    assert len(rows) == 6
    for score, eps, reach, success, samples in rows:
        assert samples == 2
        assert score == pytest.approx(eps * (0.5 + 0.5 * reach) * float(success))
    for obj in ("box", "sphere"):
        scores = [s for o, _, s in ranks if o == obj]
        assert scores == sorted(scores, reverse=True)


def test_report_html_and_markdown(validated: Path, tmp_path: Path) -> None:
    html = report.write(validated, tmp_path / "r.html")
    text = html.read_text()
    assert "hand panda" in text and "data:image/png;base64," in text and "Spearman(epsilon, success)" in text
    md = report.write(validated, tmp_path / "r")
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
