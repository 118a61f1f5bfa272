"""The spread of rho over seeds on the three examples, the chosen seed starred.

    python -m benchmarks.bench seeds > examples/out/bench_seeds.json
    python examples/seeds_spread.py [examples/out/bench_seeds.json] [--out docs/seeds_spread.png]

Reads the ``examples`` part of a ``bench seeds`` report (each example's seeds, their rho and the
seed ``plan --seeds`` chose) and draws one panel per example: rho of every seed, the median
dashed, the chosen seed starred (lower rho holds more load).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", nargs="?", default=str(HERE / "out" / "bench_seeds.json"))
    parser.add_argument("--out", default=str(HERE.parent / "docs" / "seeds_spread.png"))
    args = parser.parse_args(argv)
    examples = json.loads(Path(args.report).read_text())["examples"]
    fig, axes = plt.subplots(1, len(examples), figsize=(3.2 * len(examples), 3.2), sharey=False)
    for ax, (name, entry) in zip(np.atleast_1d(axes), examples.items()):
        seeds, rhos = entry["seeds_each"], entry["rho_each"]
        ax.plot(seeds, rhos, "o", color="tab:blue", label="seed")
        ax.axhline(float(np.median(rhos)), color="grey", lw=0.8, ls="--", label="median")
        chosen = entry["chosen_seed"]
        ax.plot(
            [chosen],
            [rhos[seeds.index(chosen)]],
            "*",
            ms=16,
            mfc="none",
            color="black",
            label=f"chosen (seed {chosen})",
        )
        ax.set_title(f"{name}: {len(seeds)} seeds")
        ax.set_xlabel("seed")
        ax.legend(fontsize="x-small")
    np.atleast_1d(axes)[0].set_ylabel("rho (lower holds more)")
    fig.tight_layout()
    fig.savefig(args.out, dpi=130, bbox_inches="tight")
    plt.close(fig)
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
