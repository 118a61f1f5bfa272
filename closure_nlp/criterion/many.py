"""Certified rho of many contact sets at once, on every core: :func:`rho_many`.

Each set is certified exactly as :func:`~closure_nlp.criterion.support_minimum.rho` certifies it,
and
its answer depends on that set alone, so the columns are the same whatever the number of
workers and whichever worker took which set. Threads share the process (the compiled kernels
release the GIL); processes (fork, where the system has it) avoid the interpreter's lock for
the Python between kernel calls, at the price of sending the sets and answers between them.
"""

from __future__ import annotations

import multiprocessing
import sys
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial

import numpy as np

from closure_nlp.base.cores import checked_workers
from closure_nlp.base.validation import as_count
from closure_nlp.contact.contact_set import (
    DEFAULT_F_MAX,
    DEFAULT_MU,
    DEFAULT_MU_S,
    ContactSet,
)
from closure_nlp.contact.slot_arrays import slots_of_arrays
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.support_minimum import (
    certified_search,
    checked_tol,
    minimizer_for,
    rho,
)

# Sets per task: large enough that sending a task costs little against certifying it (about a
# millisecond a set), small enough that the workers finish together.
CHUNK = 32
POOLS = ("threads", "processes")


class _Columns:
    """Read-only columns of many certified answers, one row per set (the fields of each
    subclass); ``from_results`` reads them from results of that kind."""

    # column -> (attribute of a result, dtype, shape of one row)
    COLUMNS: dict = {}

    def __post_init__(self) -> None:
        for name in self.COLUMNS:
            column = np.array(getattr(self, name))  # a copy the caller cannot change
            column.flags.writeable = False
            object.__setattr__(self, name, column)

    def __len__(self) -> int:
        return len(self.seconds)

    @classmethod
    def from_results(cls, results):
        columns = {}
        for name, (attribute, dtype, shape) in cls.COLUMNS.items():
            values = [_attribute(r, attribute) for r in results]
            columns[name] = np.array(values, dtype=dtype).reshape(len(results), *shape)
        return cls(**columns)


def _attribute(result, dotted: str):
    for part in dotted.split("."):
        result = getattr(result, part)
    return result


_SHARED = {
    "bounds": ("bounds", float, (2,)),
    "marginal": ("marginal", bool, ()),
    "converged": ("converged", bool, ()),
    "direction": ("direction", float, (6,)),
    "seconds": ("stats.seconds", float, ()),
}


@dataclass(frozen=True, eq=False)
class RhoColumns(_Columns):
    """The answers of :func:`rho_many`, one row per contact set, as read-only arrays.

    Attributes
    ----------
    rho : (N,) float
    bounds : (N, 2) float
        Certified ``[lo, hi]`` of each rho.
    force_closure, marginal, converged : (N,) bool
        As :class:`~closure_nlp.criterion.support_minimum.RhoResult`'s, from each certified
        bracket.
    direction : (N, 6) float
        Each set's weakest unit wrench direction ``u*``.
    seconds : (N,) float
        Each set's own cost (search and certificate).
    """

    COLUMNS = {"rho": ("rho", float, ()), "force_closure": ("force_closure", bool, ()), **_SHARED}

    rho: np.ndarray
    bounds: np.ndarray
    force_closure: np.ndarray
    marginal: np.ndarray
    converged: np.ndarray
    direction: np.ndarray
    seconds: np.ndarray


@dataclass(frozen=True, eq=False)
class RhoHatColumns(_Columns):
    """The answers of :func:`rho_hat_many`, one row per element set: ``rho_hat`` (N,),
    ``eligible`` (N,) and the other columns of :class:`RhoColumns`."""

    COLUMNS = {"rho_hat": ("rho_hat", float, ()), "eligible": ("eligible", bool, ()), **_SHARED}

    rho_hat: np.ndarray
    bounds: np.ndarray
    eligible: np.ndarray
    marginal: np.ndarray
    converged: np.ndarray
    direction: np.ndarray
    seconds: np.ndarray


