"""Sparse-KSVD denoising of an image (2-D) or a stack of images (3-D) (paper Eq. 16–21, Fig. 7).

The noisy image is cut into overlapping blocks (Fig. 7); a sparse dictionary ``D = B A`` is
trained on them with :func:`~cssat.sparse.sparse_ksvd` (error-constrained coding at the noise
level); every block is then coded over ``D`` to that error, and the coded blocks are averaged back
into the image. The defaults are KSVDSBox's documented demo values (``ksvdsdenoisedemo``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, FieldTypeError
from cssat.sparse.ksvd import KSVDInfo, SparseDictionary, odct_base, sparse_ksvd
from cssat.sparse.omp import batch_omp
from cssat.sparse.patches import _norm, accumulate_patches, extract_patches, patch_positions

__all__ = ["ksvd_denoise", "estimate_sigma", "check_settings", "DenoiseInfo", "DEMO_DEFAULTS"]

#: KSVDSBox ``ksvdsdenoisedemo`` parameters (Rubinstein 2009), per dimensionality: block edge,
#: ``T_dict``, noise gain, training blocks, iterations and the step between the denoised blocks.
#: The trained atoms default to the base dictionary's size: ``odctdict(8, 10)`` per axis, so 100
#: in 2-D and 1000 in 3-D (:func:`~cssat.sparse.odct_base`).
DEMO_DEFAULTS: dict[int, dict[str, Any]] = {
    2: {"block": 8, "atom_sparsity": 6, "gain": 1.15, "n_train": 30000, "n_iter": 15, "step": 1},
    3: {"block": 8, "atom_sparsity": 16, "gain": 1.04, "n_train": 80000, "n_iter": 15, "step": 2},
}


@dataclass
class DenoiseInfo:
    """What :func:`ksvd_denoise` used and learned."""

    sigma: float  #: noise std used (given or estimated), in the image's units
    sigma_estimated: bool
    dictionary: SparseDictionary  #: the trained ``D = B A``
    training: KSVDInfo  #: per-iteration training history
    block_size: tuple[int, ...]
    step: tuple[int, ...]
    n_train: int  #: training blocks used
    mean_atoms: float  #: mean atoms per denoised block


def estimate_sigma(x: Tensor | np.ndarray) -> float:
    """Noise std of an image ``(H, W)`` or a stack ``(k, H, W)`` from its finest Haar wavelet
    detail: ``σ̂ = median(|HH|) / 0.6745`` (Donoho & Johnstone's robust MAD estimator, as
    scikit-image's ``estimate_sigma`` with a Haar wavelet). For a stack, the root mean square of
    the per-slice estimates (the noise power a 3-D block sees)."""
    x = torch.as_tensor(x)
    if x.ndim not in (2, 3):
        raise FieldError("x", f"expected an image (H, W) or a stack (k, H, W), got shape {tuple(x.shape)}")
    if x.shape[-1] < 2 or x.shape[-2] < 2:
        raise FieldError("x", f"needs at least 2×2 pixels to estimate the noise, got shape {tuple(x.shape)}")
    x = x.double()
    s = x if x.ndim == 3 else x[None]
    H, W = (s.shape[1] // 2) * 2, (s.shape[2] // 2) * 2
    s = s[:, :H, :W]
    hh = (s[:, 0::2, 0::2] - s[:, 0::2, 1::2] - s[:, 1::2, 0::2] + s[:, 1::2, 1::2]) / 2
    per_slice = hh.abs().flatten(1).median(dim=1).values / 0.6744897501960817
    return float(torch.sqrt((per_slice**2).mean()))


def _tuple(value, nd: int, name: str) -> tuple[int, ...]:
    if isinstance(value, bool):
        raise FieldError(name, f"expected an integer or {nd} integers, got {value!r}")
    return _norm(value, nd, name)


def ksvd_denoise(
    image_or_volume: Tensor | np.ndarray,
    sigma: float | None = None,
    *,
    block_size: int | Sequence[int] | None = None,
    step: int | Sequence[int] | None = None,
    n_atoms: int | None = None,
    base_atoms: Sequence[int] | None = None,
    atom_sparsity: int | None = None,
    gain: float | None = None,
    n_train: int | None = None,
    n_iter: int | None = None,
    max_atoms: int | None = None,
    lam: float = 0.0,
    mu_thresh: float = 0.99,
    seed: int = 0,
    return_info: bool = False,
    progress: bool | None = None,
) -> Tensor | np.ndarray | tuple[Tensor | np.ndarray, DenoiseInfo]:
    """Denoise an image ``(n, n)`` in 2-D or a stack ``(k, n, n)`` in 3-D by sparse K-SVD.

    Parameters
    ----------
    image_or_volume : (H, W) or (k, H, W) tensor or array
        2-D: an image, blocks ``p × p``. 3-D: ``k`` images of one scene stacked on the first axis
        (the paper stacks 9 reconstructions), cubes ``min(p, k) × p × p``; a stack of one image
        ``(1, H, W)`` is denoised in 2-D and keeps its axis. Float tensors keep
        their dtype and device; other input is computed in float32. A numpy input gives a numpy
        output.
    sigma : float, optional
        Noise standard deviation in the image's units (``> 0``). ``None``: estimated from the data
        (:func:`estimate_sigma`), since the noise of a CS reconstruction is not known in advance.
    block_size, step : int or per-axis ints
        Block edge (default 8) and the distance between denoised blocks (2-D: 1, 3-D: 2). Training
        uses all blocks at step 1, or ``n_train`` of them evenly spread.
    n_atoms, base_atoms, atom_sparsity : int
        Trained atoms ``L`` (default: the base dictionary's size, 100 in 2-D, 1000 in 3-D, or the
        number of blocks if the image has fewer), 1-D
        ODCT atoms per axis (default ``⌈1.25 p⌉``, i.e. 10 for 8) and ``T_dict`` (6 / 16).
    gain : float
        Target coding error ``ε = √p · gain · σ`` per block (KSVDSBox's ``Edata``): 1.15 / 1.04.
    n_train, n_iter : int
        Training blocks (30000 / 80000) and sparse K-SVD iterations (15).
    max_atoms : int, optional
        Cap on the atoms per block (default ``p / 2``).
    lam : float
        Weight of the noisy input in the average: ``x̂ = (λ x + Σ blocks) / (λ + count)``
        (0 = pure block average, the demo's value).
    mu_thresh, seed
        Passed to :func:`sparse_ksvd`. Same input and seed ⇒ same output.
    return_info : bool
        Also return a :class:`DenoiseInfo`.
    progress : bool, optional
        tqdm bars of the training iterations and of the coding of every block (``None``: on a
        terminal, for a stage that runs more than a second).
    """
    is_numpy = not isinstance(image_or_volume, Tensor)
    x = torch.as_tensor(np.asarray(image_or_volume) if is_numpy else image_or_volume)
    if x.ndim not in (2, 3):
        raise FieldError(
            "image_or_volume", f"expected a 2-D image (H, W) or a 3-D stack (k, H, W), got shape {tuple(x.shape)}"
        )
    if x.is_complex():
        raise FieldTypeError("image_or_volume", f"expected a real image, got {x.dtype}; denoise the real and "
                                                "imaginary parts (or the magnitude) separately")
    if not x.is_floating_point():
        x = x.to(torch.float32)
    if not bool(torch.isfinite(x).all()):
        raise FieldError("image_or_volume", "contains NaN or Inf")
    if x.ndim == 3 and x.shape[0] == 1:  # a stack of one image: its 2-D denoising, axis kept
        res = ksvd_denoise(x[0], sigma, block_size=block_size, step=step, n_atoms=n_atoms, base_atoms=base_atoms,
                           atom_sparsity=atom_sparsity, gain=gain, n_train=n_train, n_iter=n_iter, max_atoms=max_atoms,
                           lam=lam, mu_thresh=mu_thresh, seed=seed, return_info=return_info, progress=progress)
        out, info = res if return_info else (res, None)
        out = out[None]
        if is_numpy:
            out = out.cpu().numpy() if isinstance(out, Tensor) else out
        return (out, info) if return_info else out
    st = _settings(x, sigma, block_size, step, n_atoms, base_atoms, atom_sparsity, gain, n_train, n_iter, max_atoms, lam)

    dictionary, history = _train(x, st, mu_thresh, seed, progress)
    out, oinfo = _denoise_blocks(x, dictionary, st, lam, progress)

    if is_numpy:
        out = out.cpu().numpy()
    if not return_info:
        return out
    info = DenoiseInfo(
        sigma=st.sigma, sigma_estimated=st.estimated, dictionary=dictionary, training=history,
        block_size=st.block, step=st.step, n_train=int(min(st.n_train, st.n_blocks)),
        mean_atoms=float(oinfo.n_iter.double().mean()),
    )
    return out, info


def check_settings(shape: Sequence[int], **settings: Any) -> None:
    """Check :func:`ksvd_denoise`'s ``settings`` for an input of ``shape`` — block and step sizes,
    atoms, sparsity, training blocks — before any work (a FieldError naming the setting)."""
    shape = tuple(int(s) for s in shape)
    if len(shape) == 3 and shape[0] == 1:
        shape = shape[1:]
    if len(shape) not in (2, 3):
        raise FieldError("image_or_volume", f"expected a 2-D image (H, W) or a 3-D stack (k, H, W), got shape {shape}")
    kw = {k: settings.get(k) for k in ("block_size", "step", "n_atoms", "base_atoms", "atom_sparsity", "gain",
                                        "n_train", "n_iter", "max_atoms")}
    st = _settings(torch.zeros(shape, dtype=torch.float32, device="meta"), 1.0, lam=settings.get("lam") or 0.0, **kw)
    if min(st.n_train, st.n_blocks) < st.L:
        raise FieldError("n_atoms", f"{st.L} atoms need at least as many training blocks; the image gives "
                                    f"{min(st.n_train, st.n_blocks)} blocks of {st.block} (use a smaller block_size or n_atoms)")
    if not 1 <= st.T <= st.base.n_in:
        raise FieldError("atom_sparsity", f"must be in [1, {st.base.n_in}] (the base dictionary's atoms), got {st.T}")


@dataclass
class _Settings:
    """:func:`ksvd_denoise`'s settings with the demo defaults filled in and checked."""

    block: tuple[int, ...]
    step: tuple[int, ...]
    sigma: float
    estimated: bool
    base: Any  # the KroneckerOperator B
    n_blocks: int  # blocks at step 1
    L: int
    T: int
    n_train: int
    n_iter: int
    cap: int
    tol: float  # ε² with ε = √p · gain · σ


def _settings(x, sigma, block_size=None, step=None, n_atoms=None, base_atoms=None, atom_sparsity=None, gain=None,
              n_train=None, n_iter=None, max_atoms=None, lam=0.0) -> _Settings:
    nd = x.ndim
    demo = DEMO_DEFAULTS[nd]
    if block_size is None:
        block = tuple(min(demo["block"], s) for s in x.shape)
        if any(b < demo["block"] for b in block[-2:]):
            raise FieldError("block_size", f"the default block {demo['block']} is larger than the image {tuple(x.shape)}")
    else:
        block = _tuple(block_size, nd, "block_size")
    if any(b > s for b, s in zip(block, x.shape)):
        raise FieldError("block_size", f"block {block} is larger than the {'image' if nd == 2 else 'stack'} {tuple(x.shape)}")
    stp = _tuple(demo["step"] if step is None else step, nd, "step")
    stp = tuple(min(s, b) for s, b in zip(stp, block)) if step is None else stp
    p = math.prod(block)

    est = sigma is None
    if est:
        sigma = estimate_sigma(x)
    else:
        sigma = float(sigma)
        if not math.isfinite(sigma) or sigma <= 0:
            raise FieldError("sigma", f"noise std must be finite and > 0 (or None to estimate it), got {sigma}")
    gain = float(demo["gain"] if gain is None else gain)
    if not math.isfinite(gain) or gain <= 0:
        raise FieldError("gain", f"must be finite and > 0, got {gain}")
    if float(lam) < 0 or not math.isfinite(float(lam)):
        raise FieldError("lam", f"must be finite and >= 0, got {lam}")
    base = odct_base(block, base_atoms, dtype=x.dtype)
    n_blocks = math.prod(len(q) for q in patch_positions(x.shape, block, 1))
    # default: the base dictionary's size, fewer on an image too small to train that many atoms
    L = min(base.n_in, n_blocks) if n_atoms is None else int(n_atoms)
    T = min(demo["atom_sparsity"], base.n_in) if atom_sparsity is None else int(atom_sparsity)
    n_train = demo["n_train"] if n_train is None else int(n_train)
    n_iter = demo["n_iter"] if n_iter is None else int(n_iter)
    cap = min(max(1, p // 2), L) if max_atoms is None else int(max_atoms)
    if not 1 <= cap <= L:
        raise FieldError("max_atoms", f"must be in [1, n_atoms={L}], got {cap}")
    if n_train < L:
        raise FieldError("n_train", f"must be at least n_atoms={L}, got {n_train}")
    if L < 1:
        raise FieldError("n_atoms", f"must be >= 1, got {L}")
    return _Settings(block, stp, sigma, est, base, n_blocks, L, T, n_train, n_iter, cap, p * (gain * sigma) ** 2)


def _train(x: Tensor, st: _Settings, mu_thresh: float, seed: int, progress) -> tuple[SparseDictionary, KSVDInfo]:
    """Train ``D = B A`` on the blocks at step 1 (evenly thinned to ``n_train``), means removed."""
    train = extract_patches(x, st.block, 1)
    if train.shape[0] > st.n_train:
        pick = torch.linspace(0, train.shape[0] - 1, st.n_train, dtype=torch.float64).round().long()
        train = train[pick.to(x.device)]
    if train.shape[0] < st.L:
        raise FieldError(
            "n_atoms", f"{st.L} atoms need at least as many training blocks; the image gives {train.shape[0]} "
            f"blocks of {st.block} (use a smaller block_size or n_atoms)"
        )
    train = train - train.mean(1, keepdim=True)
    return sparse_ksvd(
        train, st.base, n_atoms=st.L, atom_sparsity=st.T, tol=st.tol, n_nonzero_coefs=st.cap, n_iter=st.n_iter,
        init="identity" if st.L <= st.base.n_in else "data", mu_thresh=mu_thresh, seed=seed,
        return_info=True, progress=progress,
    )


def _denoise_blocks(x: Tensor, dictionary: SparseDictionary, st: _Settings, lam: float, progress):
    """Code every block at ``step`` over ``D`` to the error ``tol`` and average back (Eq. 18):
    ``x̂ = (λ x + Σ blocks) / (λ + count)``. Returns ``(x̂, OMPInfo)``."""
    blocks = extract_patches(x, st.block, st.step)
    dc = blocks.mean(1, keepdim=True)
    blocks = blocks - dc
    D = dictionary.matrix(dtype=x.dtype, device=x.device)
    codes, oinfo = batch_omp(
        D, blocks, n_nonzero_coefs=st.cap, tol=st.tol, gram=dictionary.gram(), Dty=dictionary.adjoint(blocks),
        return_info=True, progress=progress, check=False,
    )
    clean = codes @ D.T + dc
    total, count = accumulate_patches(clean, tuple(x.shape), st.block, st.step)
    return (float(lam) * x + total) / (float(lam) + count), oinfo
