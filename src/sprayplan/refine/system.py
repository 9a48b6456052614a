"""The speed tuning's sparse system (``refine.tuning``): its products, the dead band's residuals and
Jacobian.

The system is the film rows ``(deposit_mm * 1000)[rows][:, cols] / tol`` and a smoothness row per pair of
neighbouring waypoints (``System``); ``_residuals`` gives ``least_squares`` the residual function through the
dead band and its Jacobian. Why a small system and a large one are handled two ways: ``System``'s docstring
and docs/ARCHITECTURE.md (issue 17, session 19).
"""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import numpy as np
from numba import njit
from scipy import sparse
from scipy.sparse.linalg import LinearOperator

#: The deposit matrix is in mm; the tuning works in um.
UM_PER_MM = 1000.0

#: The film rows of the tuning's products are cut into this many pieces of about equal entries, whatever the
#: number of threads: the transposed product adds the pieces' sums in their order, so the answer is the same
#: on one thread as on several.
PRODUCT_PIECES = 4
#: Matrices with fewer entries than this are one piece, their products on the calling thread: a small
#: matrix's product takes less than handing pieces to threads (the demo roof's LSMR makes thousands of them).
THREADED_ENTRIES = 8_000_000


class System:
    """The tuning's sparse system in tolerances: the film rows ``(deposit_mm * 1000)[rows][:, cols] / tol``
    (``cols`` where ``position >= 0``, in that order), then a smoothness row ``(-scale, scale)`` on the
    columns ``pair_first + (0, 1)`` of each pair of neighbouring waypoints; entries that are 0 left out.

    A small system (fewer entries than ``THREADED_ENTRIES``) is read from the deposit matrix in place: its
    products and the dead band's Jacobian (:meth:`operator`: a CSR copy with the film rows inside the band
    emptied, which ``least_squares`` scales and multiplies itself) are computed from the matrix's own arrays
    with scipy's values and summation order. A large one is copied once (``matrix``: every entry ``(a *
    1000) * (1 / tol)``, as scipy's scaling, slicing and ``/ tol`` made it), and its products, and those of
    the Jacobian (a ``LinearOperator`` over the same matrix with the rows' flags), run in compiled loops on
    ``workers`` threads (within :meth:`threads`) over ``PRODUCT_PIECES`` pieces of the rows fixed by the
    matrix alone, so that the answers do not depend on the number of threads. Why two ways: a small
    system's LSMR makes hundreds of products per Jacobian (the demo roof: 6,000 in a tuning), fastest on a
    compact copy; a large one's makes a few (the car body: about 8), and copying 18 million entries per
    Jacobian, with ``least_squares``' own copies of it, cost more than the products. ``csr`` and ``kept`` give
    the system as a CSR matrix.
    """

    def __init__(self, deposit_mm, rows, position, n_cols, inv_tol, pair_first, scale, workers: int = 1):
        self.deposit = deposit_mm.tocsr()
        self.rows = np.asarray(rows, np.int64)
        self.position = np.asarray(position, np.int64)
        self.inv_tol, self.scale = float(inv_tol), float(scale)
        self.pair_first = np.asarray(pair_first, np.int64)
        self.n_fit = len(self.rows)
        self.shape = (self.n_fit + len(self.pair_first), int(n_cols))
        self.workers = max(int(workers), 1)
        self.pool = None
        # a large system is copied once (its products on threads); a small one is read from the deposit
        # matrix in place, its Jacobians copies of the rows kept (``kept``)
        d = self.deposit
        entries = int((d.indptr[self.rows + 1] - d.indptr[self.rows]).sum()) + 2 * len(self.pair_first)
        self.large = entries >= THREADED_ENTRIES
        self.matrix = self.csr() if self.large else None
        self._whole = _Products(self.matrix, self, np.ones(self.shape[0], np.bool_)) if self.large else None

    @contextmanager
    def threads(self):
        """A context in which a large system's products run on ``workers`` threads (one pool for all of them)."""
        if self.workers < 2 or not self.large:
            yield
            return
        with ThreadPoolExecutor(max_workers=self.workers) as executor:
            self.pool = executor
            try:
                yield
            finally:
                self.pool = None

    def matvec(self, x) -> np.ndarray:
        """The system times ``x``: the film rows, then the smoothness rows."""
        x = np.asarray(x, float)
        if self.large:
            return self._whole.matvec(x)
        out = np.empty(self.shape[0])
        out[: self.n_fit] = self.fit_matvec(x)
        first = self.pair_first
        if self.scale != 0.0:
            out[self.n_fit :] = (0.0 + (-self.scale) * x[first]) + self.scale * x[first + 1]
        else:
            out[self.n_fit :] = 0.0
        return out

    def fit_matvec(self, x) -> np.ndarray:
        """The film rows times ``x``."""
        x = np.asarray(x, float)
        if self.large:
            return self._whole.matvec(x)[: self.n_fit]
        d = self.deposit
        return _system_matvec(d.indptr, d.indices, d.data, self.rows, self.position, UM_PER_MM, self.inv_tol, x)

    def operator(self, keep_fit) -> LinearOperator | sparse.csr_matrix:
        """The system with the film rows where ``keep_fit`` (one flag a film row) is False emptied, as a
        linear map: below ``THREADED_ENTRIES`` a CSR copy of the rows kept, which ``least_squares`` scales and
        multiplies itself (a small system's LSMR makes hundreds of products per Jacobian, fastest on a compact
        copy: the tuning as it was before the threads, bit for bit), above it a ``LinearOperator`` whose
        products run on threads over the matrix itself with the rows' flags (there LSMR makes a few products
        per Jacobian, and a copy and ``least_squares``' own copies of it cost more than they save)."""
        keep = np.ones(self.shape[0], np.bool_)
        keep[: self.n_fit] = keep_fit[: self.n_fit]
        if not self.large:
            return self.kept(keep)
        products = _Products(self.matrix, self, keep)

        def matmat(xs):
            return np.column_stack([products.matvec(xs[:, j]) for j in range(xs.shape[1])])

        return LinearOperator(
            self.shape,
            matvec=lambda x: products.matvec(np.asarray(np.ravel(x), float)),
            rmatvec=lambda u: products.rmatvec(np.asarray(np.ravel(u), float)),
            matmat=matmat,
            dtype=float,
        )

    def kept(self, outside: np.ndarray) -> sparse.csr_matrix:
        """The system with the rows where ``outside`` is False emptied, as a CSR matrix of its own."""
        d = self.deposit
        data, indices, indptr = _system_kept(
            d.indptr, d.indices, d.data, self.rows, self.position, UM_PER_MM, self.inv_tol, self.pair_first,
            self.scale, outside,
        )  # fmt: skip
        return sparse.csr_matrix((data, indices, indptr), shape=self.shape)

    def csr(self) -> sparse.csr_matrix:
        """The whole system as a CSR matrix."""
        return self.kept(np.ones(self.shape[0], bool))