def rho_many(
    positions,
    inward_normals=None,
    *,
    type="pcwf",
    mu=DEFAULT_MU,
    mu_s=DEFAULT_MU_S,
    f_max=DEFAULT_F_MAX,
    torque_scale=1.0,
    reference_point=None,
    workers: int | None = None,
    pool: str = "threads",
    tol: float | None = None,
) -> RhoColumns:
    """Certified rho(0, W_c^M) of N contact sets of m contacts each.

    Parameters
    ----------
    positions : (N, m, 3) float, or a sequence of ContactSet
        Contact positions; or the contact sets themselves (then ``inward_normals`` and the
        contact parameters are theirs, and must be omitted).
    inward_normals : (N, m, 3) float
        Unit inward normals (normalised here; zero or non-finite ones are refused).
    type, mu, mu_s, f_max : scalar, (N,) or (N, m)
        One value for every contact, one per set, or one per contact. ``type`` is a name
        (``"fpc"``, ``"pcwf"``, ``"sfcl"``, ``"sfce"``) or a :class:`ContactType`.
    torque_scale : float or (N,) float
        Multiplies every torque row of the sets' grasp matrices.
    reference_point : None, (3,) or (N, 3) float
        The point torques are taken about (None: the origin).
    workers : int, optional
        How many sets are certified at once (default: one per core); 1 runs them in this
        thread. Too few sets to share out (one chunk of 32) run in this thread, each long
        certificate's rounds in two threads (:func:`rho`'s ``workers``). The answers do not
        depend on it.
    pool : {"threads", "processes"}
        How the workers run: threads of this process, or processes forked from it (where the
        system forks; threads otherwise).
    tol : float, optional
        Relative width of every certified bracket, ``hi - lo <= tol * max(|rho|, unit)`` with
        ``unit`` the set's own wrench scale (default ``1e-6``, as :func:`rho`), in
        ``[1e-9, 0.1]``. A wider bracket costs less on force-closure sets, whose branch and
        bound stops sooner; the verdicts take the same accuracy (``force_closure`` only when
        ``hi < -tol * unit``, ``marginal`` when the bracket reaches within that of zero).

    Returns
    -------
    RhoColumns
        Columns ``rho``, ``bounds``, ``force_closure``, ``marginal``, ``converged``,
        ``direction`` and ``seconds``, in the order of the sets.
    """
    tol = checked_tol(tol)
    sets = _contact_sets(positions, inward_normals, type, mu, mu_s, f_max, torque_scale,
                         reference_point)  # fmt: skip
    cores = checked_workers(workers)
    workers = _workers(cores, len(sets))
    if pool not in POOLS:
        raise ValueError(f"pool: expected one of {', '.join(POOLS)}, got {pool!r}")
    certify = partial(_certify_chunk, tol=tol)
    if workers == 1:
        return RhoColumns.from_results(certify(sets, threads=cores))
    chunks = [sets[k : k + CHUNK] for k in range(0, len(sets), CHUNK)]
    if pool == "processes" and "fork" in multiprocessing.get_all_start_methods():
        certify(sets[:1])  # kernels loaded before the fork: the workers inherit them
        context = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(workers, mp_context=context) as executor:
            parts = list(executor.map(certify, chunks))
    else:
        with ThreadPoolExecutor(workers) as executor:
            parts = list(executor.map(certify, chunks))
    return RhoColumns.from_results([r for part in parts for r in part])


def _certify_chunk(sets, tol: float, threads: int = 1) -> list:
    """Certified rho of each set to the relative bracket ``tol``: a ContactSet by
    :func:`rho`, the slots of one given as arrays (no tolerance) by the same search and
    certificate that :func:`rho` runs on them, a long certificate's rounds in ``threads``."""
    minimizer = minimizer_for(tol)
    return [
        certified_search(minimizer, s, workers=threads)
        if isinstance(s, WrenchSlots)
        else rho(s, minimizer=minimizer, workers=threads)
        for s in sets
    ]


def rho_hat_many(
    eligibility, element_sets, *, workers: int | None = None, tol: float | None = None
) -> RhoHatColumns:
    """Certified rho_hat of many element sets of one model, in threads.

    Parameters
    ----------
    eligibility : Eligibility
        The model, contact specs and torque scale
        (:class:`~closure_nlp.criterion.rho_hat.Eligibility`).
    element_sets : sequence of sequences of int
        Element ids, one per contact of each set.
    workers : int, optional
        Sets certified at once (default: one per core); the answers do not depend on it.
    tol : float, optional
        Relative width of every certified bracket, as :func:`rho_many`'s (default: the
        eligibility's minimizer's, 1e-6); the verdicts take the same accuracy.

    Returns
    -------
    RhoHatColumns
    """
    tol = None if tol is None else checked_tol(tol)
    sets = [
        eligibility.check_elements(ids, f"element_sets[{k}]") for k, ids in enumerate(element_sets)
    ]
    if not sets:
        raise ValueError("element_sets: at least one set is needed, got none")
    workers = _workers(workers, len(sets))
    certify = partial(eligibility, tol=tol)
    if workers == 1:
        return RhoHatColumns.from_results([certify(ids) for ids in sets])
    with ThreadPoolExecutor(workers) as executor:
        return RhoHatColumns.from_results(list(executor.map(certify, sets)))


