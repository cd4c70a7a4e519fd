"""Sparse K-SVD: dictionary learning under the double-sparsity model (paper Eq. 19–21).

The trained dictionary is ``D = B A`` (Eq. 20): ``B (p, K₀)`` a fixed *separable* base dictionary
— the Kronecker product of small 1-D dictionaries, by default overcomplete DCTs — and ``A (K₀, L)``
a sparse matrix whose columns have at most ``T_dict`` non-zeros. Training alternates (Eq. 21):

1. **sparse coding** of every training block over ``D`` with :func:`~cssat.sparse.batch_omp`
   (error-constrained with a cap on the atoms, or sparsity-constrained). ``Dᵀx = Aᵀ(Bᵀx)`` and
   ``DᵀD = Aᵀ(BᵀB)A`` are formed through ``B``'s separability (``BᵀB = ⊗ BₐᵀBₐ``): nothing of
   size ``p × K₀`` is multiplied with the data;
2. **atom update**, one atom at a time in random order (Rubinstein, Zibulevsky & Elad 2010,
   Algorithm 1): with ``I`` the blocks that use atom ``j`` and ``g = Γ[I, j]``, the residual without
   the atom is ``E = X_I − Γ_I Dᵀ + g dⱼᵀ`` (never formed); ``aⱼ`` is the ``T_dict``-sparse code
   over ``B`` of ``Eᵀg`` (OMP), normalised so ``‖B aⱼ‖ = 1``; then ``Γ[I, j] = E dⱼ``.
   Atoms that no block uses are replaced by the worst-coded block; after each sweep atoms used by
   fewer than 4 blocks or nearly equal to another (``|dᵢᵀdⱼ| > μ``) are replaced likewise.

Plain (approximate) K-SVD is the special case ``B = I`` with dense atoms (:func:`ksvd`).

Signals are rows (``X (n, p)``), as everywhere in cssat.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import torch
from torch import Tensor

from cssat._checks import FieldError, FieldTypeError
from cssat._progress import progress_bar
from cssat.sparse.omp import batch_omp
from cssat.sparse.operators import LinearOperator
from cssat.sparse.transforms import KroneckerOperator, odct_matrix

__all__ = ["SparseDictionary", "KSVDInfo", "sparse_ksvd", "ksvd", "odct_base"]

_USE_THRESH = 4  # an atom used by fewer training blocks is replaced (KSVDSBox's cleardict)


class SparseDictionary(LinearOperator):
    """``D = B A`` (Eq. 20) as an operator from codes ``(n, L)`` to signals ``(n, p)``.

    ``B`` is a :class:`~cssat.sparse.KroneckerOperator` ``(p, K₀)``; ``A (K₀, L)`` is stored dense
    (it is small: ``K₀ × L``) but has at most ``T_dict`` non-zeros per column; it is the buffer
    :attr:`atoms` (``A`` itself is deepinv's name for the forward map, as on every operator).
    """

    def __init__(self, base: KroneckerOperator, A: Tensor):
        super().__init__()
        if A.ndim != 2 or A.shape[0] != base.n_in:
            raise FieldError("A", f"expected shape ({base.n_in}, n_atoms) for the base dictionary, got {tuple(A.shape)}")
        self.base = base
        self.register_buffer("atoms", A)
        self.n_out, self.n_in = base.n_out, int(A.shape[1])

    def forward(self, codes: Tensor) -> Tensor:
        """``D γ`` for rows ``codes (n, L)``; returns ``(n, p)``."""
        return self.base(codes @ self.atoms.to(codes).T)

    def adjoint(self, x: Tensor) -> Tensor:
        """``Dᵀ x = Aᵀ (Bᵀ x)`` for rows ``x (n, p)``; returns ``(n, L)``."""
        return self.base.adjoint(x) @ self.atoms.to(x)

    def matrix(self, dtype: torch.dtype | None = None, device: torch.device | str | None = None) -> Tensor:
        A = self.atoms.to(dtype=dtype or self.atoms.dtype, device=device)
        return self.base(A.T).T.contiguous()

    def gram(self) -> Tensor:
        """``DᵀD = Aᵀ (⊗ BₐᵀBₐ) A`` ``(L, L)``, through the separable base Gram."""
        return self.atoms.T @ _base_gram(self.base, self.atoms)


def odct_base(block: Sequence[int], atoms: Sequence[int] | None = None, dtype: torch.dtype = torch.float32) -> KroneckerOperator:
    """Separable overcomplete-DCT base dictionary ``B = ODCT(p₁, k₁) ⊗ ODCT(p₂, k₂) (⊗ …)``.

    ``atoms`` defaults to ``⌈1.25 pₐ⌉`` per axis: ``odctdict(8, 10)`` as in KSVDSBox's demo.
    """
    block = [int(b) for b in block]
    atoms = [math.ceil(1.25 * b) for b in block] if atoms is None else [int(a) for a in atoms]
    if len(atoms) != len(block):
        raise FieldError("base_atoms", f"expected {len(block)} sizes (one per block axis), got {atoms}")
    if any(a < b for a, b in zip(atoms, block)):
        raise FieldError("base_atoms", f"each axis needs at least as many atoms as the block size {block}, got {atoms}")
    return KroneckerOperator([odct_matrix(b, a, dtype=dtype) for b, a in zip(block, atoms)])


class KSVDInfo(NamedTuple):
    """Training history of :func:`sparse_ksvd`, one entry per iteration.

    ``rmse``: ``‖X − ΓDᵀ‖_F / √(n p)`` after the atom update; ``mean_atoms``: mean ``‖γᵢ‖₀`` of the
    sparse coding; ``replaced``: atoms replaced (unused, rarely used or near-duplicate).
    """

    rmse: list
    mean_atoms: list
    replaced: list


def _base_gram(base: KroneckerOperator, A: Tensor) -> Tensor:
    """``(BᵀB) A`` ``(K₀, L)`` applied axis by axis (``BᵀB = ⊗ BₐᵀBₐ`` is never formed)."""
    mats = [m.to(A) for m in base._mats(A)]
    grams = [m.T @ m for m in mats]
    return KroneckerOperator(grams)(A.T).T.contiguous()


def _check_signals(X: Tensor, p: int) -> None:
    if X.ndim != 2 or X.shape[1] != p:
        raise FieldError("X", f"expected training signals as rows (n, {p}), got shape {tuple(X.shape)}")
    if not X.is_floating_point():
        raise FieldTypeError("X", f"expected a float32 or float64 tensor, got {X.dtype}")
    if not bool(torch.isfinite(X).all()):
        raise FieldError("X", "training signals contain NaN or Inf")


def sparse_ksvd(
    X: Tensor,
    base: KroneckerOperator,
    *,
    n_atoms: int | None = None,
    atom_sparsity: int,
    tol: float | None = None,
    n_nonzero_coefs: int | None = None,
    n_iter: int = 10,
    init: str | Tensor = "identity",
    mu_thresh: float = 0.99,
    seed: int = 0,
    return_info: bool = False,
    progress: bool | None = None,
) -> SparseDictionary | tuple[SparseDictionary, KSVDInfo]:
    """Train a sparse dictionary ``D = B A`` on the rows of ``X`` (Eq. 21, sparse K-SVD).

    Parameters
    ----------
    X : (n, p) tensor
        Training blocks as rows (vectorised in C order, matching ``base``). Its dtype and device
        set those of the computation. The caller removes the block means if it wants to.
    base : KroneckerOperator (p, K₀)
        The separable base dictionary ``B`` with unit-norm columns (e.g. :func:`odct_base`).
    n_atoms : int, optional
        ``L``, atoms to train; default ``K₀``. Needs ``L ≤ n``.
    atom_sparsity : int
        ``T_dict``: non-zeros per column of ``A`` (``1 ≤ T_dict ≤ K₀``).
    tol : float, optional
        Error-constrained coding: bound on the *squared* residual ``‖x − Dγ‖²`` of each block
        (KSVDSBox's ``Edata²``; for white noise of std ``σ``, ``tol = p (gain σ)²``).
    n_nonzero_coefs : int, optional
        Sparsity-constrained coding with this many atoms per block, or the cap on the atoms when
        ``tol`` is given (default then ``p // 2``, as KSVDSBox's ``maxatoms``).
    n_iter : int
        Training iterations (coding + atom-update sweeps).
    init : "identity", "data" or (K₀, ≥L) tensor
        Initial ``A``: the first ``L`` columns of the identity (``L ≤ K₀``; KSVDSBox's demo), the
        ``T_dict``-sparse codes over ``B`` of ``L`` random non-zero training blocks, or a matrix.
    mu_thresh : float
        Atoms with ``|dᵢᵀdⱼ| > mu_thresh`` to another atom are replaced (``≥ 1`` disables).
    seed : int
        Seeds the atom order and the data initialisation: same inputs and seed ⇒ same dictionary.
    return_info : bool
        Also return a :class:`KSVDInfo`.
    progress : bool, optional
        A tqdm bar of the iterations, with the training RMSE (``None``: on a terminal, after a
        second; see :mod:`cssat._progress`).
    """
    if not isinstance(base, KroneckerOperator):
        raise FieldTypeError("base", "expected a KroneckerOperator (a separable base dictionary)")
    L, T, cap = _check_training(X, base, n_atoms, atom_sparsity, tol, n_nonzero_coefs, n_iter)
    n, p = X.shape
    coder = _AtomCoder(base.to(device=X.device), T, X.dtype, X.device)
    gen = torch.Generator().manual_seed(int(seed))
    A = _initial_atoms(init, X, L, coder, gen)

    info = KSVDInfo([], [], [])
    BtX = coder.base.adjoint(X)  # (n, K0): Bᵀx once; Dᵀx = Aᵀ(Bᵀx) every iteration
    bar = progress_bar(None, f"K-SVD ({L} atoms, {n} blocks)", progress, unit="iter", iterable=range(int(n_iter)))
    for _ in bar:
        # ---- sparse coding (all blocks at once) ----
        D = coder.Bm @ A  # (p, L)
        G = A.T @ _base_gram(coder.base, A)  # DᵀD through the separable BᵀB
        Gamma, oinfo = batch_omp(
            D, X, n_nonzero_coefs=cap, tol=tol, gram=G, Dty=BtX @ A, return_info=True, progress=False, check=False
        )
        info.mean_atoms.append(float(oinfo.n_iter.double().mean()))
        # per-block coding error: picks replacement blocks (the worst-coded not yet used)
        pool = _Replacements(X, oinfo.residual_sq.clone(), coder)
        replaced = _update_atoms(X, A, D, Gamma, pool, coder, gen)
        R = X - Gamma @ D.T
        err = (R * R).sum(1)
        info.rmse.append(float(torch.sqrt(err.sum() / (n * p))))
        bar.set_postfix(rmse=f"{info.rmse[-1]:.4g}", refresh=False)
        pool.residual = err
        n_clear = _clean_atoms(A, D, Gamma, replaced, pool, coder, mu_thresh)
        info.replaced.append(int(replaced.sum()) + n_clear)
    bar.close()

    out = SparseDictionary(coder.base, A)
    return (out, info) if return_info else out


def _check_training(X, base, n_atoms, atom_sparsity, tol, n_nonzero_coefs, n_iter) -> tuple[int, int, int]:
    """Validate :func:`sparse_ksvd`'s sizes; returns ``(L, T_dict, cap)`` (atoms, atom sparsity,
    the coding's atom cap)."""
    p, K0 = base.n_out, base.n_in
    _check_signals(X, p)
    n = X.shape[0]
    L = K0 if n_atoms is None else int(n_atoms)
    if L < 1:
        raise FieldError("n_atoms", f"must be >= 1, got {L}")
    if L > n:
        raise FieldError("n_atoms", f"{L} atoms need at least as many training signals, got {n}")
    T = int(atom_sparsity)
    if not 1 <= T <= K0:
        raise FieldError("atom_sparsity", f"must be in [1, K0={K0}], got {T}")
    if int(n_iter) < 0:
        raise FieldError("n_iter", f"must be >= 0, got {n_iter}")
    if tol is None and n_nonzero_coefs is None:
        raise FieldError("tol", "give the coding error bound tol, a sparsity, or both")
    if tol is not None and (not math.isfinite(float(tol)) or float(tol) < 0):
        raise FieldError("tol", f"must be finite and >= 0, got {tol}")
    cap = n_nonzero_coefs if n_nonzero_coefs is not None else max(1, p // 2)
    cap = int(min(cap, L))
    if cap < 1:
        raise FieldError("n_nonzero_coefs", f"must be >= 1, got {n_nonzero_coefs}")
    return L, T, cap


class _AtomCoder:
    """``T_dict``-sparse coding over the base ``B``: ``Bm (p, K₀)`` its matrix (small, for single
    vectors), ``baseG = BᵀB``; ``dense`` when ``B = I`` with dense atoms (plain K-SVD)."""

    def __init__(self, base: KroneckerOperator, T: int, dt: torch.dtype, dev: torch.device):
        p, K0 = base.n_out, base.n_in
        self.base, self.T = base, T
        self.Bm = base.matrix(dtype=dt, device=dev)
        norms = torch.linalg.vector_norm(self.Bm, dim=0)
        if bool(((norms - 1).abs() > 1e-2).any()):
            raise FieldError("base", "the base dictionary's atoms must have unit norm")
        self.baseG = _base_gram(base, torch.eye(K0, dtype=dt, device=dev))  # (K0, K0) = BᵀB
        self.dense = T >= K0 and K0 == p and bool(torch.allclose(self.Bm, torch.eye(p, dtype=dt, device=dev)))

    def atom(self, v: Tensor) -> Tensor:
        """``T``-sparse code over ``B`` of the vector ``v (p,)``, scaled so ``‖B a‖ = 1``."""
        if self.dense:
            a = v.clone()
        else:
            a = batch_omp(self.Bm, v, n_nonzero_coefs=self.T, gram=self.baseG, Dty=self.Bm.T @ v, progress=False,
                          check=False)
        nd = torch.linalg.vector_norm(self.Bm @ a)
        return a / nd if float(nd) > 0 else a

    def codes(self, Xi: Tensor) -> Tensor:
        """``T``-sparse codes ``(K₀, L)`` of the rows of ``Xi (L, p)`` (not normalised)."""
        if self.dense:
            return Xi.T.clone()
        return batch_omp(self.Bm, Xi, n_nonzero_coefs=self.T, gram=self.baseG, Dty=self.base.adjoint(Xi),
                         progress=False, check=False).T.contiguous()


def _initial_atoms(init, X: Tensor, L: int, coder: _AtomCoder, gen: torch.Generator) -> Tensor:
    """The initial ``A (K₀, L)`` (see :func:`sparse_ksvd`'s ``init``), columns scaled to ``‖B a‖ = 1``."""
    K0 = coder.base.n_in
    dt, dev = X.dtype, X.device
    if isinstance(init, Tensor):
        if init.ndim != 2 or init.shape[0] != K0 or init.shape[1] < L:
            raise FieldError("init", f"expected a ({K0}, >= {L}) matrix, got {tuple(init.shape)}")
        A = init[:, :L].to(dtype=dt, device=dev).clone()
    elif init == "identity":
        if L > K0:
            raise FieldError("init", f"'identity' needs n_atoms <= K0={K0}, got {L}; use init='data'")
        A = torch.eye(K0, L, dtype=dt, device=dev)
    elif init == "data":
        ok = torch.nonzero((X * X).sum(1) > 1e-6 * (X * X).sum(1).max().clamp_min(1e-300)).flatten().cpu()
        if ok.numel() < L:
            raise FieldError("init", f"'data' needs {L} non-zero training signals, found {ok.numel()}")
        pick = ok[torch.randperm(ok.numel(), generator=gen)[:L]].to(dev)
        A = coder.codes(X[pick])
    else:
        raise FieldError("init", f"expected 'identity', 'data' or a matrix, got {init!r}")
    dn = torch.linalg.vector_norm(coder.Bm @ A, dim=0)
    return A / torch.where(dn > 0, dn, torch.ones_like(dn))


class _Replacements:
    """The blocks that may replace an atom, worst-coded (largest ``residual``) first, each once
    per iteration."""

    def __init__(self, X: Tensor, residual: Tensor, coder: _AtomCoder):
        self.X, self.residual, self.coder = X, residual, coder
        self.available = torch.ones(X.shape[0], dtype=torch.bool, device=X.device)

    def any(self) -> bool:
        return bool(self.available.any())

    def take(self) -> Tensor:
        """The worst-coded block not yet used for a replacement, coded as a new atom."""
        r = torch.where(self.available, self.residual, torch.full_like(self.residual, -1.0))
        i = int(torch.argmax(r))
        self.available[i] = False
        return self.coder.atom(self.X[i])


def _update_atoms(X, A, D, Gamma, pool: _Replacements, coder: _AtomCoder, gen) -> Tensor:
    """The atom update, sequential in random order (in place on ``A``, ``D``, ``Gamma``); returns
    the mask ``(L,)`` of atoms that no block used, replaced by the worst-coded blocks."""
    L = A.shape[1]
    replaced = torch.zeros(L, dtype=torch.bool, device=X.device)
    for j in torch.randperm(L, generator=gen).tolist():
        users = torch.nonzero(Gamma[:, j]).flatten()
        if users.numel() == 0:
            a = pool.take()
            A[:, j] = a
            D[:, j] = coder.Bm @ a
            replaced[j] = True
            continue
        g = Gamma[users, j]
        GI = Gamma[users]  # (|I|, L)
        dj = D[:, j]
        Eg = X[users].T @ g - D @ (GI.T @ g) + dj * (g @ g)
        a = coder.atom(Eg)
        d = coder.Bm @ a
        if float(torch.linalg.vector_norm(d)) == 0:
            continue  # nothing to learn from: keep the atom
        Gamma[users, j] = X[users] @ d - GI @ (D.T @ d) + g * (dj @ d)
        A[:, j] = a
        D[:, j] = d
    return replaced


def _clean_atoms(A, D, Gamma, replaced, pool: _Replacements, coder: _AtomCoder, mu_thresh: float) -> int:
    """Replace rarely used or near-duplicate atoms (``|dᵢᵀdⱼ| > mu_thresh``) by the worst-coded
    blocks, in place; returns how many were replaced."""
    L = A.shape[1]
    usecount = (Gamma.abs() > 1e-7).sum(0)
    n_clear = 0
    if L <= 1:
        return 0
    Gd = D.T @ D
    Gd.fill_diagonal_(0)
    for j in range(L):
        if replaced[j]:
            continue
        if bool(usecount[j] < _USE_THRESH) or float(Gd[:, j].abs().max()) > mu_thresh:
            if not pool.any():
                break
            a = pool.take()
            A[:, j] = a
            D[:, j] = coder.Bm @ a
            col = D.T @ D[:, j]
            col[j] = 0
            Gd[:, j] = col
            Gd[j, :] = col
            n_clear += 1
    return n_clear


def ksvd(
    X: Tensor,
    n_atoms: int,
    *,
    tol: float | None = None,
    n_nonzero_coefs: int | None = None,
    n_iter: int = 10,
    mu_thresh: float = 0.99,
    seed: int = 0,
    return_info: bool = False,
    progress: bool | None = None,
) -> SparseDictionary | tuple[SparseDictionary, KSVDInfo]:
    """Plain (approximate) K-SVD: :func:`sparse_ksvd` with ``B = I`` and dense atoms, initialised
    from ``n_atoms`` random training blocks (normalised). Returns a :class:`SparseDictionary`
    whose ``atoms`` are the dictionary ``D (p, n_atoms)`` itself."""
    p = X.shape[-1] if X.ndim == 2 else -1
    _check_signals(X, p)
    eye = KroneckerOperator([torch.eye(p, dtype=X.dtype)])
    return sparse_ksvd(
        X, eye, n_atoms=n_atoms, atom_sparsity=p, tol=tol, n_nonzero_coefs=n_nonzero_coefs,
        n_iter=n_iter, init="data", mu_thresh=mu_thresh, seed=seed, return_info=return_info,
        progress=progress,
    )