class _Products:
    """A CSR matrix's products with vectors, over pieces of its rows (``System``'s rule), on the system's
    threads when it has them. The kernels read the indices as unsigned (of the same width): numba then does
    not check them for negative values, which halves a product's time."""

    def __init__(self, matrix: sparse.csr_matrix, system: System, keep: np.ndarray):
        self.keep = keep
        unsigned = np.uint32 if matrix.indices.dtype == np.int32 else np.uint64
        indptr = matrix.indptr.astype(matrix.indices.dtype, copy=False).view(unsigned)
        self.arrays = (indptr, matrix.indices.view(unsigned), matrix.data)
        self.shape = matrix.shape
        self.system = system
        entries = matrix.indptr[1:]
        total = int(entries[-1]) if len(entries) else 0
        pieces = PRODUCT_PIECES if total >= THREADED_ENTRIES else 1
        cuts = np.searchsorted(entries, np.arange(1, pieces) * (total / pieces))
        bounds = np.unique(np.r_[0, cuts, self.shape[0]])
        self.spans = list(itertools.pairwise(bounds))

    def _each(self, work) -> list:
        pool = self.system.pool
        if pool is None or len(self.spans) < 2:
            return [work(lo, hi) for lo, hi in self.spans]
        return list(pool.map(lambda span: work(*span), self.spans))

    def matvec(self, x) -> np.ndarray:
        out = np.empty(self.shape[0])
        arrays, keep = self.arrays, self.keep
        self._each(lambda lo, hi: _rows_matvec(*arrays, keep, x, lo, hi, out))
        return out

    def rmatvec(self, u) -> np.ndarray:
        """Each piece summed into a vector of its own, the pieces then added in order."""
        arrays, keep, n_cols = self.arrays, self.keep, self.shape[1]
        parts = self._each(lambda lo, hi: _rows_rmatvec(*arrays, keep, u, lo, hi, n_cols))
        out = parts[0] if parts else np.zeros(n_cols)
        for part in parts[1:]:
            out += part
        return out


