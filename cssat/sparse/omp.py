"""Batched orthogonal matching pursuit (Batch-OMP): the public function, which validates its
input and picks the path; the kernels live apart (as in scikit-learn's ``_omp.py``):

* ``_omp_torch.omp_chunk``: the lockstep torch kernel (any device) of both paths, Gram
  (Batch-OMP) and no-Gram (Gram–Schmidt on the residual);
* ``_omp_numba`` / ``_omp_kernels``: the compiled CPU kernel of the Gram path, one signal per thread.

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

from cssat._checks import FieldError
from cssat._progress import progress_bar
from cssat.sparse import _omp_numba
from cssat.sparse._io import numpy_io
from cssat.sparse._omp_checks import check_consistent, check_inputs, given, rescale
from cssat.sparse._omp_torch import correlate, omp_chunk

__all__ = ["batch_omp", "gram_matrix", "omp_path_costs", "OMPInfo"]

from cssat.sparse._omp_torch import CAP0 as _CAP0  # initial per-signal atom capacity of the work buffers


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
#: memory (a matrix-vector product, the Gram-row updates) ~5 G values/s (~20 GB/s of float32); the
#: numba kernel's Gram-row updates run at ~15 G values/s while a signal's selected rows
#: (``K × n`` values) stay in cache, up to ~16 MB.
_GEMM_RATE = 70e9
_STREAM_RATE = 5e9
_CACHE_RATE = 15e9
_CACHE_BYTES = 16 << 20
#: the torch no-Gram path runs at about half its modelled rate (per-step kernel launches, the
#: batched Gram–Schmidt products): measured 1.2–4.8× its model's time on six shapes (BENCHMARKS.md)
_NOGRAM_OVERHEAD = 2.0
_GRAM_MAX_BYTES = 4 << 30  # never build a Gram matrix larger than this on "auto"


def omp_path_costs(m: int, n_atoms: int, n_signals: int, k: int, chunk: int = 256, itemsize: int = 4) -> dict[str, float]:
    """Estimated seconds of the two OMP paths, used to choose between them.

    * ``gram``: ``DᵀD`` (``m n²/2`` multiply-adds, :func:`gram_matrix`) and ``DᵀY`` (``B m n``), both
      compute-bound dense products; then per signal ``n k²/2`` for the correlation updates
      ``α = Dᵀy − G_I γ_I`` (Rubinstein, Zibulevsky & Elad 2008, Batch-OMP), which read the
      selected Gram rows — from cache while ``k n`` values fit (:data:`_CACHE_BYTES`), else from
      memory.
    * ``nogram``: per step one product ``Dᵀr`` for each chunk of signals: ``B k m n`` multiply-adds,
      and one pass over ``D`` (``m n`` values) per step and chunk — memory-bound when few signals
      share a pass, e.g. one signal on a 13225 × 16384 dictionary with K = 2815 streams 2.4 TB
      (≈ 120 s here) where the Gram path needs a 3.5 TFLOP Gram (≈ 28 s) and 0.26 TB of row
      updates (≈ 35 s); plus the Gram–Schmidt of each new atom against the ``k`` before it
      (``B k² m`` values streamed), all times :data:`_NOGRAM_OVERHEAD`.

    Only the rates' ratios matter. They were fitted on a 2-core CPU; the choice can be forced
    with ``precompute=True/False``.
    """
    B = n_signals
    update_rate = _CACHE_RATE if k * n_atoms * itemsize <= _CACHE_BYTES else _STREAM_RATE
    gram = (m * n_atoms * n_atoms / 2 + B * m * n_atoms) / _GEMM_RATE + B * n_atoms * k * k / 2 / update_rate
    passes = k * math.ceil(B / max(1, chunk))
    nogram = _NOGRAM_OVERHEAD * (max(B * k * m * n_atoms / _GEMM_RATE, passes * m * n_atoms / _STREAM_RATE)
                                 + B * k * k * m / _STREAM_RATE)
    return {"gram": float(gram), "nogram": float(nogram)}


@numpy_io
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
    progress: bool | None = None,
    check: bool = True,
) -> Tensor | tuple[Tensor, OMPInfo]:
    """Orthogonal matching pursuit for a batch of signals (Batch-OMP; no Python loop over signals).

    Parameters
    ----------
    D : (m, n_atoms) tensor
        Dictionary with atoms as columns (not assumed normalised). Its dtype (float32/float64) and
        device set those of the computation.
    Y : (B, m) or (m,) tensor
        Signals as rows. ``D`` and ``Y`` may be numpy arrays (the codes come back as numpy);
        integer input is promoted to the default float dtype; float16 is refused (the Cholesky
        updates need float32 at least); NaN or Inf in ``D`` or ``Y`` is refused on every path.
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
    progress : bool, optional
        A tqdm bar of the atoms selected (up to ``B K``), on either path: ``None`` shows it on a
        terminal once the call has run a second, ``True`` always, ``False`` never.
    check : bool
        Verify a given ``gram`` against ``D`` (its diagonal and largest column) and ``Dty``
        against ``Y`` (its first row), ``O(m n)``; callers that formed them from ``D`` and ``Y``
        themselves (K-SVD, thousands of small calls) pass ``False``. NaN, Inf and shapes are
        checked always.

    Returns
    -------
    (B, n_atoms) or (n_atoms,) tensor
        The sparse codes ``γ`` (same leading shape as ``Y``).

    Inputs whose largest entry is far from 1 (beyond 2^±20) are scaled by powers of two (exact)
    before the Gram and the correlations are formed, and the codes scaled back: the Gram cannot
    overflow or underflow (float32 dictionaries of entries 1e19 or 1e-30 work as those near 1).

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
    D, Y2, squeeze, K, tol = check_inputs(D, Y, n_nonzero_coefs, tol)
    D, Y2, gram, Dty, tol, scale = rescale(D, Y2, gram, Dty, tol)
    use_gram = _choose_path(D, Y2.shape[0], K, tol, gram, precompute, backend)
    out, n_iter, res_sq = _solve(D, Y2, K, tol, gram, Dty, use_gram, backend, chunk_size, progress, check)
    return _finish(out, n_iter, res_sq, squeeze, return_info, "gram" if use_gram else "nogram", scale)


