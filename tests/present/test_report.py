from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from helpers import made_up

from planner import api
from planner.calibration.logistic import SHIPPED_ENV, default_model
from planner.cli import main
from planner.db.store import open_db
from planner.plan.sweep import SweepSettings
from planner.present import report
from planner.record.grasp import Grasp


def test_report_html_and_markdown(validated_db: Path, tmp_path: Path) -> None:
    html = report.write(validated_db, tmp_path / "r.html")
    text = html.read_text()
    assert "hand panda" in text and "data:image/png;base64," in text and "Spearman(epsilon, success)" in text
    md = report.write(validated_db, tmp_path / "r")
    body = md.read_text()
    assert "top-1 grasp succeeds, final ranking (objects)" in body and "| box |" in body
    assert (tmp_path / "r" / "deciles_panda.png").stat().st_size > 1000


def test_a_report_that_cannot_be_written_is_a_one_line_error(validated_db: Path, tmp_path: Path) -> None:
    """--out under a file, or a folder's --out (no .html) naming a file, was an internal error (exit 1)."""
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    for out, said in ((blocker / "r.html", "a_file is a file, not a folder"),
                      (blocker / "r", "a_file is a file, not a folder"),
                      (blocker, "must be a folder, but it is a file")):
        result = CliRunner().invoke(main, ["report", "--db", str(validated_db), "--out", str(out)])
        assert result.exit_code == 2 and said in result.stderr, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
    assert blocker.read_text() == "x"


@pytest.mark.parametrize("name", ["report.png", "report.md", "Report.PDF"])
def test_a_report_named_as_another_kind_of_file_is_refused(validated_db: Path, tmp_path: Path, name: str) -> None:
    """``--out report.png`` wrote a folder named report.png holding report.md."""
    result = CliRunner().invoke(main, ["report", "--db", str(validated_db), "--out", str(tmp_path / name)])
    assert result.exit_code == 2 and "the report is an .html file or a folder" in result.stderr, result.stderr
    assert list(tmp_path.iterdir()) == []


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
    assert result.exit_code == 2 and "no validated grasps; run `grasp validate" in result.stderr
    open_db(tmp_path / "empty.db").close()  # no grasps: validate alone would not help
    result = CliRunner().invoke(main, ["report", "--db", str(tmp_path / "empty.db"), "--out", str(tmp_path / "e")])
    assert result.exit_code == 2 and "no grasps in" in result.stderr
    assert "; run `grasp generate ... --db" in result.stderr


