"""Batched orthogonal matching pursuit (Batch-OMP) as torch tensor operations.

Solves, for every signal ``y`` (a row of ``Y``), the paper's Eq. 5 or Eq. 6 greedily:

* sparsity-constrained (Eq. 5): ``min ‖y − Dγ‖₂²  s.t. ‖γ‖₀ ≤ K`` (``n_nonzero_coefs=K``);
* error-constrained (Eq. 6): ``min ‖γ‖₀  s.t. ‖y − Dγ‖₂² ≤ tol`` (``tol``, a *squared* norm, as in
  scikit-learn and SPAMS; OMPBox/KSVDBox take the norm itself). Both may be given: then ``K``
  caps the support of the error-constrained problem.

The semantics are scikit-learn's ``orthogonal_mp``: atoms (the columns of ``D``) need not be
normalised and the atom chosen at each step maximises ``|dⱼᵀ r|``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch
from torch import Tensor

__all__ = ["batch_omp", "gram_matrix", "omp_path_costs", "OMPInfo"]

_CAP0 = 64  # initial per-signal atom capacity of the work buffers (they double up to K)


class OMPInfo(NamedTuple):
    """Extra output of :func:`batch_omp` with ``return_info=True``.

    ``n_iter (B,)``: atoms selected per signal; ``residual_sq (B,)``: final ``‖y − Dγ‖₂²``
    (computed from the Cholesky factors, exact up to round-off); ``path``: ``"gram"`` or ``"nogram"``.
    """

    n_iter: Tensor
    residual_sq: Tensor
    path: str


#: Rates of the cost model of :func:`omp_path_costs`, measured on a 2-core AVX-512 CPU with 2
#: threads: dense products (GEMM/SYRK) reach ~70 G multiply-adds/s; streaming a matrix from
#: memory (a matrix-vector product, the Gram-row updates) ~5 G values/s (~20 GB/s of float32).
_GEMM_RATE = 70e9
_STREAM_RATE = 5e9
_GRAM_MAX_BYTES = 4 << 30  # never build a Gram matrix larger than this on "auto"


def omp_path_costs(m: int, n_atoms: int, n_signals: int, k: int, chunk: int = 256) -> dict[str, float]:
    """Estimated seconds of the two OMP paths, used to choose between them.

    * ``gram``: ``DᵀD`` (``m n²/2`` multiply-adds, :func:`gram_matrix`) and ``DᵀY`` (``B m n``), both
      compute-bound dense products; then per signal ``n k²/2`` for the correlation updates
      ``α = Dᵀy − G_I γ_I`` (Rubinstein, Zibulevsky & Elad 2008, Batch-OMP), which stream the
      selected Gram rows from memory.
    * ``nogram``: per step one product ``Dᵀr`` for each chunk of signals: ``B k m n`` multiply-adds,
      and one pass over ``D`` (``m n`` values) per step and chunk — memory-bound when few signals
      share a pass, e.g. one signal on a 13225 × 16384 dictionary with K = 2815 streams 2.4 TB
      (≈ 120 s here) where the Gram path needs a 3.5 TFLOP Gram (≈ 28 s) and 0.26 TB of row
      updates (≈ 35 s).

    The rates are :data:`_GEMM_RATE` and :data:`_STREAM_RATE`; only their ratio matters.
    """
    B = n_signals
    gram = (m * n_atoms * n_atoms / 2 + B * m * n_atoms) / _GEMM_RATE + B * n_atoms * k * k / 2 / _STREAM_RATE
    passes = k * math.ceil(B / max(1, chunk))
    nogram = max(B * k * m * n_atoms / _GEMM_RATE, passes * m * n_atoms / _STREAM_RATE)
    return {"gram": float(gram), "nogram": float(nogram)}


def batch_omp(
    D: Tensor,
    Y: Tensor,
    *,
    n_nonzero_coefs: int | None = None,
    tol: float | None = None,
    gram: Tensor | None = None,
    Dty: Tensor | None = None,
    precompute: bool | str = "auto",
    chunk_size: int | None = None,
    backend: str = "auto",
    return_info: bool = False,
) -> Tensor | tuple[Tensor, OMPInfo]:
    """Orthogonal matching pursuit for a batch of signals (Batch-OMP; no Python loop over signals).

    Parameters
    ----------
    D : (m, n_atoms) tensor
        Dictionary with atoms as columns (not assumed normalised). Its dtype (float32/float64) and
        device set those of the computation.
    Y : (B, m) or (m,) tensor
        Signals as rows.
    n_nonzero_coefs : int, optional
        ``K``, the maximum number of atoms per signal (Eq. 5); ``1 ≤ K ≤ n_atoms``. Steps beyond
        ``m`` atoms stop on linear dependence. If neither ``K`` nor ``tol`` is given,
        ``K = max(1, n_atoms // 10)`` as in scikit-learn.
    tol : float, optional
        Bound on the *squared* residual norm ``‖y − Dγ‖₂²`` (Eq. 6 with ``tol = ε²``).
    gram : (n_atoms, n_atoms) tensor, optional
        Precomputed ``DᵀD``; implies the Gram path.
    Dty : (B, n_atoms) or (n_atoms,) tensor, optional
        Precomputed ``DᵀY`` (rows ``Dᵀy``); used by the Gram path.
    precompute : "auto", True or False
        Path choice. ``"auto"`` picks the one with the smaller estimated time
        (:func:`omp_path_costs`): the **Gram path** (Batch-OMP) when many signals share ``D`` or
        ``K`` is large (one signal on a 13225 × 16384 dictionary with K = 2815: 63 s against
        ≈ 120 s for ``K`` memory-bound passes ``Dᵀr``), the **no-Gram path** for few signals and
        small ``K`` on a large dictionary, or when the Gram would exceed 4 GB.
    chunk_size : int, optional
        Signals processed together by the torch path. The default keeps each chunk's
        ``(chunk, K, n)`` work buffer near 8 MB on a CPU (cache) and 1 GB on a GPU.
    backend : "auto", "torch" or "numba"
        Who runs the Gram path. ``"torch"``: lockstep tensor operations on chunks of signals (any
        device). ``"numba"``: a compiled CPU kernel, one signal per thread at a time so its
        ``K × n`` working set stays in cache — several times faster on a CPU. ``"auto"`` takes
        numba for CPU tensors when it is installed. The no-Gram path always runs in torch (it is
        bound by the ``Dᵀr`` products, which BLAS already streams at memory speed).
    return_info : bool
        Also return an :class:`OMPInfo`.

    Returns
    -------
    (B, n_atoms) or (n_atoms,) tensor
        The sparse codes ``γ`` (same leading shape as ``Y``).

    Notes
    -----
    Each step selects ``j = argmax |α|`` with ``α = Dᵀr``, grows the Cholesky factor ``L`` of
    ``D_Iᵀ D_I`` by one row (``w = L⁻¹ D_Iᵀ dⱼ``, ``L_kk = √(‖dⱼ‖² − ‖w‖²)``) and
    ``z = L⁻¹ D_Iᵀ y`` by its last entry; then ``γ_I = L⁻ᵀ z``.

    * Gram path: ``D_Iᵀ dⱼ`` is read from ``G``, ``α = Dᵀy − G_I γ_I``, and the squared residual
      is ``‖y‖² − ‖z‖²`` (exact up to cancellation when it is tiny relative to ``‖y‖²``).
    * No-Gram path: ``D_I = Q Lᵀ`` with ``Q`` orthonormal, built by Gram–Schmidt
      (``w = Qᵀdⱼ``, ``q = (dⱼ − Q w)/L_kk``, ``zₖ = qᵀr``, ``r ← r − zₖ q``): no triangular solve
      until a signal finishes, the residual and its norm are exact, and each step costs one
      product ``Dᵀr`` plus ``2 m k``.

    A signal stops — cleanly, with the atoms it has — when

    * it has ``K`` atoms, or (``tol`` given) its squared residual is ``≤ tol``;
    * the best correlation is at round-off level (``≤ 16 ε max|Dᵀy|``) or names an atom
      already chosen (exact fit; a zero signal gets a zero code);
    * the chosen atom is linearly dependent on the chosen ones (``L_kk² ≤ 16 ε ‖dⱼ‖²``).
    """
    if D.ndim != 2:
        raise ValueError(f"D: expected a 2-D dictionary (m, n_atoms), got shape {tuple(D.shape)}")
    if not D.is_floating_point():
        raise TypeError(f"D: expected a float32 or float64 tensor, got {D.dtype}")
    m, n_atoms = D.shape
    squeeze = Y.ndim == 1
    Y2 = Y.reshape(1, -1) if squeeze else Y
    if Y2.ndim != 2 or Y2.shape[1] != m:
        raise ValueError(f"Y: expected shape (B, {m}) or ({m},) to match D (m={m}), got {tuple(Y.shape)}")
    Y2 = Y2.to(dtype=D.dtype, device=D.device)
    if not bool(torch.isfinite(Y2).all()):
        raise ValueError("Y: signals contain NaN or Inf")
    if tol is not None:
        tol = float(tol)
        if not math.isfinite(tol) or tol < 0:
            raise ValueError(f"tol: squared residual bound must be finite and >= 0, got {tol}")
    if n_nonzero_coefs is not None:
        if isinstance(n_nonzero_coefs, bool) or int(n_nonzero_coefs) != n_nonzero_coefs:
            raise ValueError(f"n_nonzero_coefs: expected an integer, got {n_nonzero_coefs!r}")
        n_nonzero_coefs = int(n_nonzero_coefs)
        if not 1 <= n_nonzero_coefs <= n_atoms:
            raise ValueError(
                f"n_nonzero_coefs: must be in [1, n_atoms={n_atoms}], got {n_nonzero_coefs}"
            )
    elif tol is None:
        n_nonzero_coefs = max(1, n_atoms // 10)
    K = min(n_nonzero_coefs if n_nonzero_coefs is not None else n_atoms, m, n_atoms)
    B = Y2.shape[0]

    if backend not in ("auto", "torch", "numba"):
        raise ValueError(f"backend: expected 'auto', 'torch' or 'numba', got {backend!r}")
    if precompute not in ("auto", True, False):
        raise ValueError(f"precompute: expected 'auto', True or False, got {precompute!r}")
    if gram is not None or (backend == "numba" and precompute == "auto"):
        use_gram = True
    elif precompute == "auto":
        # In error-constrained mode the final K is unknown; assume a quarter of the cap.
        k_est = K if tol is None else max(1, K // 4)
        costs = omp_path_costs(m, n_atoms, B, k_est)
        use_gram = costs["gram"] < costs["nogram"] and n_atoms * n_atoms * D.element_size() <= _GRAM_MAX_BYTES
    else:
        use_gram = bool(precompute)

    out = torch.zeros(B, n_atoms, dtype=D.dtype, device=D.device)
    n_iter = torch.zeros(B, dtype=torch.long, device=D.device)
    res_sq = torch.zeros(B, dtype=D.dtype, device=D.device)
    if B == 0:
        return _finish(out, n_iter, res_sq, squeeze, return_info, "gram" if use_gram else "nogram")

    if backend == "numba" and not use_gram:
        raise ValueError("backend: 'numba' runs the Gram path only; drop precompute=False or use backend='torch'")
    from cssat.sparse import _omp_numba

    use_numba = use_gram and D.device.type == "cpu" and (
        backend == "numba" or (backend == "auto" and _omp_numba.available())
    )
    if backend == "numba" and not _omp_numba.available():
        raise ImportError("backend: 'numba' needs the numba package (pip install numba)")
    width = n_atoms if use_gram else m
    if chunk_size is None:
        per_signal = min(K, _CAP0) * width * D.element_size()
        budget = (8 << 20) if D.device.type == "cpu" else (1 << 30)
        chunk_size = int(max(1, min(256 if D.device.type == "cpu" else 65536, budget // max(per_signal, 1))))
    chunk_size = max(1, int(chunk_size))

    if use_gram:
        G = gram.to(dtype=D.dtype, device=D.device) if gram is not None else gram_matrix(D)
        if tuple(G.shape) != (n_atoms, n_atoms):
            raise ValueError(f"gram: expected shape ({n_atoms}, {n_atoms}), got {tuple(G.shape)}")
        if Dty is not None:
            if Dty.numel() != B * n_atoms:
                raise ValueError(f"Dty: expected shape ({B}, {n_atoms}) = (signals, atoms), got {tuple(Dty.shape)}")
            A0 = Dty.reshape(B, n_atoms).to(dtype=D.dtype, device=D.device)
        else:
            A0 = Y2 @ D
        diag = torch.diagonal(G).clone()
        ynorm2 = (Y2 * Y2).sum(1)
        if use_numba:
            _omp_numba.omp_gram(
                G.contiguous().numpy(), A0.contiguous().numpy(), ynorm2.numpy(), K, tol,
                out.numpy(), n_iter.numpy(), res_sq.numpy(), torch.get_num_threads(), _CAP0,
            )
            return _finish(out, n_iter, res_sq, squeeze, return_info, "gram")
        for s in range(0, B, chunk_size):
            e = min(s + chunk_size, B)
            _omp_chunk(
                A0[s:e], ynorm2[s:e], None, G, None, diag, K, tol,
                out[s:e], n_iter[s:e], res_sq[s:e],
            )
    else:
        Dt = D.T  # (n_atoms, m): atom j is row j (contiguous when D is a transposed view)
        diag = torch.linalg.vector_norm(D, dim=0) ** 2
        for s in range(0, B, chunk_size):
            e = min(s + chunk_size, B)
            Yc = Y2[s:e]
            _omp_chunk(
                _correlate(Dt, Yc), (Yc * Yc).sum(1), Yc, None, Dt, diag, K, tol,
                out[s:e], n_iter[s:e], res_sq[s:e],
            )
    return _finish(out, n_iter, res_sq, squeeze, return_info, "gram" if use_gram else "nogram")


def gram_matrix(D: Tensor, block: int = 512) -> Tensor:
    """``DᵀD (n_atoms, n_atoms)``, exactly symmetric, computed block row by block row on and above
    the diagonal and mirrored: about half the multiply-adds of ``D.T @ D`` (like BLAS ``syrk``)."""
    n = D.shape[1]
    G = torch.empty(n, n, dtype=D.dtype, device=D.device)
    for i in range(0, n, block):
        G[i : i + block, i:] = D[:, i : i + block].T @ D[:, i:]
        G[i + block :, i : i + block] = G[i : i + block, i + block :].T
        d = G[i : i + block, i : i + block]  # make the diagonal block exactly symmetric too
        d.copy_(torch.triu(d) + torch.triu(d, 1).T)
    return G


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


def _correlate(Dt: Tensor, R: Tensor) -> Tensor:
    """``R Dᵀ`` as ``(B, n)`` for rows ``R (B, m)`` and ``Dt (n, m)``: one pass over the dictionary."""
    if R.shape[0] > 1:
        return (Dt @ R.T).T
    return _mv(Dt, R[0])[None]


def _finish(out, n_iter, res_sq, squeeze, return_info, path):
    if squeeze:
        out, n_iter, res_sq = out[0], n_iter[0], res_sq[0]
    if return_info:
        return out, OMPInfo(n_iter, res_sq.clamp_min(0), path)
    return out


def _omp_chunk(
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
    cap = min(K, _CAP0)  # buffers grow by doubling up to K atoms
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
        if bool(done.all()):
            break
        # 4. new correlations α = Dᵀr
        if gram_path:
            alpha = a0 - torch.bmm(gamma.transpose(1, 2), sel[:, : k + 1]).squeeze(1)
        else:
            alpha = _correlate(Dt, resid)
