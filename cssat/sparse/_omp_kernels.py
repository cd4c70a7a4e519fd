"""numba kernels of the Gram-path OMP (imported only when numba is installed; see ``_omp_numba``).

The helpers and ``_run`` are module-level functions so numba's on-disk cache finds them again in
a new process (a closure over another compiled function is re-keyed, and recompiled, every run).
"""

import numpy as np
from numba import njit, prange

#: LLVM fast-math flags of the kernels: no NaN, no infinity, no signed zero — and *not*
#: ``reassoc``/``contract``/``arcp``/``afn``, which let LLVM reorder sums and fuse multiply-adds
#: differently in each context a helper is compiled into: inlined into its caller when both are
#: compiled in one process (a cold cache), called as separate machine code when the caller comes
#: from numba's on-disk cache. With them, a run with a cold cache and the next one gave different
#: codes (sim1 at 64²: PSNR 25.0214 against 25.0036 dB). Without them every operation is IEEE's,
#: in the order written, whatever was inlined: same inputs, same bits, cache cold or warm.
_FAST = {"nnan", "ninf", "nsz"}


@njit(cache=True, nogil=True, fastmath=_FAST)
def _absmax(a):
    mx = a.dtype.type(0.0)
    for t in range(a.shape[0]):
        mx = max(mx, abs(a[t]))
    return mx


@njit(cache=True, nogil=True, fastmath=_FAST)
def _axpy1(a, g0, r0):
    for t in range(a.shape[0]):
        a[t] -= g0 * r0[t]


@njit(cache=True, nogil=True, fastmath=_FAST)
def _axpy4(a, g0, r0, g1, r1, g2, r2, g3, r3):
    for t in range(a.shape[0]):
        a[t] -= g0 * r0[t] + g1 * r1[t] + g2 * r2[t] + g3 * r3[t]


@njit(cache=True, nogil=True)
def _grow_square(a, cap):
    b = np.zeros((cap, cap), a.dtype)
    b[: a.shape[0], : a.shape[1]] = a
    return b


@njit(cache=True, nogil=True)
def _grow_rows(a, cap):
    b = np.empty((cap, a.shape[1]), a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True, nogil=True)
def _grow1(a, cap):
    b = np.zeros(cap, a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True, nogil=True)
def _run(G, a0, alpha, U, sel, idx, z, w, gamma, k, err, K, tol, use_tol, eps, floor, steps, slot, spread):
    """Continue one signal from ``k`` atoms; stop when done (status 0) or when the work
    arrays are full (status 1: grow them and call again). ``steps[slot]`` counts the atoms
    selected (read by a progress bar in another thread). ``U = Lᵀ`` holds the Cholesky factor
    by columns, so both substitutions read contiguous rows of ``U`` (the forward one
    column-oriented, each ``w[i]`` still summed in ascending order): strided reads of ``L`` made
    a large ``K`` cost ``K³/3`` cache misses."""
    n = a0.shape[0]
    dt = a0.dtype.type
    cap = idx.shape[0]
    while k < K and not (use_tol and err <= tol):
        # 1. the atom with the largest |correlation|
        best = _absmax(alpha)
        if best <= floor:
            break
        j = 0
        for t in range(n):
            if abs(alpha[t]) == best:
                j = t
                break
        for i in range(k):
            if idx[i] == j:
                return k, err, 0
        if k == cap:
            return k, err, 1
        # 2. Cholesky row: w = L⁻¹ G[I, j] (forward substitution by columns of L = rows of U)
        gj = G[j]
        ajj = gj[j]
        lkk2 = ajj
        for i in range(k):
            w[i] = gj[idx[i]]
        for t in range(k):
            w[t] = w[t] / U[t, t]
            lkk2 -= w[t] * w[t]
            wt = w[t]
            row = U[t]
            for i in range(t + 1, k):
                w[i] -= row[i] * wt
        if lkk2 <= dt(16.0) * eps * ajj:
            break
        s = a0[j]
        for i in range(k):
            U[i, k] = w[i]
            s -= w[i] * z[i]
        U[k, k] = np.sqrt(lkk2)
        z[k] = s / U[k, k]
        idx[k] = j
        for t in range(n):
            sel[k, t] = gj[t]
        err -= z[k] * z[k]
        k += 1
        steps[slot] += 1
        # 3. γ = L⁻ᵀ z by back substitution
        for i in range(k - 1, -1, -1):
            s = z[i]
            row = U[i]
            for t in range(i + 1, k):
                s -= row[t] * gamma[t]
            gamma[i] = s / U[i, i]
        if k == K or (use_tol and err <= tol):
            break
        # 4. α = Dᵀy − G_I γ: over all atoms here, or split among threads (one signal, `spread`)
        if spread:
            _update_spread(alpha, a0, gamma, sel, k)
        else:
            _update(alpha, a0, gamma, sel, k, 0, n)
    return k, err, 0