def _solve(D, Y2, K, tol, gram, Dty, use_gram, backend, chunk_size, progress, check):
    """``(codes (B, n_atoms), atoms per signal (B,), squared residuals (B,))`` by the chosen path."""
    B, n_atoms = Y2.shape[0], D.shape[1]
    out = torch.zeros(B, n_atoms, dtype=D.dtype, device=D.device)
    n_iter = torch.zeros(B, dtype=torch.long, device=D.device)
    res_sq = torch.zeros(B, dtype=D.dtype, device=D.device)
    if B == 0:
        return out, n_iter, res_sq
    use_numba, chunk_size = _kernel_settings(D, K, use_gram, backend, chunk_size)

    path = "gram" if use_gram else "nogram"
    with progress_bar(B * K, f"OMP ({path}, {B} signal{'s' if B != 1 else ''}, K={K})", progress, unit="atom") as bar:
        state = (out, n_iter, res_sq, bar)
        if use_gram:
            _run_gram(D, Y2, K, tol, gram, Dty, use_numba, chunk_size, state, check)
        else:
            _run_nogram(D, Y2, K, tol, chunk_size, state)
    return out, n_iter, res_sq


def _choose_path(D, B, K, tol, gram, precompute, backend) -> bool:
    """True for the Gram path: forced by ``gram``/``precompute``/``backend="numba"``, else the
    cheaper one by :func:`omp_path_costs` (and never a Gram over :data:`_GRAM_MAX_BYTES`)."""
    m, n_atoms = D.shape
    if backend not in ("auto", "torch", "numba"):
        raise FieldError("backend", f"expected 'auto', 'torch' or 'numba', got {backend!r}")
    if precompute not in ("auto", True, False):
        raise FieldError("precompute", f"expected 'auto', True or False, got {precompute!r}")
    if gram is not None or (backend == "numba" and precompute == "auto"):
        return True
    if precompute == "auto":
        # In error-constrained mode the final K is unknown; assume a quarter of the cap.
        k_est = K if tol is None else max(1, K // 4)
        costs = omp_path_costs(m, n_atoms, B, k_est, itemsize=D.element_size())
        return costs["gram"] < costs["nogram"] and n_atoms * n_atoms * D.element_size() <= _GRAM_MAX_BYTES
    return bool(precompute)


def _kernel_settings(D, K, use_gram, backend, chunk_size) -> tuple[bool, int]:
    """Whether the numba kernel runs the Gram path, and the torch path's chunk of signals: its
    ``(chunk, K, width)`` work buffer near 8 MB on a CPU (cache), 1 GB on a GPU."""
    if backend == "numba" and not use_gram:
        raise FieldError("backend", "'numba' runs the Gram path only; drop precompute=False or use backend='torch'")
    use_numba = use_gram and D.device.type == "cpu" and (
        backend == "numba" or (backend == "auto" and _omp_numba.available())
    )
    if backend == "numba" and not _omp_numba.available():
        raise ImportError("backend: 'numba' needs the numba package (pip install numba)")
    if chunk_size is None:
        m, n_atoms = D.shape
        per_signal = min(K, _CAP0) * (n_atoms if use_gram else m) * D.element_size()
        budget = (8 << 20) if D.device.type == "cpu" else (1 << 30)
        chunk_size = int(max(1, min(256 if D.device.type == "cpu" else 65536, budget // max(per_signal, 1))))
    return use_numba, max(1, int(chunk_size))


def _run_gram(D, Y2, K, tol, gram, Dty, use_numba, chunk_size, state, check=True) -> None:
    """The Gram path (Batch-OMP) into ``state = (out, n_iter, res_sq, bar)``, by the numba kernel
    (one signal per thread) or the torch kernel (chunks of ``chunk_size`` signals)."""
    out, n_iter, res_sq, bar = state
    B, n_atoms = out.shape
    G = given(gram, "gram", (n_atoms, n_atoms), D) if gram is not None else gram_matrix(D)
    if gram is None and not bool(torch.isfinite(torch.diagonal(G)).all()):
        raise FieldError("D", "its Gram matrix DᵀD overflows this dtype; use float64")
    if Dty is not None:
        A0 = given(Dty, "Dty", (B, n_atoms), D)
    else:
        A0 = Y2 @ D
    if check and (gram is not None or Dty is not None):
        check_consistent(D, Y2, G if gram is not None else None, A0 if Dty is not None else None)
    diag = torch.diagonal(G).clone()
    ynorm2 = (Y2 * Y2).sum(1)
    if use_numba:
        _omp_numba.omp_gram(
            G.contiguous().numpy(), A0.contiguous().numpy(), ynorm2.numpy(), K, tol,
            out.numpy(), n_iter.numpy(), res_sq.numpy(), torch.get_num_threads(), _CAP0, bar,
        )
        return
    for s in range(0, B, chunk_size):
        e = min(s + chunk_size, B)
        omp_chunk(
            A0[s:e], ynorm2[s:e], None, G, None, diag, K, tol,
            out[s:e], n_iter[s:e], res_sq[s:e], bar,
        )


def _run_nogram(D, Y2, K, tol, chunk_size, state) -> None:
    """The no-Gram path (Gram–Schmidt on the residual, torch) into ``state``, chunk by chunk."""
    out, n_iter, res_sq, bar = state
    Dt = D.T  # (n_atoms, m): atom j is row j (contiguous when D is a transposed view)
    diag = torch.linalg.vector_norm(D, dim=0) ** 2
    for s in range(0, Y2.shape[0], chunk_size):
        e = min(s + chunk_size, Y2.shape[0])
        Yc = Y2[s:e]
        omp_chunk(
            correlate(Dt, Yc), (Yc * Yc).sum(1), Yc, None, Dt, diag, K, tol,
            out[s:e], n_iter[s:e], res_sq[s:e], bar,
        )


#: the sparse Gram kernel's rate (scattered multiply-adds per second, 2 threads) and the dense
#: Gram size (multiply-adds) below which the dense product is always used: there the saving is
#: under a second, and the dense result — what cssat returned before the sparse kernel — is kept
_SCATTER_RATE = 0.05e9
_SPARSE_GRAM_MIN = 7e10


def gram_matrix(D: Tensor, block: int = 512, sparse: bool | str = "auto") -> Tensor:
    """``DᵀD (n_atoms, n_atoms)``, exactly symmetric.

    Dense: block row by block row on and above the diagonal, mirrored — about half the
    multiply-adds of ``D.T @ D`` (like BLAS ``syrk``), ``m n²/2``. Sparse (CPU, numba): the sum of
    the rows' outer products over their non-zeros, ``Σᵢ nnzᵢ²`` — e.g. the dictionary ``Âᵀ``
    of the sparse reference-satellite estimate (Eq. 30), 13108 rows with ≤ 100 non-zeros over
    16384 atoms: 0.13 G products against 1.76 T. ``sparse="auto"`` takes the sparse kernel when
    its estimated time is below the dense product's and the dense one would cost over a second
    (:data:`_SPARSE_GRAM_MIN`); ``True``/``False`` force it.
    """
    if sparse not in ("auto", True, False):
        raise FieldError("sparse", f"expected 'auto', True or False, got {sparse!r}")
    m, n = D.shape
    dense_work = m * n * n / 2  # multiply-adds of the dense product
    if sparse is not False and D.device.type == "cpu":
        if sparse is True or (dense_work >= _SPARSE_GRAM_MIN and _omp_numba.available()):
            mask = D != 0
            nnz = mask.sum(1)
            if sparse is True or float((nnz.double() ** 2).sum()) / _SCATTER_RATE < dense_work / _GEMM_RATE:
                return _sparse_gram(D, mask, nnz)
            del mask
    G = torch.empty(n, n, dtype=D.dtype, device=D.device)
    for i in range(0, n, block):
        G[i : i + block, i:] = D[:, i : i + block].T @ D[:, i:]
        G[i + block :, i : i + block] = G[i : i + block, i + block :].T
        d = G[i : i + block, i : i + block]  # make the diagonal block exactly symmetric too
        d.copy_(torch.triu(d) + torch.triu(d, 1).T)
    return G


def _sparse_gram(D: Tensor, mask: Tensor, nnz: Tensor) -> Tensor:
    """``DᵀD`` by the numba kernel from ``D``'s non-zeros (``mask``, ``nnz`` per row), built into
    CSR by hand: ``nonzero()`` lists them row by row, columns ascending."""
    if not _omp_numba.available():
        raise ImportError("sparse: the sparse Gram needs the numba package (pip install numba)")
    crow = torch.zeros(D.shape[0] + 1, dtype=torch.int64)
    torch.cumsum(nnz, 0, out=crow[1:])
    G = _omp_numba.sparse_gram(crow.numpy(), mask.nonzero()[:, 1].contiguous().numpy(), D[mask].numpy(),
                               D.shape[1], torch.get_num_threads())
    return torch.from_numpy(G)


def _finish(out, n_iter, res_sq, squeeze, return_info, path, scale=(1.0, 1.0)):
    s, t = scale
    if s != 1.0 or t != 1.0:  # back to the caller's scale: γ = γ' t / s, ‖r‖² = ‖r'‖² t²
        out.mul_(t / s)
        res_sq.mul_(t * t)
    if squeeze:
        out, n_iter, res_sq = out[0], n_iter[0], res_sq[0]
    if return_info:
        return out, OMPInfo(n_iter, res_sq.clamp_min(0), path)
    return out
