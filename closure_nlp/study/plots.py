"""Plots of a study: rho and seconds per group of tasks."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from closure_nlp.study.grid import Study, task_groups


def plot_study(study: Study, frame, out) -> dict:
    """``rho.png``: rho over seeds per group; ``seconds.png``: seconds per task per group."""
    from closure_nlp.report.drawing import pyplot, save_figure

    plt = pyplot()
    groups = [
        (" ".join(_label(k, v) for k, v in values.items()), rows[rows.status == "ok"])
        for values, _, rows in task_groups(study, frame)
    ]
    paths = {}
    for name, column, xlabel in (
        ("rho.png", "rho", "rho (negative = force closure; lower is better)"),
        ("seconds.png", "seconds", "seconds per task (heuristic + iterative + placement)"),
    ):
        fig, ax = plt.subplots(figsize=(8.0, 1.2 + 0.38 * max(1, len(groups))))
        data = [g[column].dropna().to_numpy() for _, g in groups]
        positions = np.arange(len(groups))[::-1]
        filled = [i for i, d in enumerate(data) if len(d)]
        if filled:
            ax.boxplot(
                [data[i] for i in filled],
                positions=positions[filled],
                **_horizontal(),
                widths=0.6,
                showfliers=False,
            )
        rng = np.random.default_rng(0)
        for i, d in enumerate(data):
            y = positions[i] + rng.uniform(-0.18, 0.18, len(d))
            ax.plot(d, y, "o", ms=3, alpha=0.6, color="tab:blue")
        ax.set_yticks(positions)
        ax.set_yticklabels([label for label, _ in groups], fontsize=8)
        ax.set_ylim(-0.7, len(groups) - 0.3)
        if column == "rho":
            ax.axvline(0.0, color="grey", lw=0.8)
        ax.set_xlabel(xlabel)
        ax.set_title(f"{study.name}: {column} per task (over seeds)")
        fig.tight_layout()
        paths[name] = save_figure(fig, Path(out) / name)
        plt.close(fig)
    return paths


def _horizontal() -> dict:
    """``boxplot`` keywords for horizontal boxes (``vert`` is deprecated from matplotlib 3.10)."""
    import matplotlib

    major, minor = (int(p) for p in matplotlib.__version__.split(".")[:2])
    return {"orientation": "horizontal"} if (major, minor) >= (3, 10) else {"vert": False}


def _label(key: str, value) -> str:
    if key in ("model", "type"):
        return str(value)
    if key == "contacts":
        return f"x{value}"
    return f"{key}={'-' if value is None else f'{value:g}'}"