@njit(cache=True, nogil=True)
def _rows_matvec(indptr, indices, data, keep, x, lo, hi, out):
    """``out[lo:hi]``: the rows ``lo..hi`` of a CSR matrix times ``x``, each summed in order; 0 where ``keep``
    is False."""
    for i in range(lo, hi):
        total = 0.0
        if keep[i]:
            for k in range(indptr[i], indptr[i + 1]):
                total += data[k] * x[indices[k]]
        out[i] = total


@njit(cache=True, nogil=True)
def _rows_rmatvec(indptr, indices, data, keep, u, lo, hi, n_cols):
    """The rows ``lo..hi`` of a CSR matrix (those where ``keep``) transposed, times ``u[lo:hi]``: a vector of
    ``n_cols``."""
    out = np.zeros(n_cols)
    for i in range(lo, hi):
        weight = u[i]
        if keep[i] and weight != 0.0:
            for k in range(indptr[i], indptr[i + 1]):
                out[indices[k]] += data[k] * weight
    return out


@njit(cache=True, nogil=True)
def _system_matvec(indptr, indices, data, rows, position, factor, inv_tol, x):
    """The film rows of ``System`` times ``x``, read from the deposit matrix in place, each row summed in
    order (as scipy's CSR product of the system sums it)."""
    out = np.empty(len(rows))
    for i in range(len(rows)):
        r = rows[i]
        total = 0.0
        for k in range(indptr[r], indptr[r + 1]):
            column = position[indices[k]]
            value = (data[k] * factor) * inv_tol
            if column >= 0 and value != 0.0:
                total += value * x[column]
        out[i] = total
    return out


@njit(cache=True, nogil=True)
def _system_kept(indptr, indices, data, rows, position, factor, inv_tol, pair_first, scale, keep):
    n_fit = len(rows)
    most = 2 * len(pair_first)  # room for every kept entry, allocated once (pages past the end stay untouched)
    for i in range(n_fit):
        if keep[i]:
            most += indptr[rows[i] + 1] - indptr[rows[i]]
    out_indptr = np.zeros(n_fit + len(pair_first) + 1, indices.dtype)
    out_indices = np.empty(most, indices.dtype)
    out_data = np.empty(most, np.float64)
    at = 0
    for i in range(n_fit):
        if keep[i]:
            r = rows[i]
            for k in range(indptr[r], indptr[r + 1]):
                column = position[indices[k]]
                value = (data[k] * factor) * inv_tol
                if column >= 0 and value != 0.0:
                    out_indices[at] = column
                    out_data[at] = value
                    at += 1
        out_indptr[i + 1] = at
    for j in range(len(pair_first)):
        if scale != 0.0 and keep[n_fit + j]:
            out_indices[at] = pair_first[j]
            out_data[at] = -scale
            out_indices[at + 1] = pair_first[j] + 1
            out_data[at + 1] = scale
            at += 2
        out_indptr[n_fit + j + 1] = at
    return out_data[:at], out_indices[:at], out_indptr


def _residuals(system: System, target_vec: np.ndarray, band: float):
    """The tuning's residual function and its Jacobian: ``system @ x - target_vec``, the film rows (in
    tolerances) through the dead band ``d(u) = sign(u) max(|u| - band, 0)``, whose derivative is 1 outside
    the band and 0 inside: the Jacobian is ``diags(slope) @ system``, the system with its rows inside the band
    emptied (``System.operator``, a ``LinearOperator``)."""
    n_fit = system.n_fit
    # which film rows are outside the dead band at the last residual's point: the solver asks for the
    # Jacobian at the point whose residual it has just computed, so the Jacobian reuses them (the same rows as
    # computing the misfit again; kept as flags, a byte a row)
    last: dict = {"x": None, "outside": None}

    def residual(x):
        r = system.matvec(x) - target_vec
        if band > 0:
            f = r[:n_fit]
            last["x"], last["outside"] = np.array(x, dtype=float), np.abs(f) > band
            r[:n_fit] = np.sign(f) * np.maximum(np.abs(f) - band, 0.0)
        return r

    if band <= 0:
        whole = system.operator(np.ones(n_fit, np.bool_))
        return residual, lambda x: whole

    def jacobian(x):
        if last["x"] is not None and np.array_equal(last["x"], x):
            outside = last["outside"]
        else:
            outside = np.abs(system.fit_matvec(x) - target_vec[:n_fit]) > band
        return system.operator(outside)

    return residual, jacobian
