"""Studies: grids of planning runs on many models, contact types and seeds, run on Dask.

A study file (TOML) names a grid: models (files, or folders of ``*.model.json``, relative to the
study file), contact types and counts, ``mu``, ``mu_s``, ``f_max``, ``torque_scale`` (each one
value or a list), seeds (a count or a list) and the options of the selection and placement
algorithms::

    name = "grasps"
    models = ["../../models/lamp.model.json", "../../models/cup.model.json"]
    type = ["pcwf", "sfce"]
    contacts = [3, 4]
    mu = [0.2, 0.4]
    seeds = 20

    [placement]
    starts = 2

Keys: ``models`` (required; a path or a list), ``contacts`` (required; number of contacts m),
``type`` (default ``"pcwf"``), ``mu`` (0.2), ``mu_s`` (0.2), ``f_max`` (1), ``torque_scale`` (1),
``seeds`` (1: seed 0), ``name`` (default: the file name), ``description``, and the tables
``[selection]`` (fields of :class:`~closure_nlp.selection.algorithms.SelectionOptions`) and
``[placement]``
(fields of :class:`~closure_nlp.placement.options.PlacementOptions`). Every value-or-list key is one
axis of the grid; an unknown key or option, a missing model or a bad value is a ``ValueError``
(or ``TypeError``) that names the key and the value.

:func:`load_study` validates everything before anything runs and expands the grid into
:class:`Task` objects, each with a stable ``task_id`` (a hash of its inputs). :func:`run_study`
runs the tasks not done yet on a ``dask.distributed`` cluster (a local one by default) or
serially, and writes one Parquet part-file per task in ``OUT/results/`` as each task finishes, so
a crash loses nothing already done and running the study again resumes it. At the end it writes
a summary table (``summary.md``, ``summary.csv``), all rows (``results.csv``) and plots
(``rho.png``, ``seconds.png``).

Each worker builds the solvers of a (model, contact specs, torque scale) once and reuses them for
every seed (:func:`run_task` keeps a small per-thread cache); the rho and rho_hat NLPs, cached
by shape, serve every task of the worker. A seed whose heuristic meets a set that an earlier
task of the worker met takes the iterative run and the placement from it (both are
deterministic; ``plan``'s ``memo``).

A result row (:data:`ROW_COLUMNS`) holds the task's inputs, ``status`` (``ok`` or ``error``) and
``error``; per selection step its ``elements``, ``rho_hat`` with its certified bounds
``rho_hat_lo`` and ``rho_hat_hi``, ``eligible``, ``evaluations`` and ``seconds``; the
placement's ``elements``, ``rho`` with its bounds ``rho_lo`` and ``rho_hi``, ``rho_unit`` (the
wrench scale by which ``plan --seeds`` tells ties apart), ``force_closure``,
``marginal``, ``converged`` (the bracket reached 1e-6), ``start_rho``, rounds, moves, seconds
and the placed contacts (JSON); the task's ``seconds`` (the three steps, as this task spent
them), ``reused`` (the steps taken from an earlier task of the worker, comma-separated, e.g.
``iterative,placement``: their rows' step seconds are what computing them took),
``setup_seconds`` (model and problem objects; CasADi builds its solvers lazily, inside the first
step), ``wall_seconds``, ``solvers_built`` (this task met an empty cache), ``rss_mib`` and
``peak_rss_mib`` (the worker's resident set at the task's end and its peak so far, Linux),
``worker`` (``host:pid``) and ``finished`` (UTC).
The package has one module per concept: :mod:`.grid` (the study file, its grid, the task groups),
:mod:`.tasks` (a task and running it on a worker), :mod:`.store` (the Parquet result files),
:mod:`.running` (the driver, on Dask or serially), :mod:`.summary` (tables) and :mod:`.plots`.
"""

from closure_nlp.study.grid import (
    MODEL_SUFFIX,
    REQUIRED_KEYS,
    STUDY_KEYS,
    ModelRef,
    Study,
    group_keys,
    load_study,
    study_from_dict,
    task_groups,
)
from closure_nlp.study.plots import plot_study
from closure_nlp.study.running import (
    StudyProgress,
    StudyRun,
    check_scheduler_address,
    local_cluster,
    run_study,
)
from closure_nlp.study.store import ROW_COLUMNS, read_results, write_row
from closure_nlp.study.summary import SUMMARY_COLUMNS, summarize, summary_markdown, write_outputs
from closure_nlp.study.tasks import (
    TASK_VERSION,
    Runner,
    Task,
    clear_cache,
    error_row,
    run_task,
    task_row,
)

__all__ = [
    "MODEL_SUFFIX",
    "ModelRef",
    "REQUIRED_KEYS",
    "ROW_COLUMNS",
    "Runner",
    "STUDY_KEYS",
    "SUMMARY_COLUMNS",
    "Study",
    "StudyProgress",
    "StudyRun",
    "TASK_VERSION",
    "Task",
    "check_scheduler_address",
    "clear_cache",
    "error_row",
    "group_keys",
    "load_study",
    "local_cluster",
    "plot_study",
    "read_results",
    "run_study",
    "run_task",
    "study_from_dict",
    "summarize",
    "summary_markdown",
    "task_groups",
    "task_row",
    "write_outputs",
    "write_row",
]
