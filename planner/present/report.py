"""``grasp report``: how well each score predicts simulated success.

Per hand (and per object): success rate by epsilon decile; ROC AUC against
simulated success of every measure (epsilon, weight resistance, push, the
margins, feasibility, the analytic score, reachability, robust epsilon,
over the validated grasps); Spearman rank correlations; the success rate of
the top-1 / top-10 grasps by final rank among validated grasps, and of the
top-1 / top-10 of the *analytic order* (the rule without simulation, over
each object's whole sweep; picks without a trial are counted as unlabelled,
not as failures). Written as one self-contained HTML file (plots embedded as
PNG) or, for a path without ``.html``, a folder with ``report.md`` and PNGs.

Per hand with a p_hold model (stored by ``grasp calibrate``, or shipped):
the reliability diagram (predicted p_hold vs observed success per decile)
of the model's held-out predictions on its labels, and of p_hold against
the stored trials (MuJoCo's, else PyBullet's) where there are any, each with its expected
calibration error (:func:`calibration`, ``reliability_<hand>.png``).

Validated grasps are whatever ``grasp validate`` or ``bench/calibration.py``
tested: the calibration's uniform samples make unbiased AUCs; a database
validated on its top-K only measures the AUC among its best grasps.
"""

from __future__ import annotations

import base64
import html
import io
import math
import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planner.calibration.metrics import roc_auc
from planner.db.failures import no_grasps
from planner.db.ranking import RankingRule, first_measures, ranks_first, rule_measures
from planner.db.store import open_db
from planner.errors import InputError
from planner.present.reliability import (  # noqa: F401 - calibration and labelled re-exported
    FileLabels,
    HandCalibration,
    calibration,
    ece_lines,
    engines,
    file_lines,
    labelled,
    read,
    reliability_png,
)
from planner.record import fields
from planner.record.grasp import Grasp


@dataclass
class HandReport:
    """The validated grasps of one hand, rank order within each object."""

    hand: str
    grasps: list[Grasp] = field(default_factory=list)
    rule: RankingRule = field(default_factory=RankingRule)
    #: object -> every grasp of its sweep in analytic order, best first (ids)
    analytic_orders: dict[str, list[int]] = field(default_factory=dict)

    @property
    def success(self) -> np.ndarray:
        return np.array([g.trial.success for g in self.grasps], float)  # type: ignore[union-attr]

    def measure(self, name: str) -> np.ndarray:
        """(n,) a declared field of every grasp by its flat name (``epsilon``,
        ``push``, ``robust_quantile`` ...; :mod:`planner.record.fields`), or
        ``analytic`` (the rule without simulation) or ``feasible``; NaN where
        not computed."""
        if name == "analytic":
            return untried_analytic(self.rule, self.grasps)
        if name == "feasible":
            return np.array([np.nan if g.measures is None else g.measures.feasible for g in self.grasps], float)
        return np.array([np.nan if v is None else v for v in fields.values(fields.by_name(name), self.grasps)], float)

    @property
    def objects(self) -> list[str]:
        return sorted({g.object for g in self.grasps})

    def _of(self, name: str) -> list[Grasp]:
        return sorted((g for g in self.grasps if g.object == name), key=lambda g: g.rank)  # type: ignore[arg-type, return-value]

    def top_k(self, k: int) -> tuple[float, int]:
        """Success rate of each object's k best-ranked validated grasps, and how many objects."""
        rates = [np.mean([g.trial.success for g in self._of(name)[:k]]) for name in self.objects]  # type: ignore[union-attr]
        return (float(np.mean(rates)) if rates else math.nan), len(rates)

    def top1_objects(self) -> tuple[int, int]:
        """Objects whose best-ranked validated grasp succeeded, out of all objects."""
        wins = sum(int(self._of(name)[0].trial.success) for name in self.objects)  # type: ignore[union-attr]
        return wins, len(self.objects)

    def analytic_top(self, k: int) -> tuple[float, float, int]:
        """(top-1, top-k, unlabelled picks) of the analytic order over each
        object's whole sweep (see :func:`top_k_success`)."""
        ok = {g.id: float(g.trial.success) for g in self.grasps}  # type: ignore[union-attr]
        orders = [(np.arange(len(ids)), np.array([ok.get(i, np.nan) for i in ids], float))
                  for ids in self.analytic_orders.values()]
        return top_k_success(orders, k)


