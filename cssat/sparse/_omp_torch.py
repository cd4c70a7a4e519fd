"""The lockstep torch kernel of :func:`cssat.sparse.batch_omp` (both paths, any device).

Signals of a chunk advance together, one atom per step; the Gram path reads ``D_Iᵀ dⱼ`` from the
Gram matrix, the no-Gram path orthogonalises atoms against the selected ones (Gram–Schmidt) and
updates the residual. The stopping rules and the output are documented in :func:`batch_omp`.
"""

from __future__ import annotations

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
    from concurrent.futures import ThreadPoolExecutor

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
    c, n = alpha0.shape
    dev, dt = alpha0.device, alpha0.dtype
    eps = torch.finfo(dt).eps
    gram_path = G is not None
    width = n if gram_path else Dt.shape[1]

    rows = torch.arange(c, device=dev)  # chunk row of each state row
    cap = min(K, CAP0)  # buffers grow by doubling up to K atoms
    sel = torch.empty(c, cap, width, dtype=dt, device=dev)  # G rows (Gram) or orthonormal q (no-Gram)
    L = torch.zeros(c, cap, cap, dtype=dt, device=dev)
    idx = torch.zeros(c, cap, dtype=torch.long, device=dev)
    z = torch.zeros(c, cap, dtype=dt, device=dev)
    a0, alpha = alpha0, alpha0
    resid = Y.clone() if Y is not None else None  # the residual r (no-Gram path)
    err = ynorm2.clone()
    floor = 16 * eps * alpha0.abs().amax(1)  # a correlation at round-off level
    done = err <= tol if tol is not None else torch.zeros(c, dtype=torch.bool, device=dev)
    n_iter_out.zero_()
    res_out.copy_(ynorm2)

    def flush(mask: Tensor, kk: int, gamma: Tensor | None = None) -> None:
        """Write out the state rows in ``mask``, which keep their first ``kk`` atoms."""
        if kk == 0 or not bool(mask.any()):
            return
        w_rows = mask.nonzero().squeeze(1)
        if gamma is None:
            Lk = L[w_rows, :kk, :kk]
            g = torch.linalg.solve_triangular(Lk.transpose(1, 2), z[w_rows, :kk, None], upper=True)
        else:
            g = gamma[w_rows]
        r_out = rows[w_rows]
        out[r_out] = out[r_out].scatter(1, idx[w_rows, :kk], g.squeeze(2))
        res_out[r_out] = err[w_rows]
        n_iter_out[r_out] = kk

    for k in range(K):
        live = ~done
        n_live = int(live.sum())
        if n_live == 0:
            break
        if n_live < 0.75 * len(rows):
            keep = live.nonzero().squeeze(1)
            rows, sel, L, idx, z = rows[keep], sel[keep], L[keep], idx[keep], z[keep]
            a0, err, floor, alpha, done = a0[keep], err[keep], floor[keep], alpha[keep], done[keep]
            resid = resid[keep] if resid is not None else None
        r = len(rows)
        ar = torch.arange(r, device=dev)
        if k == cap:
            cap = min(K, 2 * cap)
            sel = torch.cat([sel, sel.new_empty(r, cap - k, width)], 1)
            L = torch.nn.functional.pad(L, (0, cap - k, 0, cap - k))
            idx = torch.nn.functional.pad(idx, (0, cap - k))
            z = torch.nn.functional.pad(z, (0, cap - k))

        # 1. the atom with the largest |correlation|; stop at round-off level or on a repeat
        j = alpha.abs().argmax(1)
        stop = alpha[ar, j].abs() <= floor
        if k > 0:
            stop |= (idx[:, :k] == j[:, None]).any(1)
        # 2. the new row of the Cholesky factor L of D_Iᵀ D_I (D_I = Q Lᵀ)
        src = G if gram_path else Dt
        g = src.index_select(0, j)  # Gram column j (symmetric) or atom j, (r, width)
        ajj = diag[j]
        w = None
        if gram_path:
            if k > 0:  # w = L⁻¹ G[I, j]
                b = g.gather(1, idx[:, :k])
                w = torch.linalg.solve_triangular(L[:, :k, :k], b[:, :, None], upper=False).squeeze(2)
                lkk2 = ajj - (w * w).sum(1)
            else:
                lkk2 = ajj.clone()
        else:  # Gram–Schmidt against the orthonormal rows q of sel: w = Qᵀd, v = d − Q w
            v = g
            if k > 0 and r == 1:  # one signal: threaded matrix-vector products
                w = _mv(sel[0, :k], g[0])[None]
                v = g - _mv(sel[0, :k].T, w[0])[None]
            elif k > 0:
                w = torch.bmm(sel[:, :k], g[:, :, None]).squeeze(2)
                v = g - torch.bmm(w[:, None, :], sel[:, :k]).squeeze(1)
            lkk2 = (v * v).sum(1)
        stop |= lkk2 <= 16 * eps * ajj  # linearly dependent atom
        stop &= ~done
        flush(stop, k)
        done = done | stop
        ok = ~done
        lkk = torch.sqrt(torch.where(ok, lkk2, torch.ones_like(lkk2)))
        if k > 0:
            L[:, k, :k] = w * ok[:, None]
        L[:, k, k] = lkk
        idx[:, k] = j
        if gram_path:
            sel[:, k] = g
            zk = (a0[ar, j] - ((w * z[:, :k]).sum(1) if k > 0 else 0.0)) / lkk
        else:
            q = v / lkk[:, None]
            sel[:, k] = q
            zk = (q * resid).sum(1)  # qᵀr = qᵀy, computed on the residual for stability
        z[:, k] = torch.where(ok, zk, torch.zeros_like(zk))
        if gram_path:
            err = torch.where(ok, err - z[:, k] ** 2, err)
        else:
            resid = resid - z[:, k, None] * q
            err = torch.where(ok, (resid * resid).sum(1), err)  # exact, no cancellation

        # 3. the stopping test; finished rows are written out (γ_I = L⁻ᵀ z)
        finished = ok.clone() if k + 1 == K else ok & (err <= tol) if tol is not None else torch.zeros_like(ok)
        if gram_path:
            gamma = torch.linalg.solve_triangular(
                L[:, : k + 1, : k + 1].transpose(1, 2), z[:, : k + 1, None], upper=True
            )  # (r, k+1, 1)
            flush(finished, k + 1, gamma)
        else:
            flush(finished, k + 1)
        done = done | finished
        if bar is not None:
            bar.update(n_live)
        if bool(done.all()):
            break
        # 4. new correlations α = Dᵀr
        if gram_path:
            alpha = a0 - torch.bmm(gamma.transpose(1, 2), sel[:, : k + 1]).squeeze(1)
        else:
            alpha = correlate(Dt, resid)
