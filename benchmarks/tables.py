"""Markdown tables from the JSON that ``python -m benchmarks.bench WHAT > out.json`` writes.

    python -m benchmarks.tables out.json [more.json ...] [--columns KEY[=HEADER],...]

One table per file: a row per family, model or example (the report's first mapping of named
entries), a column per number in it (a ``{"median": ...}`` entry gives its median; lists are
left out), and a caption naming the benchmark, the machine (cores, CPU model), the load average
before and after the run and the date, from the report's ``machine`` entry. A report without one
says so in its caption.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

# the mappings of named entries a report's rows come from, in the order they are looked for
ROWS = ("families", "models", "examples", "fixtures", "parts", "cases", "runs")


def _flat(entry: dict, prefix: str = "") -> dict:
    """``entry``'s numbers (and short strings such as ``"20/20"``) by dotted key."""
    out = {}
    for key, value in entry.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            if "median" in value and not isinstance(value["median"], dict):
                out[name] = value["median"]
            else:
                out.update(_flat(value, f"{name}."))
        elif isinstance(value, bool) or isinstance(value, (int, float)):
            out[name] = value
        elif isinstance(value, str) and len(value) <= 24:
            out[name] = value
    return out


def _cell(value) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if value == 0 or 1e-3 <= abs(value) < 1e5:
            return f"{value:.4g}" if abs(value) < 10 else f"{value:.1f}"
        return f"{value:.2g}"
    return str(value)


def caption(report: dict) -> str:
    """What was measured, where and when."""
    what = report.get("benchmark", "benchmark")
    m = report.get("machine")
    if not m:
        return f"*`bench {what}`; machine, load and date not recorded.*"
    load = m.get("load")
    if isinstance(load, list):
        load_text = f"load {load[0]:.1f} before, {load[1]:.1f} after"
    else:  # a report stored before the machine entry: the load as its run noted it
        load_text = f"load {load}" if load else "load not recorded"
    cpu = m.get("cpu") or "CPU not recorded"
    cores, date = m.get("cores", "?"), m.get("date", "?")
    return f"*`bench {what}`: {cores} cores ({cpu}), {load_text}, {date}.*"


def table(report: dict, columns: list[str] | None = None) -> str:
    """The report's rows as a Markdown table under its caption; ``columns``: dotted keys, each
    optionally ``KEY=HEADER``."""
    rows_key = next((k for k in ROWS if isinstance(report.get(k), dict)), None)
    if rows_key is None:  # one row: the report itself
        rows = {report.get("benchmark", "run"): _flat(report)}
    else:
        entries = report[rows_key].items()
        rows = {name: _flat(entry) for name, entry in entries if isinstance(entry, dict)}
    if columns is None:
        columns = []
        for flat in rows.values():
            columns += [c for c in flat if c not in columns]
    keys = [c.split("=", 1)[0] for c in columns]
    headers = [c.split("=", 1)[-1] for c in columns]
    lines = [
        caption(report),
        "",
        "| | " + " | ".join(headers) + " |",
        "|---|" + "---|" * len(columns),
    ]
    for name, flat in rows.items():
        lines.append(f"| {name} | " + " | ".join(_cell(flat.get(k, "-")) for k in keys) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.tables", description=__doc__)
    parser.add_argument("reports", nargs="+", type=Path)
    parser.add_argument(
        "--columns", help="comma-separated dotted keys, each KEY or KEY=HEADER (default: all)"
    )
    args = parser.parse_args(argv)
    columns = args.columns.split(",") if args.columns else None
    for path in args.reports:
        print(table(json.loads(path.read_text()), columns))
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