def untried_analytic(rule: RankingRule, grasps: Sequence[Grasp]) -> np.ndarray:
    """(n,) the rule's analytic score as the sweep gave it, without simulation: p_hold (else the formula), not
    p_hold_trial, which the hand's model makes from the verdict of the trial that tried the grasp (scored against
    those verdicts it read an AUC of 1.000 after `grasp calibrate --trial`)."""
    measures = rule_measures(grasps)
    measures["p_hold_trial"] = np.full(len(grasps), np.nan)
    return rule.analytic(measures)


def analytic_order(rule: RankingRule, sweep: Sequence[Grasp]) -> list[int]:
    """The ids of an object's ``sweep`` best first by :func:`untried_analytic`, those that rank first as the
    database ranks them (:func:`planner.db.ranking.ranks_first`: force closure as planned, or once squeezed where no
    end of that squeeze is stored) first, ties by candidate, a planned grasp before its squeeze's end."""
    score, first = untried_analytic(rule, sweep), ranks_first(first_measures(sweep))
    squeezed = np.array([g.squeezed_from_turn is not None for g in sweep])
    order = np.lexsort((squeezed, np.array([g.candidate for g in sweep]), -score, ~first))
    return [sweep[i].id for i in order]  # type: ignore[misc]


#: The analytic measures the report reads: every numeric field of the measures record.
ANALYTIC_MEASURES = tuple(f.name for f in fields.group("measures") if f.dtype != "string" and not f.shape)
#: Measures whose ROC AUC the report shows (higher should mean "holds").
AUC_MEASURES = ("analytic", "p_hold", "epsilon", *ANALYTIC_MEASURES, "feasible", "reachability", "robust_mean",
                "robust_quantile")


def top_k_success(orders: list[tuple[np.ndarray, np.ndarray]], k: int) -> tuple[float, float, int]:
    """Per object an order (indices, best first) and success per grasp (NaN:
    not tested): (share of objects whose first pick held, mean over objects of
    the share of the k first picks that held, picks without a trial). Picks
    without a trial are left out, not counted as failures."""
    top1, topk, missing = [], [], 0
    for order, ok in orders:
        picks = ok[np.asarray(order, int)[:k]]
        missing += int(np.isnan(picks).sum())
        if len(picks) and np.isfinite(picks[0]):
            top1.append(picks[0])
        if np.isfinite(picks).any():
            topk.append(np.nanmean(picks))
    return (float(np.mean(top1)) if top1 else math.nan, float(np.mean(topk)) if topk else math.nan, missing)


def spearman(x: np.ndarray, y: np.ndarray) -> float:
    from scipy.stats import spearmanr

    keep = np.isfinite(x) & np.isfinite(y)
    if keep.sum() < 3 or np.ptp(x[keep]) == 0 or np.ptp(y[keep]) == 0:
        return math.nan
    return float(spearmanr(x[keep], y[keep]).statistic)


def deciles(eps: np.ndarray, success: np.ndarray) -> list[tuple[float, float, float, int]]:
    """(low, high, success rate, count) for each epsilon decile."""
    if len(eps) == 0:
        return []
    edges = np.unique(np.quantile(eps, np.linspace(0, 1, 11)))
    if len(edges) == 1:  # one epsilon for all (one grasp; none force closure, 0): one bin, not none
        return [(float(edges[0]), float(edges[0]), float(np.mean(success)), len(eps))]
    out = []
    for i in range(len(edges) - 1):
        lo, hi = edges[i], edges[i + 1]
        sel = (eps >= lo) & ((eps <= hi) if i == len(edges) - 2 else (eps < hi))
        if sel.any():
            out.append((float(lo), float(hi), float(success[sel].mean()), int(sel.sum())))
    return out


