"""Measured BRDFs: tables of lab measurements, the scatter models fitted to them (Harvey's
ABg, Greynolds' binomial) and least-squares fits of those and of :class:`~cssat.optics.CookTorrance`.

Table layout (lumos-sat's, ``lumos.brdf.tools.fit``): a text file of whitespace-separated rows
``phi_in theta_in phi_out theta_out brdf``, angles in degrees in the surface's frame (normal +z):
``phi`` the polar angle from the normal, ``theta`` the azimuth, a unit vector
``(sin φ cos θ, sin φ sin θ, cos φ)`` (a negative ``phi`` is the opposite azimuth); ``in`` points
from the surface to the light, ``out`` to the detector; ``brdf`` in sr⁻¹. Lines starting with
``#`` are comments; a first line of column names is skipped.

Models, with ``r = 2(n·l)n − l`` the mirror direction and ``β = v − (v·n)n``,
``β₀ = r − (r·n)n`` the projections of the view and mirror directions on the surface:

=================  ===========================================================================
``ABG(A, B, g)``   ``A / (B + |β − β₀|^g)`` (Harvey's ABg scatter; ``A/B`` the specular peak)
``Binomial``       ``log10 f = Σ_k (Σ_i B_ki D^i + ½ Σ_i C_ki log10(1 + d^(i+l1) D²)) V^k`` with
                   ``D = |ρ − ρ₀|``, ``V = ρ·ρ₀`` (ρ = β, ρ₀ = β₀): Greynolds' model as lumos-sat
                   writes it (``B (n, m)``, ``C (n, l2 − l1)``)
=================  ===========================================================================

Fits minimise the squared error of ``log10 f`` (the data span decades: lumos-sat's default) with
``scipy.optimize.least_squares`` in bounds. Assumptions: isotropic surfaces, one wavelength band,
the measured points in front of the surface (others are refused).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError, float_param, int_param
from cssat.optics.brdf import BRDF, BRDFS, CookTorrance, _dot

if TYPE_CHECKING:
    from typing import Sequence

__all__ = ["ABG", "Binomial", "BRDFTable", "FIT_MODELS", "fit_brdf", "fit_brdf_file", "read_brdf_table", "write_brdf_table"]

COLUMNS = ("phi_in", "theta_in", "phi_out", "theta_out", "brdf")


def _projections(n: Tensor, l: Tensor, v: Tensor, nl: Tensor, nv: Tensor) -> tuple[Tensor, Tensor]:
    """``β = v − (v·n)n`` and ``β₀ = r − (r·n)n = (n·l)n − l`` (``r`` the mirror of ``l``)."""
    return v - nv[..., None] * n, nl[..., None] * n - l


class ABG(BRDF):
    """Harvey's ABg scatter ``A / (B + |β − β₀|^g)`` (sr⁻¹): ``A > 0``, ``B > 0`` (``A/B`` the
    peak at the mirror direction), ``g`` the log–log slope of the wings."""

    name = "abg"

    def __init__(self, A: float = 0.1, B: float = 0.1, g: float = 1.0):
        self.A = float_param(A, "A", 0.0, 1e12, open_lo=True)
        self.B = float_param(B, "B", 0.0, 1e12, open_lo=True)
        self.g = float_param(g, "g", 0.0, 10.0)

    def _f(self, n, l, v, nl, nv):
        beta, beta0 = _projections(n, l, v, nl, nv)
        x = (beta - beta0).norm(dim=-1)
        return self.A / (self.B + x ** self.g)


class Binomial(BRDF):
    """Greynolds' binomial scatter as lumos-sat writes it: ``B (n, m)``, ``C (n, l2 − l1)``
    coefficients, ``d > 0`` the specularity constant, ``l1`` the first Gaussian index."""

    name = "binomial"

    def __init__(self, B: Any = ((-1.0, 0.0),), C: Any = ((0.0,),), d: float = 10.0, l1: int = 0):
        self.B = np.atleast_2d(np.asarray(B, dtype=np.float64))
        self.C = np.atleast_2d(np.asarray(C, dtype=np.float64))
        if self.B.ndim != 2 or self.C.ndim != 2 or self.B.shape[0] != self.C.shape[0]:
            raise FieldError("B", f"B (n, m) and C (n, j) need the same n rows, got {self.B.shape} and {self.C.shape}")
        for name, arr in (("B", self.B), ("C", self.C)):
            if not np.isfinite(arr).all():
                raise FieldError(name, "must be finite numbers")
        self.d = float_param(d, "d", 0.0, 1e12, open_lo=True)
        self.l1 = int_param(l1, "l1", -100, 100)

    def _f(self, n, l, v, nl, nv):
        rho, rho0 = _projections(n, l, v, nl, nv)
        D, V = (rho - rho0).norm(dim=-1), _dot(rho, rho0)
        log_f = torch.zeros_like(D)
        for k in range(self.B.shape[0]):
            t = sum(float(b) * D ** i for i, b in enumerate(self.B[k]))
            t = t + 0.5 * sum(float(c) * torch.log10(1 + self.d ** (i + self.l1) * D * D) for i, c in enumerate(self.C[k]))
            log_f = log_f + t * V ** k
        return 10.0 ** log_f

    def describe(self) -> dict[str, Any]:
        return {"brdf": self.name, "brdf_B": self.B.tolist(), "brdf_C": self.C.tolist(), "brdf_d": self.d, "brdf_l1": self.l1}

    def __repr__(self) -> str:
        return f"Binomial(B={self.B.tolist()}, C={self.C.tolist()}, d={self.d:g}, l1={self.l1})"


BRDFS.update({c.name: c for c in (ABG, Binomial)})


@dataclass
class BRDFTable:
    """Measured BRDF values: ``to_light``, ``to_viewer`` ``(N, 3)`` unit vectors in the surface
    frame (normal +z), ``brdf (N,)`` sr⁻¹."""

    to_light: np.ndarray
    to_viewer: np.ndarray
    brdf: np.ndarray

    def __len__(self) -> int:
        return len(self.brdf)


def _unit(phi_deg: np.ndarray, theta_deg: np.ndarray) -> np.ndarray:
    p, t = np.radians(phi_deg), np.radians(theta_deg)
    return np.stack([np.sin(p) * np.cos(t), np.sin(p) * np.sin(t), np.cos(p)], -1)


def read_brdf_table(path: str | os.PathLike, field: str = "path") -> BRDFTable:
    """The table at ``path`` (module docstring: lumos-sat's layout). Errors name ``field``, or the
    column (``phi_in``, ..., ``brdf``) at fault."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FieldError(field, f"no such file: {path!r}")
    rows = []
    with open(path, "rb") as fh:
        raw = fh.read()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise FieldError(field, f"{path!r} is not a UTF-8 text table (byte {e.start}: {raw[e.start:e.start + 1]!r}); "
                                "a gzip or binary file must be unpacked first") from None
    for k, line in enumerate(text.splitlines(), 1):
        s = line.split("#", 1)[0].strip()
        if not s:
            continue
        parts = s.replace(",", " ").split()
        try:
            rows.append([float(x) for x in parts])
        except ValueError:
            if rows:
                raise FieldError(field, f"{path!r} line {k}: not numbers: {s[:60]!r}") from None
            continue  # a header of column names
        if len(parts) != len(COLUMNS):
            raise FieldError(field, f"{path!r} line {k}: expected {len(COLUMNS)} columns {' '.join(COLUMNS)}, "
                                    f"got {len(parts)}")
    if not rows:
        raise FieldError(field, f"{path!r} holds no rows of {' '.join(COLUMNS)}")
    data = np.asarray(rows, dtype=np.float64)
    for j, name in enumerate(COLUMNS):
        if not np.isfinite(data[:, j]).all():
            raise FieldError(name, f"{path!r}: non-finite values")
    for j in (0, 2):
        if np.any(np.abs(data[:, j]) >= 90.0):
            raise FieldError(COLUMNS[j], f"{path!r}: polar angles must lie within (-90, 90) degrees of the normal, "
                                         f"got {data[np.argmax(np.abs(data[:, j])), j]:g}")
    if np.any(data[:, 4] <= 0):
        raise FieldError("brdf", f"{path!r}: BRDF values must be > 0 (sr^-1) to be fitted in log space")
    return BRDFTable(_unit(data[:, 0], data[:, 1]), _unit(data[:, 2], data[:, 3]), data[:, 4])


def write_brdf_table(path: str | os.PathLike, phi_in: Any, theta_in: Any, phi_out: Any, theta_out: Any, brdf: Any,
                     comment: str = "") -> None:
    """Write a table in lumos-sat's layout (degrees, sr⁻¹), ``comment`` as ``#`` lines on top."""
    cols = np.broadcast_arrays(*(np.asarray(c, dtype=np.float64) for c in (phi_in, theta_in, phi_out, theta_out, brdf)))
    with open(path, "w", encoding="utf-8") as fh:
        for line in comment.splitlines():
            fh.write(f"# {line}\n")
        fh.write("# " + "     ".join(COLUMNS) + "\n")
        for row in np.stack([c.ravel() for c in cols], -1):
            fh.write("  ".join(f"{x:.9g}" for x in row) + "\n")


def _abg(p):
    return ABG(math.exp(p[0]), math.exp(p[1]), p[2])


def _cook_torrance(f0):
    def make(p):
        return CookTorrance(kd=p[0], ks=(1 - p[0]) * p[1], roughness=p[2], f0=f0)
    return make


#: the models :func:`fit_brdf` fits
FIT_MODELS = ("abg", "binomial", "cook_torrance")


def fit_brdf(table: BRDFTable, model: str = "abg", *, f0: float = 0.9, binomial: Sequence[int] = (1, 2, 1, 2),
             p0: Sequence[float] | None = None) -> BRDF:
    """The ``model`` (:data:`FIT_MODELS`) of least squared ``log10`` error to ``table``.

    ``abg``: ``A``, ``B`` (fitted in log), ``g ∈ [0, 10]``. ``cook_torrance``: ``kd``, ``ks``
    (``kd + ks ≤ 1``), GGX ``roughness ∈ [0.001, 1]``, Schlick's ``f0`` held at ``f0`` (it and
    ``ks`` scale the lobe alike: they are not separable from in-plane data). ``binomial``: shape
    ``(n, m, l1, l2)`` as lumos-sat's ``BinomialHelper``, all ``B``, ``C`` and ``log d`` fitted.
    ``p0``: a start (the model's own parameters; defaults: a broad lobe).
    """
    from scipy.optimize import least_squares  # heavy: scipy.optimize, only for fits

    if model not in FIT_MODELS:
        raise FieldError("model", f"expected one of {list(FIT_MODELS)}, got {model!r}")
    n = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    L, Vv = torch.as_tensor(table.to_light), torch.as_tensor(table.to_viewer)
    target = np.log10(table.brdf)
    if model == "abg":
        make, lo, hi = _abg, [-30.0, -30.0, 0.0], [30.0, 30.0, 10.0]
        start = [math.log(0.1), math.log(0.1), 1.0] if p0 is None else [math.log(p0[0]), math.log(p0[1]), p0[2]]
    elif model == "cook_torrance":
        make, lo, hi = _cook_torrance(float_param(f0, "f0", 0.0, 1.0)), [0.0, 0.0, 1e-3], [1.0, 1.0, 1.0]
        start = [0.3, 0.5, 0.3] if p0 is None else [p0[0], p0[1] / max(1 - p0[0], 1e-12), p0[2]]
    else:
        nb, mb, l1, l2 = (int_param(x, "binomial", 0, 50) for x in binomial)
        if nb < 1 or mb < 1 or l2 <= l1:
            raise FieldError("binomial", f"expected (n >= 1, m >= 1, l1, l2 > l1), got {tuple(binomial)}")

        def make(p):
            return Binomial(np.reshape(p[:nb * mb], (nb, mb)), np.reshape(p[nb * mb:-1], (nb, l2 - l1)), math.exp(p[-1]), l1)
        size = nb * mb + nb * (l2 - l1)
        lo, hi = [-50.0] * size + [-20.0], [50.0] * size + [20.0]
        B0 = [float(np.median(target))] + [0.0] * (nb * mb - 1)
        start = (B0 + [-1.0] * (size - nb * mb) + [math.log(10.0)]) if p0 is None else list(p0)  # C ≠ 0: d moves
    start = np.clip(np.asarray(start, dtype=np.float64), np.asarray(lo) + 1e-9, np.asarray(hi) - 1e-9)

    def resid(p):
        f = make(p).evaluate(n, L, Vv).numpy()
        return np.log10(np.maximum(f, 1e-300)) - target

    sol = least_squares(resid, start, bounds=(lo, hi), x_scale="jac")
    return make(sol.x)


def fit_brdf_file(path: str, model: str = "abg", f0: float = 0.9, binomial: Sequence[int] = (1, 2, 1, 2)) -> BRDF:
    """:func:`fit_brdf` of the table at ``path`` (the ``brdf=table`` config option)."""
    return fit_brdf(read_brdf_table(path), model, f0=f0, binomial=tuple(binomial))
