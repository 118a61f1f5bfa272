"""Cells of the unit sphere as boxes on the faces of the cube ``max |x_k| = 1`` (a direction
``u`` is the box point ``x = u / max |u_k|``): the branch and bound's starting cells, and a
symmetric set's reduced range of them."""

from __future__ import annotations

from functools import lru_cache

import numpy as np


def face_cells(splits: int, ranges=None):
    """The cube's faces within ``ranges`` (6, 2) of the coordinates (all of ``[-1, 1]`` when
    omitted), each cut into boxes: ``2^splits`` along every free coordinate of non-zero width.
    A face ``x_k = +-1`` is kept when ``+-1`` lies in coordinate ``k``'s range.

    Returns
    -------
    axis : (N,) int
    sign : (N,) float
    lo, hi : (N, 5) float
        The boxes of the five free coordinates.
    """
    if ranges is None:  # the whole sphere's: built once per size (0.5 ms of numpy each time)
        return tuple(a.copy() for a in _whole_sphere(splits))
    return _face_cells(splits, np.asarray(ranges, dtype=float))


@lru_cache(maxsize=4)
def _whole_sphere(splits: int):
    return _face_cells(splits, np.tile([-1.0, 1.0], (6, 1)))


def _face_cells(splits: int, ranges: np.ndarray):
    n = 2**splits
    axes, signs, los, his = [], [], [], []
    for k in range(6):
        free = [j for j in range(6) if j != k]
        cuts = [n if ranges[j, 1] > ranges[j, 0] else 1 for j in free]  # none across zero width
        pieces = [np.linspace(*ranges[j], c + 1) for j, c in zip(free, cuts)]
        grid = (
            np.array(np.meshgrid(*[np.arange(len(e) - 1) for e in pieces], indexing="ij"))
            .reshape(5, -1)
            .T
        )
        lo = np.column_stack([pieces[j][grid[:, j]] for j in range(5)])
        hi = np.column_stack([pieces[j][grid[:, j] + 1] for j in range(5)])
        for sign in (1.0, -1.0):
            if ranges[k, 0] <= sign <= ranges[k, 1]:
                axes.append(np.full(len(grid), k, dtype=np.int64))
                signs.append(np.full(len(grid), sign))
                los.append(lo)
                his.append(hi)
    return np.concatenate(axes), np.concatenate(signs), np.concatenate(los), np.concatenate(his)