def collect(db_path: Path, allow_empty: bool = False) -> list[HandReport]:
    with open_db(Path(db_path), create=False, readonly=True) as db:
        grasps = db.validated()
        rule = db.rule()
        if not grasps and not allow_empty:
            if not db.pairs():
                raise InputError(no_grasps(Path(db_path), db.object_names()))
            raise InputError(f"{db_path}: no validated grasps; run `grasp validate --db {shlex.quote(str(db_path))}` "
                             "first")
        reports: dict[str, HandReport] = {}
        for g in grasps:
            reports.setdefault(g.hand, HandReport(g.hand, rule=rule)).grasps.append(g)
        for rep in reports.values():
            for name in rep.objects:
                sweep = [g for batch in db.grasp_batches(name, rep.hand) for g in batch]
                rep.analytic_orders[name] = analytic_order(rule, sweep)
    return list(reports.values())


def _plot(report: HandReport) -> bytes:
    import matplotlib.pyplot as plt

    fig = decile_figure(report)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    return buffer.getvalue()


#: [pt] the decile chart's tick labels (at 6 pt, "0.004-0.006" under a bar could not be read).
TICK_SIZE = 8


def decile_figure(report: HandReport):  # type: ignore[no-untyped-def]
    """The success rate by epsilon decile as a matplotlib figure, each bar's grasps written on it; fewer
    grasps than ten deciles make fewer bins, said as bins of equal count, not deciles."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    eps, ok = report.measure("epsilon"), report.success
    bins = deciles(eps, ok)
    fig, ax = plt.subplots(figsize=(6, 3.2))
    bars = ax.bar(range(len(bins)), [b[2] for b in bins], color="#4a7bb7")
    ax.bar_label(bars, [f"n={b[3]}" for b in bins], fontsize=TICK_SIZE)
    ax.set_xticks(range(len(bins)), [f"{b[0]:.3f}-\n{b[1]:.3f}" for b in bins], fontsize=TICK_SIZE)
    ax.set_ylim(0, 1.12)  # room for the counts over a bar of 1
    ax.set_yticks(np.linspace(0, 1, 6))
    ax.set_xlabel("epsilon decile" if len(bins) == 10 else "epsilon, one bin (every grasp's the same)" if len(bins) == 1
                  else f"epsilon, {len(bins)} bins of equal count (too few grasps for deciles)" if len(eps) < 10
                  else f"epsilon, {len(bins)} bins (deciles of tied values merged)")
    ax.set_ylabel("simulated success rate")
    ax.set_title(f"{report.hand}: success by epsilon ({len(eps)} grasps)")
    fig.tight_layout()
    return fig


#: An AUC over fewer grasps than this of either class (held, slipped) is
#: marked: its standard error (Hanley and McNeil 1982) is then about 0.05 or
#: more, so differences of a few hundredths between measures mean nothing.
AUC_MIN_CLASS = 50


def _summary_rows(report: HandReport) -> list[tuple[str, str]]:
    """The summary table; a figure that cannot be computed (NaN: a measure
    never stored, one class only) is left out, not printed as ``nan``."""
    ok = report.success
    wins, n = report.top1_objects()
    top1, top10a, missing = report.analytic_top(10)
    top10, _ = report.top_k(10)
    held, slipped = int(np.nansum(ok)), int(np.isfinite(ok).sum() - np.nansum(ok))
    small = min(held, slipped) < AUC_MIN_CLASS
    mark = f" (small sample: fewer than {AUC_MIN_CLASS} of a class)" if small else ""
    rows: list[tuple[str, float | str]] = [
        ("validated grasps", f"{len(ok)} ({held} held, {slipped} slipped)"),
        ("verdicts from", engines(report.grasps)),
        ("objects", str(n)),
        ("overall success rate", float(np.nanmean(ok))),
        ("top-1 grasp succeeds, final ranking (objects)", f"{wins}/{n} = {wins / max(n, 1):.1%}"),
        ("top-1 of the analytic order succeeds (share of objects)", top1),
        ("top-10 of the analytic order, success rate",
         f"{top10a:.3f} ({missing} picks without a trial left out)" if math.isfinite(top10a) else math.nan),
        ("top-10 success rate (mean over objects)", top10),
        *[(f"ROC AUC({name}, success)", _marked(roc_auc(ok, report.measure(name)), mark)) for name in AUC_MEASURES],
        ("Spearman(epsilon, success)", spearman(report.measure("epsilon"), ok)),
        ("Spearman(robust epsilon mean, success)", spearman(report.measure("robust_mean"), ok)),
        ("Spearman(robust epsilon quantile, success)", spearman(report.measure("robust_quantile"), ok)),
        ("Spearman(reachability, success)", spearman(report.measure("reachability"), ok)),
        ("Spearman(rank, success) (negative is good)", spearman(report.measure("rank"), ok)),
    ]
    if not min(held, slipped):  # "AUCs ... are uncertain; validate more": there was none, and more trials of
        # grasps that all held (every stored one, maybe) give none
        rows.insert(1, ("note", f"{held} held and {slipped} slipped: no AUC or Spearman correlation without both "
                                "outcomes; they need grasps that drop (a heavier or more slippery object, or "
                                "grasps further down the ranking: --sample N)"))
    elif small:
        rows.insert(1, ("note", f"{held} held and {slipped} slipped: AUCs from fewer than {AUC_MIN_CLASS} grasps "
                                "of a class are uncertain by 0.05 or more; validate more (--sample N)"))
    return [(k, v if isinstance(v, str) else f"{v:.3f}") for k, v in rows
            if not (isinstance(v, float) and math.isnan(v))]


def _marked(auc: float, mark: str) -> float | str:
    return auc if math.isnan(auc) else f"{auc:.3f}{mark}"


def _per_object(report: HandReport) -> list[tuple[str, ...]]:
    out = []
    for name in report.objects:
        mine = report._of(name)
        ok = np.array([g.trial.success for g in mine], float)  # type: ignore[union-attr]
        eps = np.array([g.epsilon for g in mine], float)
        rho = spearman(eps, ok)
        out.append((name, str(len(mine)), f"{ok.mean():.2f}", "yes" if ok[0] else "no",
                    "n/a" if math.isnan(rho) else f"{rho:.2f}"))
    return out


#: Said where the database has no trials, only a p_hold model's held-out figures (`grasp calibrate` into it) or an
#: imported file's labels: {shown}, those of the two it has.
NO_TRIALS = ("No validated grasps: {shown} only (no trial of this project's); `grasp validate --db {db}` tries "
             "grasps.")


def no_trials(db_path: Path, cals: list[HandCalibration], files: dict[str, FileLabels]) -> str:
    """:data:`NO_TRIALS` naming what the report shows instead: a hand without a p_hold model (the Barrett's) has no
    held-out figures, a database nothing was imported into no file's labels."""
    held_out = any(c.held_out is not None for c in cals)
    shown = [what for what, there in (("the p_hold model's held-out figures", held_out),
                                      ("the imported files' own labels", bool(files))) if there]
    return NO_TRIALS.format(shown=" and ".join(shown), db=shlex.quote(str(db_path)))


#: The heading of the imported files' own labels (``grasp import``; :func:`planner.present.reliability.labelled`).
FILES = "The imported files' own labels"


def write(db_path: Path, out: Path, found: tuple[list[HandCalibration], dict[str, FileLabels]] | None = None) -> Path:
    """The report of ``db_path`` at ``out``; ``found``: its p_hold section as
    :func:`planner.present.reliability.read` read it (None: read here)."""
    cals, files = found or read(db_path)
    cals = [c for c in cals if c.curves()]
    reports = collect(db_path, allow_empty=bool(cals or files))
    if out.suffix.lower() == ".html":
        return _write_html(reports, cals, files, out, db_path)
    return _write_markdown(reports, cals, files, out, db_path)


def _write_html(reports: list[HandReport], cals: list[HandCalibration], files: dict[str, FileLabels], out: Path,
                db_path: Path) -> Path:
    parts = [f"<html><head><meta charset='utf-8'><title>grasp report</title></head><body>"
             f"<h1>Simulated success vs scores</h1><p>database: {html.escape(str(db_path))}</p>"]
    parts += [f"<p>{html.escape(no_trials(db_path, cals, files))}</p>"] if not reports else []
    for rep in reports:
        parts.append(f"<h2>hand {html.escape(rep.hand)}</h2><table border=1 cellpadding=3>")
        parts += [f"<tr><td>{html.escape(k)}</td><td>{html.escape(v)}</td></tr>" for k, v in _summary_rows(rep)]
        parts.append("</table>")
        parts.append(f"<img src='data:image/png;base64,{base64.b64encode(_plot(rep)).decode()}'>")
        parts.append("<h3>per object</h3><table border=1 cellpadding=3><tr><th>object</th><th>validated</th>"
                     "<th>success rate</th><th>top-1 succeeds</th><th>Spearman(epsilon, success)</th></tr>")
        parts += ["<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in _per_object(rep)]
        parts.append("</table>")
    for c in cals:
        parts.append(f"<h2>p_hold of hand {html.escape(c.hand)}</h2><p>model: {html.escape(c.source)}</p><ul>")
        parts += [f"<li>{html.escape(line)}</li>" for line in ece_lines([c])]
        parts.append(f"</ul><img src='data:image/png;base64,{base64.b64encode(reliability_png(c)).decode()}'>")
    if files:
        parts.append(f"<h2>{FILES}</h2><ul>" + "".join(f"<li>{html.escape(line)}</li>" for line in file_lines(files))
                     + "</ul>")
    parts.append("</body></html>")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(parts), encoding="utf-8")
    return out


def _write_markdown(reports: list[HandReport], cals: list[HandCalibration], files: dict[str, FileLabels],
                    out: Path, db_path: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    lines = ["# Simulated success vs scores", "", f"database: `{db_path}`", ""]
    lines += [no_trials(db_path, cals, files), ""] if not reports else []
    for rep in reports:
        png = out / f"deciles_{rep.hand}.png"
        png.write_bytes(_plot(rep))
        lines += [f"## hand {rep.hand}", "", "| measure | value |", "| --- | --- |"]
        lines += [f"| {k} | {v} |" for k, v in _summary_rows(rep)]
        lines += ["", f"![success by epsilon decile]({png.name})", "", "| object | validated | success rate |"
                  " top-1 succeeds | Spearman(epsilon, success) |", "| --- | --- | --- | --- | --- |"]
        lines += ["| " + " | ".join(row) + " |" for row in _per_object(rep)]
        lines.append("")
    for c in cals:
        png = out / f"reliability_{c.hand}.png"
        png.write_bytes(reliability_png(c))
        lines += [f"## p_hold of hand {c.hand}", "", f"model: `{c.source}`", ""]
        lines += [f"- {line}" for line in ece_lines([c])]
        lines += ["", f"![reliability diagram]({png.name})", ""]
    lines += [f"## {FILES}", "", *(f"- {line}" for line in file_lines(files)), ""] if files else []
    path = out / "report.md"
    path.write_text("\n".join(lines), encoding="utf-8")
    return path
