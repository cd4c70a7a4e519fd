"""The lockstep torch kernel of :func:`cssat.sparse.batch_omp` (both paths, any device).

Signals of a chunk advance together, one atom per step; the Gram path reads ``D_Iᵀ dⱼ`` from the
Gram matrix, the no-Gram path orthogonalises atoms against the selected ones (Gram–Schmidt) and
updates the residual. The stopping rules and the output are documented in :func:`batch_omp`.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import torch
from torch import Tensor

__all__ = ["omp_chunk", "correlate", "CAP0"]

CAP0 = 64  # initial per-signal atom capacity of the work buffers (they double up to K)

_POOL: dict[int, object] = {}


def _mv(A: Tensor, x: Tensor) -> Tensor:
    """``A @ x`` for a 2-D ``A`` (any strides) and a vector ``x``.

    torch runs a matrix-vector product on a single core; on a CPU a large one is split into row
    blocks run by ``torch.get_num_threads()`` threads (each output entry is the same dot product,
    up to the summation order BLAS picks for a block). Memory-bound: one pass over ``A``.
    """
    threads = torch.get_num_threads()
    if A.device.type != "cpu" or threads < 2 or A.numel() < (1 << 22):
        return torch.mv(A, x)

    pool = _POOL.get(threads)
    if pool is None:
        pool = _POOL[threads] = ThreadPoolExecutor(threads, thread_name_prefix="cssat-mv")
    out = torch.empty(A.shape[0], dtype=A.dtype)
    jobs = [
        pool.submit(torch.mv, part, x, out=o)
        for part, o in zip(torch.tensor_split(A, 2 * threads), torch.tensor_split(out, 2 * threads))
    ]
    for job in jobs:
        job.result()
    return out


def correlate(Dt: Tensor, R: Tensor) -> Tensor:
    """``R Dᵀ`` as ``(B, n)`` for rows ``R (B, m)`` and ``Dt (n, m)``: one pass over the dictionary."""
    if R.shape[0] > 1:
        return (Dt @ R.T).T
    return _mv(Dt, R[0])[None]



class _Chunk:
    """The lockstep state of one chunk of signals (``r`` live state rows, capacity ``cap`` atoms).

    ``rows (r,)``: each state row's chunk row; ``sel (r, cap, width)``: the selected Gram rows
    (Gram path) or orthonormal atoms ``q`` (no-Gram path); ``L (r, cap, cap)``: the Cholesky
    factor of ``D_Iᵀ D_I``; ``idx (r, cap)``: the atoms chosen; ``z (r, cap)``: ``L⁻¹ D_Iᵀ y``;
    ``a0``/``alpha (r, n)``: ``Dᵀy`` and the current correlations; ``err (r,)``: the squared
    residual; ``resid (r, m)``: the residual (no-Gram path); ``done (r,)``.
    """

    def __init__(self, alpha0, ynorm2, Y, width, K, tol, outputs):
        c = alpha0.shape[0]
        dev, dt = alpha0.device, alpha0.dtype
        self.eps = torch.finfo(dt).eps
        self.K, self.tol, self.width = K, tol, width
        self.out, self.n_iter_out, self.res_out = outputs
        self.rows = torch.arange(c, device=dev)
        self.cap = min(K, CAP0)  # buffers grow by doubling up to K atoms
        self.sel = torch.empty(c, self.cap, width, dtype=dt, device=dev)
        self.L = torch.zeros(c, self.cap, self.cap, dtype=dt, device=dev)
        self.idx = torch.zeros(c, self.cap, dtype=torch.long, device=dev)
        self.z = torch.zeros(c, self.cap, dtype=dt, device=dev)
        self.a0, self.alpha = alpha0, alpha0
        self.resid = Y.clone() if Y is not None else None
        self.err = ynorm2.clone()
        self.floor = 16 * self.eps * alpha0.abs().amax(1)  # a correlation at round-off level
        self.done = self.err <= tol if tol is not None else torch.zeros(c, dtype=torch.bool, device=dev)
        self.n_iter_out.zero_()
        self.res_out.copy_(ynorm2)

    def compact(self, live: Tensor) -> None:
        """Keep only the state rows in ``live`` (copying those rows only)."""
        keep = live.nonzero().squeeze(1)
        for name in ("rows", "sel", "L", "idx", "z", "a0", "err", "floor", "alpha", "done"):
            setattr(self, name, getattr(self, name)[keep])
        if self.resid is not None:
            self.resid = self.resid[keep]

    def grow(self, k: int) -> None:
        """Double the atom capacity (up to ``K``) when step ``k`` reaches it."""
        r, pad = len(self.rows), torch.nn.functional.pad
        self.cap = min(self.K, 2 * self.cap)
        self.sel = torch.cat([self.sel, self.sel.new_empty(r, self.cap - k, self.width)], 1)
        self.L = pad(self.L, (0, self.cap - k, 0, self.cap - k))
        self.idx = pad(self.idx, (0, self.cap - k))
        self.z = pad(self.z, (0, self.cap - k))

    def flush(self, mask: Tensor, kk: int, gamma: Tensor | None = None) -> None:
        """Write out the state rows in ``mask``, which keep their first ``kk`` atoms."""
        if kk == 0 or not bool(mask.any()):
            return
        w_rows = mask.nonzero().squeeze(1)
        if gamma is None:
            Lk = self.L[w_rows, :kk, :kk]
            g = torch.linalg.solve_triangular(Lk.transpose(1, 2), self.z[w_rows, :kk, None], upper=True)
        else:
            g = gamma[w_rows]
        r_out = self.rows[w_rows]
        self.out[r_out] = self.out[r_out].scatter(1, self.idx[w_rows, :kk], g.squeeze(2))
        self.res_out[r_out] = self.err[w_rows]
        self.n_iter_out[r_out] = kk


def _new_factor_row(st: _Chunk, k: int, j: Tensor, G: Tensor | None, Dt: Tensor | None, diag: Tensor):
    """Step 2: the new row ``w`` of the Cholesky factor for atom ``j`` and ``L_kk²``. Returns
    ``(g, w, v, lkk2)``: ``g`` the Gram row or atom, ``v`` the atom orthogonalised (no-Gram path)."""
    g = (G if G is not None else Dt).index_select(0, j)  # Gram column j (symmetric) or atom j, (r, width)
    ajj = diag[j]
    w = v = None
    if G is not None:
        if k > 0:  # w = L⁻¹ G[I, j]
            b = g.gather(1, st.idx[:, :k])
            w = torch.linalg.solve_triangular(st.L[:, :k, :k], b[:, :, None], upper=False).squeeze(2)
            lkk2 = ajj - (w * w).sum(1)
        else:
            lkk2 = ajj.clone()
    else:  # Gram–Schmidt against the orthonormal rows q of sel: w = Qᵀd, v = d − Q w
        v = g
        if k > 0 and len(st.rows) == 1:  # one signal: threaded matrix-vector products
            w = _mv(st.sel[0, :k], g[0])[None]
            v = g - _mv(st.sel[0, :k].T, w[0])[None]
        elif k > 0:
            w = torch.bmm(st.sel[:, :k], g[:, :, None]).squeeze(2)
            v = g - torch.bmm(w[:, None, :], st.sel[:, :k]).squeeze(1)
        lkk2 = (v * v).sum(1)
    return g, w, v, lkk2


def _append(st: _Chunk, k: int, j: Tensor, g: Tensor, w, v, lkk2: Tensor, ok: Tensor, gram_path: bool) -> None:
    """Grow ``L``, ``idx``, ``z`` by atom ``j`` for the rows in ``ok``; update ``err`` (and the residual)."""
    ar = torch.arange(len(st.rows), device=lkk2.device)
    lkk = torch.sqrt(torch.where(ok, lkk2, torch.ones_like(lkk2)))
    if k > 0:
        st.L[:, k, :k] = w * ok[:, None]
    st.L[:, k, k] = lkk
    st.idx[:, k] = j
    if gram_path:
        st.sel[:, k] = g
        zk = (st.a0[ar, j] - ((w * st.z[:, :k]).sum(1) if k > 0 else 0.0)) / lkk
    else:
        q = v / lkk[:, None]
        st.sel[:, k] = q
        zk = (q * st.resid).sum(1)  # qᵀr = qᵀy, computed on the residual for stability
    st.z[:, k] = torch.where(ok, zk, torch.zeros_like(zk))
    if gram_path:
        st.err = torch.where(ok, st.err - st.z[:, k] ** 2, st.err)
    else:
        st.resid = st.resid - st.z[:, k, None] * q
        st.err = torch.where(ok, (st.resid * st.resid).sum(1), st.err)  # exact, no cancellation


def omp_chunk(
    alpha0: Tensor,  # (c, n) Dᵀy
    ynorm2: Tensor,  # (c,)
    Y: Tensor | None,  # (c, m) signals (no-Gram path) or None
    G: Tensor | None,  # (n, n) Gram (Gram path) or None
    Dt: Tensor | None,  # (n, m) atoms as rows (no-Gram path) or None
    diag: Tensor,  # (n,) squared atom norms
    K: int,
    tol: float | None,
    out: Tensor,  # (c, n) written in place
    n_iter_out: Tensor,  # (c,)
    res_out: Tensor,  # (c,)
    bar=None,  # a tqdm bar of atoms selected, or None
) -> None:
    """OMP on one chunk of signals in lockstep.

    Rows that finish are written out at once; when fewer than 3/4 of the state rows are alive the
    state is compacted to the live rows (copying only those)."""
    gram_path = G is not None
    st = _Chunk(alpha0, ynorm2, Y, alpha0.shape[1] if gram_path else Dt.shape[1], K, tol,
                (out, n_iter_out, res_out))
    for k in range(K):
        live = ~st.done
        n_live = int(live.sum())
        if n_live == 0:
            break
        if n_live < 0.75 * len(st.rows):
            st.compact(live)
        if k == st.cap:
            st.grow(k)
        ar = torch.arange(len(st.rows), device=alpha0.device)

        # 1. the atom with the largest |correlation|; stop at round-off level or on a repeat
        j = st.alpha.abs().argmax(1)
        stop = st.alpha[ar, j].abs() <= st.floor
        if k > 0:
            stop |= (st.idx[:, :k] == j[:, None]).any(1)
        # 2. the new row of the Cholesky factor L of D_Iᵀ D_I (D_I = Q Lᵀ)
        g, w, v, lkk2 = _new_factor_row(st, k, j, G, Dt, diag)
        stop |= lkk2 <= 16 * st.eps * diag[j]  # linearly dependent atom
        stop &= ~st.done
        st.flush(stop, k)
        st.done = st.done | stop
        ok = ~st.done
        _append(st, k, j, g, w, v, lkk2, ok, gram_path)

        # 3. the stopping test; finished rows are written out (γ_I = L⁻ᵀ z)
        tol_ = st.tol
        finished = ok.clone() if k + 1 == K else ok & (st.err <= tol_) if tol_ is not None else torch.zeros_like(ok)
        if gram_path:
            gamma = torch.linalg.solve_triangular(
                st.L[:, : k + 1, : k + 1].transpose(1, 2), st.z[:, : k + 1, None], upper=True
            )  # (r, k+1, 1)
            st.flush(finished, k + 1, gamma)
        else:
            st.flush(finished, k + 1)
        st.done = st.done | finished
        if bar is not None:
            bar.update(n_live)
        if bool(st.done.all()):
            break
        # 4. new correlations α = Dᵀr
        if gram_path:
            st.alpha = st.a0 - torch.bmm(gamma.transpose(1, 2), st.sel[:, : k + 1]).squeeze(1)
        else:
            st.alpha = correlate(Dt, st.resid)
