"""Unique rows of an (n, 2) array of non-negative indices (mesh edges), through one int64 key a row.

``np.unique(pairs, axis=0)`` sorts rows as structured values, many times slower than sorting one integer a
row; the key ``a * (max + 1) + b`` sorts in the same (lexicographic) order, so the results are the same.
"""

from __future__ import annotations

import numpy as np


def unique_pairs(pairs: np.ndarray, return_inverse: bool = False, return_counts: bool = False):
    """``np.unique(pairs, axis=0, return_inverse=..., return_counts=...)`` for (n, 2) non-negative integers.

    Returns the unique rows ((k, 2) int64, in lexicographic order), then the inverse ((n,) int64) and the
    counts ((k,) int64) when asked for, as ``np.unique`` does (a tuple when more than one)."""
    pairs = np.asarray(pairs).reshape(-1, 2).astype(np.int64, copy=False)
    if len(pairs) and pairs.min() < 0:
        raise ValueError("unique_pairs takes non-negative indices")
    base = int(pairs.max()) + 1 if len(pairs) else 1
    if base > 3_037_000_499:  # base**2 would overflow int64: the slow way
        found = np.unique(pairs, axis=0, return_inverse=return_inverse, return_counts=return_counts)
    else:
        key = pairs[:, 0] * base + pairs[:, 1]
        found = np.unique(key, return_inverse=return_inverse, return_counts=return_counts)
        keys = found[0] if isinstance(found, tuple) else found
        rows = np.column_stack([keys // base, keys % base])
        found = (rows, *found[1:]) if isinstance(found, tuple) else rows
    if isinstance(found, tuple):
        return tuple([found[0]] + [np.asarray(f).reshape(-1).astype(np.int64) for f in found[1:]])
    return found
