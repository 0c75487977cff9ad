"""Union-find over labels, for the kernels that join pieces of a mask as they scan it in raster
order: the labelling of the regions (:mod:`.regions`) and the cutting of mixed regions into the
pieces of each colour model (:mod:`percept.perception.segmentation.split`)."""

from __future__ import annotations

import numpy as np

from percept.perception.compiled import jit


@jit
def find(parent: np.ndarray, i: int) -> int:
    """The root of ``i`` in the union-find forest ``parent``, halving the path to it."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@jit
def union(parent: np.ndarray, a: int, b: int) -> None:
    """Join the trees of ``a`` and ``b``, the smaller root the root of both."""
    a, b = find(parent, a), find(parent, b)
    if a < b:
        parent[b] = a
    elif b < a:
        parent[a] = b
