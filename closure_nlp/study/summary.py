"""Summaries of a study: the table per group, its Markdown, the CSV files."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from closure_nlp.base.files import write_atomic
from closure_nlp.planning.seeds import DEFAULT_SEEDS, choose
from closure_nlp.study.grid import Study, group_keys, task_groups
from closure_nlp.study.plots import plot_study


def summarize(study: Study, frame):
    """The summary table: one row per group of :func:`group_keys`.

    Columns: the group keys, ``tasks`` (of the study), ``done``, ``errors``, ``force_closure``
    (count), ``certified`` (rows whose rho bracket converged to the tolerance; rows of older
    versions have none), ``success_rate`` (force closure among the tasks done), ``rho_median``,
    ``rho_best`` (most negative rho), ``rho_hat_median`` (iterative selection), ``gap_median``
    (the placements' certified gap to the best placement on their elements, force closure only),
    ``seconds_median`` (the three steps of one task, as it ran), ``reused`` (tasks that took
    the iterative run and the placement of a set from an earlier task of their worker),
    ``best_of_8_rho`` and ``best_of_8_seed`` (:func:`best_of_seeds`).
    """
    import pandas as pd

    out = []
    for values, tasks, mine in task_groups(study, frame):
        ok = mine[mine.status == "ok"]
        fc = int(ok.force_closure.fillna(False).astype(bool).sum())
        out.append(
            values
            | {
                "tasks": tasks,
                "done": len(mine),
                "errors": int((mine.status != "ok").sum()),
                "force_closure": fc,
                "certified": int(ok.converged.fillna(False).astype(bool).sum()),
                "success_rate": fc / len(mine) if len(mine) else float("nan"),
                "rho_median": _stat(ok.rho, "median"),
                "rho_best": _stat(ok.rho, "min"),
                "rho_hat_median": _stat(ok.iterative_rho_hat, "median"),
                "gap_median": _stat(ok.gap, "median") if "gap" in ok else float("nan"),
                "seconds_median": _stat(ok.seconds, "median"),
                "reused": int(ok.reused.fillna("").astype(bool).sum()),
                **best_of_seeds(ok, study.seeds[:DEFAULT_SEEDS]),
            }
        )
    return pd.DataFrame(out, columns=group_keys(study) + SUMMARY_COLUMNS)


def best_of_seeds(ok, seeds) -> dict:
    """``best_of_8_rho`` and ``best_of_8_seed``: the task among the group's first seeds that
    ``plan --seeds 8`` with the tasks' options returns (:func:`closure_nlp.planning.seeds.choose`,
    by
    the rows' ``rho_unit``), over the tasks of those seeds done without error."""
    rows = ok[ok.seed.isin(list(seeds))].to_dict("records")
    if not rows:
        return {BEST_RHO: float("nan"), BEST_SEED: None}
    best = rows[
        choose([(r["seed"], bool(r["force_closure"]), r["rho"], r.get("rho_unit")) for r in rows])
    ]
    return {BEST_RHO: float(best["rho"]), BEST_SEED: int(best["seed"])}


BEST_RHO = f"best_of_{DEFAULT_SEEDS}_rho"
BEST_SEED = f"best_of_{DEFAULT_SEEDS}_seed"


SUMMARY_COLUMNS = [
    "tasks",
    "done",
    "errors",
    "force_closure",
    "certified",
    "success_rate",
    "rho_median",
    "rho_best",
    "rho_hat_median",
    "gap_median",
    "seconds_median",
    "reused",
    BEST_RHO,
    BEST_SEED,
]


def _stat(series, how: str) -> float:
    series = series.dropna()
    return float(getattr(series, how)()) if len(series) else float("nan")


def summary_markdown(study: Study, summary, frame) -> str:
    """``summary.md``: the table, the counts and the first errors."""
    rows = frame[frame.task_id.isin({t.task_id for t in study.tasks})]
    errors = rows[rows.status != "ok"]
    lines = [f"# Study {study.name}", ""]
    if study.description:
        lines += [study.description, ""]
    lines += [
        f"{len(study.tasks)} tasks ({len(study.models)} models, seeds "
        f"{_range_text(study.seeds)}); {len(rows)} done, {len(errors)} with errors. "
        "rho < 0 is force closure (best = most negative); success = force closure; seconds = "
        "heuristic + iterative + placement of one task as it ran (median); reused = tasks that "
        "took the iterative run and the placement of a set from an earlier task of their worker; "
        "gap = the placement's certified gap to the best placement on its elements (median of "
        "the force-closure rows); "
        f"best of {DEFAULT_SEEDS} = the task of the first {DEFAULT_SEEDS} seeds that `plan --seeds "
        f"{DEFAULT_SEEDS}` returns (force closure first, then the lowest rho; rhos within the "
        "certified accuracy tie, and the lowest seed wins).",
        "",
        "| " + " | ".join(summary.columns) + " |",
        "|" + "---|" * len(summary.columns),
    ]
    for record in summary.to_dict("records"):
        lines.append("| " + " | ".join(_cell(k, v) for k, v in record.items()) + " |")
    if len(errors):
        lines += ["", "## Errors", ""]
        for record in errors.head(20).to_dict("records"):
            lines.append(
                f"- {record['task_id']} ({record['model']}, {record['type']} x "
                f"{record['contacts']}, seed {record['seed']}): {record['error']}"
            )
        if len(errors) > 20:
            lines.append(f"- ... and {len(errors) - 20} more (see results.csv)")
    lines += ["", "Plots: rho.png (rho over seeds), seconds.png (time per task).", ""]
    return "\n".join(lines)


def _range_text(seeds: Sequence[int]) -> str:
    if list(seeds) == list(range(seeds[0], seeds[0] + len(seeds))) and len(seeds) > 2:
        return f"{seeds[0]}..{seeds[-1]}"
    return ",".join(str(s) for s in seeds)


def _cell(key: str, value) -> str:
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return "-"
    if key == "success_rate":
        return f"{100 * value:.0f}%"
    if key in ("rho_median", "rho_best", "rho_hat_median", BEST_RHO):
        return f"{value:.4f}"
    if key == "seconds_median":
        return f"{value:.2f}"
    if key == "gap_median":
        return f"{100 * value:.2g}%"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def write_outputs(study: Study, frame, summary, out) -> dict:
    """Write ``results.csv``, ``summary.md``, ``summary.csv``, ``rho.png`` and ``seconds.png``."""
    out = Path(out)
    order = {t.task_id: i for i, t in enumerate(study.tasks)}
    rows = frame[frame.task_id.isin(order)].copy()
    rows["_order"] = rows.task_id.map(order)
    rows = rows.sort_values("_order").drop(columns="_order")
    for column in ("heuristic_elements", "iterative_elements", "elements"):
        rows[column] = rows[column].map(
            lambda ids: " ".join(str(int(i)) for i in ids) if ids is not None else None
        )
    paths = {
        "results.csv": write_atomic(out / "results.csv", rows.to_csv(index=False)),
        "summary.csv": write_atomic(out / "summary.csv", summary.to_csv(index=False)),
        "summary.md": write_atomic(out / "summary.md", summary_markdown(study, summary, frame)),
    }
    paths.update(plot_study(study, frame, out))
    return {k: str(v) for k, v in paths.items()}
