"""Wrench sets and their support functions (paper eqs 26-32, 35-36), vectorised over directions.

A :class:`WrenchSlots` holds ``m`` slots. Slot ``i`` is the union of the extreme wrench sets of
its rows (one row per grasp matrix): one row for a contact (``W_i``, eq 14), one row per vertex
for an element (``What_i``, eq 22). The support function of the union of all Minkowski sums of
the slots (eqs 26 and 35) is, with ``P_i`` the slot values,

    p(u) = max over non-empty subsets S of sum_{i in S} P_i = sum_i max(P_i, 0) + min(max_i P_i, 0)

(the sum of the positive ``P_i`` if any is positive, otherwise the largest): O(m), not O(2^m).
The friction term is the same formula everywhere: ``f_max * (d_n + max_k sqrt(q_k(d)))`` with
``q_k(d) = sum_j W[k, j] * d_j**2`` from :func:`closure_nlp.contact.contact_set.friction_pieces`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from closure_nlp.base.ties import first_largest
from closure_nlp.base.validation import as_shaped
from closure_nlp.contact.contact_set import ContactSet, ContactType, friction_pieces
from closure_nlp.kernels import kernel_array
from closure_nlp.kernels import support as kernels

MAX_PIECES = 2  # SFCl has two friction pieces, the others fewer
# The NLPs (support minimum, exchange) take an element's vertex rows padded up to one of these
# sizes, so that elements of similar size share one NLP; evaluation in numpy takes them as they
# are (three of the pistol's facets have 18-24 vertices: padded, a certificate evaluated 1.5x
# the rows).
ROW_BUCKETS = (1, 2, 4, 8, 16, 32, 64)


def padded_rows(count: int) -> int:
    """The smallest bucket size holding ``count`` vertex rows."""
    for size in ROW_BUCKETS:
        if count <= size:
            return size
    return count


def pad_rows(rows: np.ndarray) -> np.ndarray:
    """``rows`` with its last one repeated up to :func:`padded_rows` (a repeated vertex adds
    nothing to the hull, and shapes in one bucket share their NLP)."""
    pad = padded_rows(len(rows)) - len(rows)
    return np.concatenate([rows, np.repeat(rows[-1:], pad, axis=0)]) if pad else rows


def piece_square(weights, d):
    """``q(d) = sum_j weights[j] * d[j]**2``: numpy arrays (last axis 4) or CasADi 4-vectors."""
    if isinstance(d, np.ndarray):
        return np.sum(weights * d**2, axis=-1)
    return sum(weights[j] * d[j] ** 2 for j in range(4))


@dataclass(frozen=True, eq=False)
class WrenchSlots:
    """Grasp matrices grouped in slots, with each row's force bound and friction pieces.

    Attributes
    ----------
    G : (K, 6, 4) float
        Grasp matrices, rows of one slot consecutive.
    starts : (m,) int
        Index of each slot's first row.
    f_max : (K,) float
    pieces : (K, MAX_PIECES, 4) float
        Friction weights of each row, zero rows where a type has fewer pieces.
    types : tuple of ContactType, length m
    n_pieces : tuple of int, length m
        Number of real friction pieces of each slot's type.
    """

    G: np.ndarray
    starts: np.ndarray
    f_max: np.ndarray
    pieces: np.ndarray
    types: tuple[ContactType, ...]
    n_pieces: tuple[int, ...]

    @classmethod
    def build(cls, slots) -> WrenchSlots:
        """From ``[(G_i (k_i, 6, 4), type, mu, mu_s, f_max), ...]``, one tuple per slot."""
        G, starts, f_max, pieces, types, n_pieces = [], [], [], [], [], []
        row = 0
        for Gi, kind, mu, mu_s, fmax in slots:
            Gi = np.asarray(Gi, dtype=float).reshape(-1, 6, 4)
            w = friction_pieces(kind, mu, mu_s)
            padded = np.zeros((MAX_PIECES, 4))
            padded[: len(w)] = w
            starts.append(row)
            row += len(Gi)
            G.append(Gi)
            f_max.append(np.full(len(Gi), fmax))
            pieces.append(np.broadcast_to(padded, (len(Gi), MAX_PIECES, 4)))
            types.append(kind)
            n_pieces.append(len(w))
        return cls(
            np.concatenate(G),
            np.asarray(starts),
            np.concatenate(f_max),
            np.concatenate(pieces),
            tuple(types),
            tuple(n_pieces),
        )

    @classmethod
    def from_contacts(cls, contact_set: ContactSet) -> WrenchSlots:
        """One slot, one row per contact: the sets ``W_i`` of ``W_c^M``."""
        G = contact_set.grasp_matrices()
        return cls.build(
            (G[i], c.type, c.mu, c.mu_s, c.f_max) for i, c in enumerate(contact_set.contacts)
        )

    def scaled(self, factor: float) -> WrenchSlots:
        """The same slots with every ``f_max`` times ``factor``: the support function, support
        points and rho scale by ``factor``, directions do not. The copy shares what does not
        depend on ``f_max`` (the packed rows, the rows' norms): a certificate scales every set
        it is given, and packing the rows afresh cost more than its search of a 4-contact set
        that is not in force closure."""
        f_max = self.f_max * factor
        copy = WrenchSlots(self.G, self.starts, f_max, self.pieces, self.types, self.n_pieces)
        G, _, pieces, npc, ends = self.packed
        object.__setattr__(copy, "_packed", (G, kernel_array(f_max), pieces, npc, ends))
        object.__setattr__(copy, "_row_norms_", self._row_norms())
        return copy

    @property
    def m(self) -> int:
        return len(self.starts)

    @property
    def rows_per_slot(self) -> tuple[int, ...]:
        return tuple(np.diff(np.append(self.starts, len(self.G))).tolist())

    def row_scales(self, friction: bool = True) -> tuple[float, float]:
        """Upper bounds on the force part and the torque part of any row's extreme wrench
        (``friction=False``: ``f_max`` times the norms of the rows of ``G``, the scale of the
        normal force's wrench), in the units of the set whatever the length unit.

        A row's force ``(f_n, f_t)`` has ``|f_t|^2 <= (sum of its friction weights) f_n^2`` and
        ``f_n <= f_max``; the first three rows of ``G`` map it to the force, the last three to
        the torque. The spin column (``torque_scale`` times the normal) counts times the spin
        coefficient ``mu_s``, a length: the spin moment is at most ``mu_s f_n``. Unweighted, it
        made a 7-FPC fixture (no spin at all) look 35x longer in torque than it is, and a part
        in metres with soft fingers (``mu_s`` 0.01 R) 1e6 times longer than in millimetres.
        """
        cached = self.__dict__.setdefault("_scales", {})  # the set is immutable
        if friction not in cached:
            cached[friction] = self._row_scales(friction)
        return cached[friction]

    def _row_scales(self, friction: bool) -> tuple[float, float]:
        top, bottom, tangential = self._row_norms()
        force = self.f_max * (np.sqrt(1.0 + tangential) if friction else 1.0)
        return float(np.max(top * force)), float(np.max(bottom * force))

    def _row_norms(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What :meth:`row_scales` takes from ``G`` and the pieces, not ``f_max`` (K,) each:
        the spectral norms of each row's force and torque parts (the spin column per unit of
        normal force) and the sum of its friction weights (1 more with spin friction)."""
        if "_row_norms_" not in self.__dict__:
            spin = np.sqrt(self.pieces[:, :, 3].max(axis=1))  # mu_s, or 0 without spin friction
            G = self.G.copy()
            G[:, :, 3] *= spin[:, None]  # the spin column per unit of normal force
            tangential = self.pieces[:, :, 1:3].sum(axis=(1, 2)) + (spin > 0)
            # spectral norms (numpy's ord=2: the largest singular value), both parts in one call
            parts = np.concatenate([G[:, :3, :], G[:, 3:, :]])
            top, bottom = np.split(np.linalg.svd(parts, compute_uv=False).max(axis=-1), 2)
            object.__setattr__(self, "_row_norms_", (top, bottom, tangential))
        return self._row_norms_

    # --- evaluation: the compiled kernels of :mod:`closure_nlp.kernels.support` ------------

    @property
    def packed(self) -> tuple:
        """The rows as the kernels take them, rows last (:mod:`closure_nlp.kernels.support`):
        ``G`` (6, 4, K), ``f_max`` (K,), pieces (2, 4, K), real pieces per row (K,) int, slot
        ends (m + 1,) int."""
        if "_packed" not in self.__dict__:
            self._check_rows()
            counts = np.diff(np.append(self.starts, len(self.G)))
            packed = (
                kernel_array(self.G.transpose(1, 2, 0)),
                kernel_array(self.f_max),
                kernel_array(self.pieces.transpose(1, 2, 0)),
                np.repeat(np.asarray(self.n_pieces, dtype=np.int64), counts),
                np.append(self.starts, len(self.G)).astype(np.int64),
            )
            object.__setattr__(self, "_packed", packed)
        return self._packed

    def _check_rows(self) -> None:
        """The arrays' shapes agree (``ValueError`` naming the first that does not): the kernels
        index the rows by ``starts`` and ``len(f_max)`` without bounds checks."""
        K = len(as_shaped(self.G, "G", ("K", 6, 4)))
        as_shaped(self.f_max, "f_max", (K,))
        as_shaped(self.pieces, "pieces", (K, MAX_PIECES, 4))
        starts = as_shaped(self.starts, "starts", ("m",))
        if starts.dtype.kind not in "iu" or not (
            len(starts) > 0 and starts[0] == 0 and np.all(np.diff(starts) > 0) and starts[-1] < K
        ):
            raise ValueError(
                f"starts: expected whole numbers rising from 0, each slot's first of the {K} rows "
                f"of G, got {np.array2string(starts, threshold=8)} ({starts.dtype})"
            )
        if len(self.n_pieces) != len(starts):
            raise ValueError(
                f"n_pieces: expected one count per slot ({len(starts)}), got {len(self.n_pieces)}"
            )

    def local(self, U: np.ndarray) -> np.ndarray:
        """``d = G^T u`` of every row: (N, 6) -> (N, K, 4)."""
        U = np.atleast_2d(U)
        if "_G_flat" not in self.__dict__:  # one (6, 4K) matrix: a single BLAS call per batch
            object.__setattr__(self, "_G_flat", self.G.transpose(1, 0, 2).reshape(6, -1))
        return (U @ self._G_flat).reshape(len(U), -1, 4)

    def row_terms(self, U: np.ndarray):
        """Row values ``p_{W_ij}`` (N, K) and each row's largest friction piece (N, K) int."""
        return kernels.rows_many(*self.packed, _directions(U))

    def _normal_wrenches(self) -> np.ndarray | None:
        """``f_max`` times each row's normal column (K, 6) when no row has friction (FPC, or
        mu = mu_s = 0): then every row's support wrench is that one, whatever the direction."""
        if "_normals" not in self.__dict__:
            normals = None if self.pieces.any() else self.f_max[:, None] * self.G[:, :, 0]
            object.__setattr__(self, "_normals", normals)
        return self._normals

    def row_values(self, U: np.ndarray) -> np.ndarray:
        """Support function of every row's extreme wrench set ``W_ij``: (N, 6) -> (N, K)."""
        return self.row_terms(U)[0]

    def slot_values(self, U: np.ndarray) -> np.ndarray:
        """``P_i(u)``, the support function of each slot (eq 36): (N, 6) -> (N, m)."""
        return kernels.slots_many(*self.packed, _directions(U))

    def support(self, U: np.ndarray) -> np.ndarray:
        """Support function ``p(u)`` of the whole set (eqs 26, 35): (N, 6) -> (N,)."""
        return kernels.support_many(*self.packed, _directions(U))

    def row_support(self, U: np.ndarray):
        """Each row's value ``p_{W_ij}(u)`` and support wrench (gradient): (N, K), (N, K, 6)."""
        return kernels.row_wrenches_many(*self.packed, _directions(U))

    def evaluate(self, U: np.ndarray):
        """``p(u)`` and a wrench attaining it (its gradient where unique): (N,), (N, 6)."""
        return kernels.evaluate_many(*self.packed, _directions(U))

    def support_points(self, U: np.ndarray) -> np.ndarray:
        """Wrenches of the set attaining ``p(u)``: (N, 6) -> (N, 6)."""
        return self.evaluate(U)[1]

    def support_point(self, u: np.ndarray) -> np.ndarray:
        """A wrench of the set attaining ``p(u)``: (6,) -> (6,)."""
        return self.evaluate(as_shaped(u, "u", (6,))[None])[1][0]


def pushing_subsets(
    P: np.ndarray, f_max: np.ndarray, margin: float = 0.0, ties: bool = False
) -> np.ndarray:
    """The contacts that push in each direction (eq 26's subset) from their support values ``P``
    (n, m): those with ``P_ik > -margin f_i``, the largest alone if none; (m, n) of 0 and 1.
    ``ties``: the largest is the first within :data:`~closure_nlp.base.ties.TIE` of it (contacts on
    one facet often tie for it exactly, and round-off picks one of them)."""
    mask = (P > -margin * f_max[None, :]).T.astype(float)
    none = ~mask.any(axis=0)
    if ties:
        largest = first_largest(P[none], float(f_max.max()))
    else:
        largest = np.argmax(P[none], axis=1)
    mask[largest, np.flatnonzero(none)] = 1.0
    return mask


def _directions(U) -> np.ndarray:
    """Directions as the kernels take them: (N, 6) (:func:`~closure_nlp.kernels.kernel_array`),
    one direction (6,) as a row."""
    U = np.asarray(U)
    return kernel_array(as_shaped(U[None] if U.ndim == 1 else U, "U", ("N", 6)))


def as_slots(value) -> WrenchSlots:
    """A :class:`WrenchSlots` from slots or a :class:`ContactSet` (``TypeError`` otherwise)."""
    if isinstance(value, WrenchSlots):
        return value
    if isinstance(value, ContactSet):
        return WrenchSlots.from_contacts(value)
    raise TypeError(f"slots: expected WrenchSlots or ContactSet, got {type(value).__name__}")
