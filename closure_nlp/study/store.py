"""The result store: one Parquet part-file per finished task, read back as one table."""

from __future__ import annotations

import io
import logging
from pathlib import Path

from closure_nlp.base.files import write_atomic

log = logging.getLogger(__name__)


def _columns() -> list[tuple[str, str]]:
    """(name, kind) of every result column; kinds: text, real, int, flag, ids."""
    steps = [
        (f"{prefix}_{name}", kind)
        for prefix in ("heuristic", "iterative")
        for name, kind in (
            ("elements", "ids"),
            ("rho_hat", "real"),
            ("rho_hat_lo", "real"),
            ("rho_hat_hi", "real"),
            ("eligible", "flag"),
            ("evaluations", "int"),
            ("seconds", "real"),
        )
    ]
    return [
        *[(k, "text") for k in ("task_id", "model", "model_digest", "type")],
        ("contacts", "int"),
        *[(k, "real") for k in ("mu", "mu_s", "f_max", "torque_scale")],
        ("seed", "int"),
        *[(k, "text") for k in ("selection", "placement", "status", "error")],
        *steps,
        ("heuristic_rounds", "int"),
        ("elements", "ids"),
        ("rho", "real"),
        ("rho_lo", "real"),
        ("rho_hi", "real"),
        ("rho_unit", "real"),
        ("force_closure", "flag"),
        ("robust", "flag"),
        ("marginal", "flag"),
        ("converged", "flag"),
        ("start_rho", "real"),
        ("capacity_bound", "real"),
        ("gap", "real"),
        ("placement_rounds", "int"),
        ("placement_moves", "int"),
        ("placement_attempts", "int"),
        ("placement_seconds", "real"),
        ("placed_contacts", "text"),
        ("objective", "text"),
        *[(k, "real") for k in ("load_factor", "load_factor_lo", "load_factor_hi")],
        ("load_factors", "text"),
        ("seconds", "real"),
        ("reused", "text"),
        ("setup_seconds", "real"),
        ("solvers_built", "flag"),
        ("wall_seconds", "real"),
        ("rss_mib", "real"),
        ("peak_rss_mib", "real"),
        *[(k, "text") for k in ("worker", "finished", "closure_nlp")],
    ]


ROW_COLUMNS: tuple[str, ...] = tuple(name for name, _ in _columns())


def _schema():
    """The Arrow schema of a result row (:data:`ROW_COLUMNS`)."""
    import pyarrow as pa

    types = {
        "text": pa.string(),
        "real": pa.float64(),
        "int": pa.int64(),
        "flag": pa.bool_(),
        "ids": pa.list_(pa.int64()),
    }
    return pa.schema([(name, types[kind]) for name, kind in _columns()])


def write_row(results_dir, row: dict) -> Path:
    """Write one row as ``results_dir/<task_id>.parquet``, atomically (replacing an old one)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist([row], schema=_schema())
    buffer = io.BytesIO()
    pq.write_table(table, buffer)
    return write_atomic(Path(results_dir) / f"{row['task_id']}.parquet", buffer.getvalue())


def read_results(results_dir):
    """Every row in ``results_dir`` as a pandas DataFrame (one row per part-file).

    An unreadable part-file is skipped with a warning (its task then counts as not done).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = _schema()
    tables = []
    for path in sorted(Path(results_dir).glob("*.parquet")):
        try:
            table = pq.read_table(path)
        except (OSError, pa.ArrowException) as exc:
            log.warning("skipping unreadable result file %s: %s", path, exc)
            continue
        for name in schema.names:  # files from older versions may lack newer columns
            if name not in table.column_names:
                table = table.append_column(name, pa.nulls(len(table), schema.field(name).type))
        tables.append(table.select(schema.names).cast(schema))
    if not tables:
        return schema.empty_table().to_pandas()
    frame = pa.concat_tables(tables).to_pandas()
    return frame.drop_duplicates("task_id", keep="last").reset_index(drop=True)
