"""The optimal one-to-one assignment (the linear sum assignment problem), numpy only.

It pairs anchors with true objects, boxes with boxes and one robot's objects with another's:
tens of rows at most, where scipy.optimize would put about 140 MB on the robot's disk for one
function. The method is the shortest augmenting path of Jonker and Volgenant as Crouse describes
it for rectangular matrices (scipy's ``linear_sum_assignment`` is the same method), so where
several assignments cost the same the same one is chosen.
"""

from __future__ import annotations

import numpy as np


def linear_sum_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns (each ascending by row) of the assignment of least total ``cost``: every
    row paired with one column when there are no more rows than columns, else every column with
    one row. ``cost`` is a 2-D array of finite numbers; anything else is a ``ValueError``."""
    c = np.asarray(cost, dtype=float)
    if c.ndim != 2:
        raise ValueError(f"cost must be a 2-D array, not {c.ndim}-D")
    if not np.isfinite(c).all():
        raise ValueError("cost must hold finite numbers only")
    transposed = c.shape[1] < c.shape[0]
    if transposed:
        c = c.T
    col4row = _assign(c)
    rows = np.arange(c.shape[0])
    if transposed:
        order = np.argsort(col4row)
        return col4row[order], rows[order]
    return rows, col4row


def _assign(cost: np.ndarray) -> np.ndarray:
    """The column of each row (rows <= columns): one shortest augmenting path per row, with the
    dual variables ``u``, ``v`` keeping the reduced costs non-negative."""
    nr, nc = cost.shape
    u = np.zeros(nr)
    v = np.zeros(nc)
    col4row = np.full(nr, -1)
    row4col = np.full(nc, -1)
    for start in range(nr):
        shortest = np.full(nc, np.inf)
        path = np.full(nc, -1)
        seen_rows = np.zeros(nr, dtype=bool)
        seen_cols = np.zeros(nc, dtype=bool)
        # The columns not yet reached, in the order the search takes them (as scipy's, so that
        # ties are broken alike).
        remaining = np.arange(nc - 1, -1, -1)
        reached = 0.0
        i, sink = start, -1
        while sink < 0:
            seen_rows[i] = True
            reduced = reached + cost[i, remaining] - u[i] - v[remaining]
            better = reduced < shortest[remaining]
            path[remaining[better]] = i
            shortest[remaining[better]] = reduced[better]
            values = shortest[remaining]
            lowest = values.min()
            ties = np.flatnonzero(values == lowest)
            free = ties[row4col[remaining[ties]] < 0]
            # A free column among the nearest ends the path: the last such, as scipy takes it.
            at = int(free[-1]) if free.size else int(ties[0])
            j = int(remaining[at])
            remaining[at] = remaining[-1]
            remaining = remaining[:-1]
            reached = float(lowest)
            seen_cols[j] = True
            if row4col[j] < 0:
                sink = j
            else:
                i = int(row4col[j])
        # The duals moved so that the path's reduced costs stay zero.
        u[start] += reached
        others = seen_rows.copy()
        others[start] = False
        u[others] += reached - shortest[col4row[others]]
        v[seen_cols] -= reached - shortest[seen_cols]
        # The path flipped: each of its rows takes the column before it.
        j = sink
        while True:
            i = int(path[j])
            row4col[j] = i
            col4row[i], j = j, int(col4row[i])
            if i == start:
                break
    return col4row
