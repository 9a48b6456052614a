"""Unique rows of integer arrays (mesh edges, rounded vertices) without `np.unique(..., axis=0)`.

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


def unique_rows(rows: np.ndarray):
    """``np.unique(rows, axis=0, return_index=True, return_inverse=True)`` for an (n, k) integer array, by a
    stable lexicographic sort of the columns (no structured view): the unique rows in the same order, the
    first occurrence of each and the inverse, (n,)."""
    rows = np.asarray(rows)
    if rows.ndim != 2 or rows.dtype.kind not in "iu":
        raise ValueError(f"unique_rows takes an (n, k) integer array, got {rows.dtype} of shape {rows.shape}")
    if not len(rows):
        return rows[:0].copy(), np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    starts = np.r_[True, (ordered[1:] != ordered[:-1]).any(axis=1)]
    group = np.cumsum(starts) - 1
    inverse = np.empty(len(rows), np.int64)
    inverse[order] = group
    return ordered[starts], order[starts].astype(np.int64), inverse
