"""The engineer's intent on the machined block (examples/block): a 3-2-1 fixture's three base
locators fixed, four clamps with friction planned off the machined top (``exclude
facing:+z``) at least 5 mm apart, against the same seven contacts planned freely."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from closure_nlp import (
    Contact,
    ContactSet,
    Eligibility,
    PlacementOptions,
    contact_specs,
    load_model,
    plan,
)

BLOCK = Path(__file__).resolve().parents[1] / "examples" / "block" / "block.model.json"
BASE = ((-20.0, -12.0, 0.0), (20.0, -12.0, 0.0), (0.0, 14.0, 0.0))
SPACING = 5.0


def base_locators() -> ContactSet:
    return ContactSet(tuple(Contact(p, (0.0, 0.0, 1.0), type="fpc") for p in BASE))


def _entry(result, seconds: float, excluded=()) -> dict:
    placed = result.placement
    x = np.array([c.position for c in placed.contact_set.contacts])
    d = np.linalg.norm(x[:, None] - x[None], axis=2)[np.triu_indices(len(x), 1)]
    return {
        "rho": placed.rho,
        "bounds": list(placed.bounds),
        "force_closure": placed.force_closure,
        "seconds": seconds,
        "elements": list(placed.elements),
        "on_excluded": sorted(set(placed.elements) & set(excluded)),
        "closest_pair": float(d.min()),
    }


def bench_intent(seeds=(0, 1, 2)) -> dict:
    """Per seed: the plan with intent and without, rho and seconds; the ratio of the seconds."""
    model = load_model(BLOCK)
    fixed = base_locators()
    clamps = contact_specs(4, type="pcwf", mu=0.3)
    free = contact_specs(7, type=["fpc"] * 3 + ["pcwf"] * 4, mu=0.3)
    rows = []
    for seed in seeds:
        intent = Eligibility(model, clamps, exclude="facing:+z", fixed=fixed)
        t0 = time.perf_counter()
        kept = plan(intent, seeds=1, seed=seed, placement=PlacementOptions(min_spacing=SPACING))
        with_intent = _entry(kept, time.perf_counter() - t0, intent.excluded)
        placed = kept.placement.contact_set.contacts[: len(BASE)]
        with_intent["fixed_unchanged"] = all(
            np.array_equal(c.position, p) for c, p in zip(placed, BASE)
        )
        t0 = time.perf_counter()
        plain = plan(Eligibility(model, free), seeds=1, seed=seed)
        without = _entry(plain, time.perf_counter() - t0, intent.excluded)
        rows.append({"seed": seed, "intent": with_intent, "without": without})
    total = [sum(r[k]["seconds"] for r in rows) for k in ("intent", "without")]
    return {
        "model": str(BLOCK.name),
        "fixed": [list(p) for p in BASE],
        "exclude": "facing:+z",
        "min_spacing": SPACING,
        "runs": rows,
        "seconds_ratio": total[0] / total[1],
        "seconds_ratio_median": float(
            np.median([r["intent"]["seconds"] / r["without"]["seconds"] for r in rows])
        ),
    }