def test_a_database_with_only_a_calibrated_model_reports_its_held_out_figures(tmp_path: Path,
                                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """`grasp calibrate LABELS --db new.db` stores a model in a database without grasps: its report said "no
    validated grasps; run `grasp validate`" though the model's held-out reliability was there to draw."""
    monkeypatch.setenv(SHIPPED_ENV, "1")
    model = default_model("panda")
    assert model is not None and model.held_out
    monkeypatch.setenv(SHIPPED_ENV, "0")
    db = tmp_path / "calibrated.db"
    with open_db(db) as handle:
        handle.write_model(model, '{"command": "grasp calibrate"}', handle.rule())
    result = CliRunner().invoke(main, ["report", "--db", str(db), "--out", str(tmp_path / "r")])
    assert result.exit_code == 0, result.stderr
    text = (tmp_path / "r" / "report.md").read_text()
    assert "## p_hold of hand panda" in text and "No validated grasps: the p_hold model's held-out figures" in text
    assert (tmp_path / "r" / "reliability_panda.png").read_bytes()[:4] == b"\x89PNG"
    assert "panda: ECE of p_hold (held out on its labels" in result.stdout


def test_roc_auc_and_top_k_known_answers() -> None:
    from planner.present.report import roc_auc, top_k_success

    ok = np.array([1.0, 1.0, 0.0, 0.0, np.nan])
    assert roc_auc(ok, np.array([4.0, 3.0, 2.0, 1.0, 9.0])) == 1.0  # unlabelled grasps left out
    assert roc_auc(ok, np.array([1.0, 2.0, 3.0, 4.0, 0.0])) == 0.0
    assert roc_auc(ok, np.array([1.0, 3.0, 2.0, 4.0, 0.0])) == 0.25
    assert roc_auc(ok, np.ones(5)) == 0.5  # ties count half
    assert roc_auc(ok, np.array([1.0, np.nan, 0.5, 0.2, 0.0])) == 0.5  # not computed ranks lowest
    assert np.isnan(roc_auc(ok, np.full(5, np.nan)))  # never computed: no figure, not 0.5
    assert np.isnan(roc_auc(np.array([1.0, 1.0]), np.array([1.0, 2.0])))  # one class only
    orders = [(np.array([0, 1, 2]), np.array([1.0, 0.0, np.nan])), (np.array([2, 1, 0]), np.array([1.0, 1.0, 0.0]))]
    top1, top2, missing = top_k_success(orders, 2)
    assert (top1, top2, missing) == (0.5, 0.5, 0)
    top1, top3, missing = top_k_success(orders, 3)
    assert missing == 1 and top3 == pytest.approx((0.5 + 2 / 3) / 2)


def test_no_nan_rows_and_small_samples_are_marked(validated_db: Path) -> None:
    """Six validated grasps: every figure that exists is a number, every AUC
    says it rests on a small sample, and a note says how small."""
    for rep in report.collect(validated_db):
        rows = dict(report._summary_rows(rep))
        assert not any("nan" in v for v in rows.values()), rows
        assert "held" in rows["validated grasps"] and "--sample N" in rows["note"]
        aucs = {k: v for k, v in rows.items() if k.startswith("ROC AUC")}
        assert all("small sample" in v for v in aucs.values())
        assert all(cells[-1] != "nan" for cells in report._per_object(rep))


def test_auc_of_a_large_sample_is_not_marked() -> None:
    """The mark depends on the class counts alone: 60 held and 60 slipped pass."""
    from planner.record.grasp import Trial

    rep = report.HandReport("toy")
    for i in range(120):
        g = made_up(i, epsilon=0.01 * (i % 7), fc=True)
        rep.grasps.append(replace(g, id=i, rank=i + 1, validation=Trial(bool(i % 2), 2, 0.0, 0.0, 0.0, 0.0)))
    rows = dict(report._summary_rows(rep))
    assert "note" not in rows and "small sample" not in rows["ROC AUC(epsilon, success)"]
    assert rows["validated grasps"] == "120 (60 held, 60 slipped)"


def test_the_held_out_ece_is_printed_with_its_interval_or_why_there_is_none(validated_db: Path,
                                                                             shipped_models: None) -> None:
    """The shipped Panda model's fit recorded no interval of its ECE: the report says so; a model whose
    figures hold one prints it."""
    cals = report.calibration(validated_db)
    assert [c.hand for c in cals] == ["panda"] and cals[0].held_out_ece is None
    line = report.ece_lines(cals)[0]
    assert line.startswith("panda: ECE of p_hold (held out on its labels: the model's source, ")
    assert "no interval: the model's fit" in line
    lines = report.ece_lines([replace(cals[0], held_out_ece=(0.0125, 0.0581))])
    assert lines[0].endswith("= 0.0162 [0.0125, 0.0581] (95% over objects: a bootstrap drawing the labelled objects)")


def test_the_analytic_score_is_read_without_the_trials_it_is_scored_against() -> None:
    """The report's 'analytic' AUC took p_hold_trial, which the model makes from the verdict of the trial it is
    scored against: it read 1.000 after `grasp calibrate --trial`. It is the sweep's p_hold now."""
    from planner.db.ranking import RankingRule
    from planner.record.grasp import Trial

    grasps = [replace(made_up(i, 0.05), rank=i + 1, p_hold=p, p_hold_trial=float(held),
                      mujoco=Trial(held, 2, 0.0, 0.0, 0.0, 0.0, "held" if held else "slipped"))
              for i, (p, held) in enumerate([(0.9, False), (0.8, True), (0.3, True), (0.2, False)])]
    rep = report.HandReport("panda", rule=RankingRule(), grasps=grasps)
    assert np.allclose(rep.measure("analytic"), [0.9, 0.8, 0.3, 0.2])
    assert np.allclose(report.untried_analytic(RankingRule(), grasps), [0.9, 0.8, 0.3, 0.2])
    assert dict(report._summary_rows(rep))["verdicts from"] == "MuJoCo 4"  # the report says whose


def test_the_reliability_legend_names_only_the_engines_whose_trials_it_draws() -> None:
    """The quick start's report drew p_hold against 3 MuJoCo trials under the legend "trials: MuJoCo 3, PyBullet 0",
    which read as a PyBullet trial that held none."""
    from planner.calibration.metrics import reliability
    from planner.record.grasp import Trial

    held = Trial(True, 2, 0.0, 0.0, 0.0, 0.0, "held")
    for tried, said in ((dict(mujoco=held), "trials: MuJoCo 3"), (dict(validation=held), "trials: PyBullet 3")):
        grasps = [replace(made_up(i, 0.05), p_hold=0.9, **tried) for i in range(3)]
        cal = report.HandCalibration("panda", "shipped", None, reliability(np.ones(3), np.full(3, 0.9)),
                                     engines=report.engines(grasps))
        assert [label for label, _ in cal.curves()] == [said]


def test_a_trial_with_one_outcome_only_says_no_auc_can_be_made() -> None:
    """1,035 grasps, every stored one, all held: the note said AUCs "are uncertain ...; validate more"."""
    from planner.record.grasp import Trial

    rep = report.HandReport("toy")
    for i in range(80):
        g = made_up(i, epsilon=0.01 * (i % 7), fc=True)
        rep.grasps.append(replace(g, id=i, rank=i + 1, validation=Trial(True, 2, 0.0, 0.0, 0.0, 0.0)))
    rows = dict(report._summary_rows(rep))
    assert rows["note"].startswith("80 held and 0 slipped: no AUC or Spearman correlation without both outcomes")
    assert "uncertain" not in rows["note"] and not any(k.startswith(("ROC AUC", "Spearman")) for k in rows)


def test_the_analytic_order_puts_first_the_grasps_the_database_ranks_first() -> None:
    """The report's analytic top-k ranks as the database does: a Panda grasp force closure only once squeezed
    (planner.db.ranking.FIRST) before one that is neither, whatever their p_hold."""
    from planner.db.ranking import RankingRule
    from planner.record.measures import Measures

    def one(i: int, p: float, squeezed: bool | None) -> Grasp:
        g = made_up(i, 0.0, False)
        return replace(g, id=100 + i, p_hold=p, measures=Measures(5.0, 5.0, 0.01, 0.01, 1.0, (),
                                                                  squeezed_force_closure=squeezed))

    sweep = [one(0, 0.9, False), one(1, 0.2, True), one(2, 0.8, None), replace(made_up(3, 0.05), id=103, p_hold=0.1)]
    assert report.analytic_order(RankingRule(), sweep) == [101, 103, 100, 102]


def test_the_decile_chart_of_a_few_grasps_says_its_bins_and_counts_in_readable_type() -> None:
    """The quick start's report (`validate --top 3`) drew three bars titled "epsilon decile", each of one grasp
    unsaid, under tick labels of 6 pt."""
    import matplotlib.pyplot as plt

    from planner.present.report import TICK_SIZE, decile_figure
    from planner.record.grasp import Trial

    rep = report.HandReport("panda")
    for i, eps in enumerate([0.004, 0.02, 0.06]):
        rep.grasps.append(replace(made_up(i, epsilon=eps, fc=True), id=i, rank=i + 1,
                                  mujoco=Trial(True, 2, 0.0, 0.0, 0.0, 0.0, "held")))
    fig = decile_figure(rep)
    ax = fig.axes[0]
    assert ax.get_xlabel().startswith("epsilon, 3 bins of equal count")
    assert [t.get_text() for t in ax.texts] == ["n=1"] * 3 and ax.get_ylim()[1] > 1.0
    assert all(t.get_fontsize() >= TICK_SIZE >= 8 for t in ax.get_xticklabels())
    plt.close(fig)


@pytest.mark.parametrize("eps", [[0.05], [0.0] * 12], ids=["one-grasp", "none-force-closure"])
def test_the_decile_chart_of_grasps_of_one_epsilon_draws_them_in_one_bin(eps: list[float]) -> None:
    """`grasp validate --top 1`, or trials of grasps none force closure (epsilon 0 each): every quantile is the one
    value, so no bin was made; the chart drew no bar and said "epsilon, 0 bins of equal count"."""
    import matplotlib.pyplot as plt

    from planner.present.report import decile_figure
    from planner.record.grasp import Trial

    ok = np.arange(len(eps)) % 2 == 0
    assert report.deciles(np.array(eps), ok.astype(float)) == [(eps[0], eps[0], float(ok.mean()), len(eps))]
    rep = report.HandReport("panda")
    for i, (e, held) in enumerate(zip(eps, ok)):
        rep.grasps.append(replace(made_up(i, epsilon=e, fc=e > 0), id=i, rank=i + 1,
                                  mujoco=Trial(bool(held), 2, 0.0, 0.0, 0.0, 0.0, "held" if held else "dropped")))
    ax = decile_figure(rep).axes[0]
    assert [t.get_text() for t in ax.texts] == [f"n={len(eps)}"] and ax.get_xlabel().startswith("epsilon, one bin")
    plt.close("all")


def test_file_labels_p_hold_was_fitted_on_are_said_to_be_in_sample() -> None:
    """`grasp calibrate crate.h5 can.h5 --db X` of the files imported into X: the report set p_hold against their
    labels (ECE 0.0135, better than its held-out 0.0610) as the imported files' own check of it, though the model was
    fitted on those very labels."""
    import json

    from planner.present.reliability import FittedOn, HandCalibration, file_labels, file_lines, fitted_on
    from planner.record.grasp import FileLabel

    source = json.dumps({"command": "grasp calibrate", "labels": ["crate.h5", "b/can.h5"], "poses_per_file": 100})
    assert fitted_on(source).names == {"crate.h5", "can.h5"} and fitted_on("shipped") == FittedOn()
    grasps = [replace(made_up(i, 0.05), p_hold=0.2 + 0.1 * i,
                      file_label=FileLabel(i % 2 == 1, f"{'crate' if i < 3 else 'mug'}.h5 grasps/qualities/flex/"
                                           "object_in_gripper")) for i in range(5)]
    scores = np.array([g.p_hold for g in grasps])
    mine = file_labels(grasps, scores, fitted_on(source))
    assert mine.in_sample == 3 and file_labels(grasps, scores).in_sample == 0
    assert "in-sample: the p_hold model was fitted on the labels of the files of 3 of these 5 grasps" in \
        file_lines({"panda": mine})[0]
    assert "in-sample" not in file_lines({"panda": file_labels(grasps, scores)})[0]
    cal = HandCalibration("panda", source, None, None, files=mine)
    assert [label for label, _ in cal.curves()] == ["the imported files' own labels (2 sources: crate.h5 grasps/"
                                                    "qualities/flex/object_in_gripper, ...; in-sample: 3 of them of "
                                                    "the files p_hold was fitted on)"]


def test_file_labels_are_in_sample_by_their_files_bytes_where_the_model_records_them() -> None:
    """Matched by name, a model fitted on robot/mug/outcomes.h5 made robot/cup/outcomes.h5's grasps in-sample and a
    renamed copy of the fitted file's not: a model with its files' sha256 is matched by the grasps' files' bytes."""
    from planner.present.reliability import file_labels, fitted_on
    from planner.record.grasp import FileLabel

    mug, cup = "a" * 64, "b" * 64
    source = '{"command": "grasp calibrate", "labels": ["mug/outcomes.h5"]}'
    fitted = fitted_on(source, ("mug/outcomes.h5",), (mug.upper(),))
    named = [(1, "outcomes.h5"), (1, "outcomes.h5"), (2, "outcomes.h5"), (3, "copy.h5"), (4, "outcomes.h5")]
    grasps = [replace(made_up(i, 0.05), p_hold=0.5, unit_id=unit,
                      file_label=FileLabel(i % 2 == 1, f"{name} grasps/qualities/flex/object_in_gripper"))
              for i, (unit, name) in enumerate(named)]
    hashes = {1: mug, 2: cup, 3: mug}  # unit 4: no hash known
    scores = np.full(5, 0.5)
    assert file_labels(grasps, scores, fitted, hashes).in_sample == 3  # the fitted file's two, its renamed copy's
    assert fitted.holds("cup/outcomes.h5", cup) is False and fitted.holds("x/copy.h5", mug) is True
    assert fitted.holds("mug/outcomes.h5") is False  # the model has hashes: no name alone makes a file its
    by_name = fitted_on(source, ("mug/outcomes.h5",))  # a model that records none: the name rule
    assert file_labels(grasps, scores, by_name, hashes).in_sample == 4
    assert by_name.holds("cup/outcomes", cup) and not by_name.holds("copy.h5", mug)