@njit(cache=True, nogil=True, fastmath=_FAST)
def _update(alpha, a0, gamma, sel, k, lo, hi):
    """``α[lo:hi] = a0[lo:hi] − Σᵢ γᵢ sel[i, lo:hi]``, four rows per pass over ``α``."""
    a = alpha[lo:hi]
    for t in range(hi - lo):
        a[t] = a0[lo + t]
    i = 0
    while i + 4 <= k:
        _axpy4(a, gamma[i], sel[i, lo:hi], gamma[i + 1], sel[i + 1, lo:hi],
               gamma[i + 2], sel[i + 2, lo:hi], gamma[i + 3], sel[i + 3, lo:hi])
        i += 4
    while i < k:
        _axpy1(a, gamma[i], sel[i, lo:hi])
        i += 1


@njit(parallel=True, cache=True, nogil=True, fastmath=_FAST)
def _update_spread(alpha, a0, gamma, sel, k):
    """:func:`_update` over all atoms in chunks run by numba's threads (for a lone signal, whose
    update streams ``k × n`` values each step; the result is the same, element by element)."""
    n = alpha.shape[0]
    size = 2048
    for c in prange((n + size - 1) // size):
        _update(alpha, a0, gamma, sel, k, c * size, min(n, (c + 1) * size))


def build(parallel: bool):
    """The batch kernel, parallel over signals or serial."""

    @njit(parallel=parallel, cache=True, nogil=True)
    def _batch(G, A0, ynorm2, K, tol, use_tol, out, n_iter, res, n_blocks, cap0, steps, spread):
        B, n = A0.shape
        is_parallel = parallel  # a closure cell: numba's cache keys the two variants apart  # noqa: F841
        dt = A0.dtype.type
        eps = dt(np.finfo(A0.dtype).eps)
        step = (B + n_blocks - 1) // n_blocks
        for blk in prange(n_blocks):
            # per-thread work arrays, grown by doubling up to K atoms
            cap = cap0
            U = np.zeros((cap, cap), A0.dtype)  # Lᵀ
            sel = np.empty((cap, n), A0.dtype)
            idx = np.zeros(cap, np.int64)
            z = np.zeros(cap, A0.dtype)
            w = np.zeros(cap, A0.dtype)
            gamma = np.zeros(cap, A0.dtype)
            alpha = np.empty(n, A0.dtype)
            for b in range(blk * step, min(B, (blk + 1) * step)):
                a0 = A0[b]
                floor = dt(0.0)
                for t in range(n):
                    alpha[t] = a0[t]
                    if abs(a0[t]) > floor:
                        floor = abs(a0[t])
                floor = dt(16.0) * eps * floor
                k, err, status = _run(G, a0, alpha, U, sel, idx, z, w, gamma, 0, ynorm2[b], K, tol, use_tol, eps,
                                      floor, steps, blk, spread)
                while status == 1:
                    cap = min(K, 2 * cap)
                    U = _grow_square(U, cap)
                    sel = _grow_rows(sel, cap)
                    idx = _grow1(idx, cap)
                    z = _grow1(z, cap)
                    w = _grow1(w, cap)
                    gamma = _grow1(gamma, cap)
                    k, err, status = _run(G, a0, alpha, U, sel, idx, z, w, gamma, k, err, K, tol, use_tol, eps,
                                          floor, steps, blk, spread)
                for i in range(k):
                    out[b, idx[i]] = gamma[i]
                n_iter[b] = k
                res[b] = err
    return _batch



def build_sparse_gram(parallel: bool):
    """The kernel ``sparse_gram(crow, col, val, n, n_blocks)``: ``DᵀD (n, n)`` of a sparse
    ``D (m, n)`` given as CSR (``crow``, ``col`` sorted within each row, ``val``), as
    ``Σᵢ dᵢ dᵢᵀ`` over the rows, ``nnzᵢ²`` products each. The rows of the result are split into
    ``n_blocks`` ranges, one per task, so no two tasks write one entry; each entry sums its
    products in row order, so ``G[a, b]`` and ``G[b, a]`` are equal bit for bit."""

    @njit(parallel=parallel, cache=True, nogil=True)
    def sparse_gram(crow, col, val, n, n_blocks):
        is_parallel = parallel  # a closure cell: numba's cache keys the two variants apart  # noqa: F841
        G = np.zeros((n, n), val.dtype)
        m = crow.shape[0] - 1
        step = (n + n_blocks - 1) // n_blocks
        for blk in prange(n_blocks):
            lo, hi = blk * step, min(n, (blk + 1) * step)
            for i in range(m):
                s, e = crow[i], crow[i + 1]
                first = s + np.searchsorted(col[s:e], lo)
                for p in range(first, e):
                    a = col[p]
                    if a >= hi:
                        break
                    va = val[p]
                    ga = G[a]
                    for q in range(s, e):
                        ga[col[q]] += va * val[q]
        return G
    return sparse_gram