def _workers(workers, count: int) -> int:
    return max(1, min(checked_workers(workers), -(-count // CHUNK)))


def _contact_sets(positions, normals, kind, mu, mu_s, f_max, torque_scale, reference_point):
    """The N sets the arguments describe (see :func:`rho_many`): the ContactSets given, or for
    arrays their slots built in one pass (:func:`slots_of_arrays`), or ContactSets where that
    pass leaves the input to the per-set checks."""
    if normals is None:
        sets = list(positions) if isinstance(positions, (list, tuple)) else None
        if sets is None or not sets:
            raise TypeError(
                "positions: expected (N, m, 3) positions with inward_normals, or a non-empty "
                f"list of ContactSet, got {type(positions).__name__}"
            )
        for k, s in enumerate(sets):
            if not isinstance(s, ContactSet):
                raise TypeError(f"positions[{k}]: expected a ContactSet, got {type(s).__name__}")
        return sets
    P = _array3(positions, "positions")
    U = _array3(normals, "inward_normals")
    if P.shape != U.shape:
        raise ValueError(
            f"inward_normals: expected the shape of positions {P.shape}, got {U.shape}"
        )
    N, m, _ = P.shape
    as_count(N, "positions", sys.maxsize, "contact sets")
    kinds = _per_contact(kind, N, m, "type", object)
    columns = {name: _per_contact(value, N, m, name, float)
               for name, value in (("mu", mu), ("mu_s", mu_s), ("f_max", f_max))}  # fmt: skip
    scales = _per_set(torque_scale, N, "torque_scale", ())
    points = (
        None if reference_point is None else _per_set(reference_point, N, "reference_point", (3,))
    )
    slots = slots_of_arrays(P, U, kinds, *columns.values(), scales, points)
    if slots is not None:
        return slots
    return [
        ContactSet.from_arrays(
            P[k],
            U[k],
            type=kinds[k],
            mu=columns["mu"][k],
            mu_s=columns["mu_s"][k],
            f_max=columns["f_max"][k],
            torque_scale=float(scales[k]),
            reference_point=None if points is None else points[k],
            name=f"sets[{k}].contacts",
        )
        for k in range(N)
    ]


def _array3(value, field: str) -> np.ndarray:
    if isinstance(value, np.ma.MaskedArray):
        raise TypeError(f"{field}: a masked array is not accepted (fill or drop masked rows)")
    array = np.asarray(value)
    if array.dtype == bool or not np.issubdtype(array.dtype, np.number):
        raise TypeError(f"{field}: expected numbers, got an array of {array.dtype}")
    if array.ndim != 3 or array.shape[2] != 3 or 0 in array.shape:
        raise ValueError(f"{field}: expected shape (N, m, 3) with N, m >= 1, got {array.shape}")
    return array.astype(float)


def _per_contact(value, N: int, m: int, field: str, dtype) -> np.ndarray:
    """``value`` as (N, m): one value, one per set (N,), or one per contact (N, m)."""
    array = np.asarray(value, dtype=object if dtype is object else None)
    if dtype is not object and (array.dtype == bool or not np.issubdtype(array.dtype, np.number)):
        raise TypeError(f"{field}: expected numbers, got {value!r:.60}")
    if array.ndim == 0:
        return np.full((N, m), array.item(), dtype=dtype)
    if array.shape == (N,):
        return np.repeat(array.astype(dtype)[:, None], m, axis=1)
    if array.shape == (N, m):
        return array.astype(dtype)
    raise ValueError(f"{field}: expected one value, ({N},) or ({N}, {m}) values, got {array.shape}")


def _per_set(value, N: int, field: str, shape: tuple) -> np.ndarray:
    """``value`` as (N, *shape): one value for every set or one per set."""
    array = np.asarray(value)
    if array.dtype == bool or not np.issubdtype(array.dtype, np.number):
        raise TypeError(f"{field}: expected numbers, got {value!r:.60}")
    if array.shape == shape:
        return np.broadcast_to(array, (N, *shape)).astype(float)
    if array.shape == (N, *shape):
        return array.astype(float)
    raise ValueError(f"{field}: expected shape {shape} or {(N, *shape)}, got {array.shape}")


__all__ = ["RhoColumns", "RhoHatColumns", "rho_hat_many", "rho_many"]
