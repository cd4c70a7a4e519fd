"""Resolved images: orthographic projection, rasterisation, flat shading and a z-buffer, batched
over views as tensor operations (paper: "Synthetic Resolved Image Generation", Fig. 4a).

Each image is the satellite seen from ``observer`` on an image plane perpendicular to it, with a
fixed field of view so every image of one object shares a scale. A facet's brightness (Eq. 8) is
spread evenly over the pixels whose centres it covers and where it is the nearest facet (flat
shading with a z-buffer). A lit facet that wins no pixel — smaller than a pixel, or hidden in the
raster though its centroid is visible — deposits its brightness at the pixel under its centroid,
so the pixel sum of every image equals the light curve (Eq. 10) for the same geometry.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import Tensor

from cssat._checks import FieldError
from cssat._progress import progress_bar
from cssat.optics import _render_numba
from cssat.optics.photometry import check_unit, facet_brightness
from cssat.scene.mesh import Mesh, as_mesh

if TYPE_CHECKING:
    from typing import Any, Sequence

    from cssat._types import Vectors

__all__ = ["render", "image_basis", "default_fov"]


def default_fov(mesh: Mesh, margin: float = 1.05) -> float:
    """A field of view (m) that holds ``mesh`` in any orientation: ``2 · radius · margin``."""
    mesh = as_mesh(mesh)
    return 2.0 * mesh.radius * margin


def image_basis(observer: Tensor, up: Sequence[float] = (0.0, 0.0, 1.0)) -> tuple[Tensor, Tensor]:
    """Image axes ``(e_x, e_y)``, each ``(T, 3)``, perpendicular to the view direction ``V``:
    ``e_y`` is ``up`` projected on the image plane (body +z by default; body +x when ``V`` is
    nearly parallel to it), ``e_x = e_y × V``, so ``e_x × e_y = V`` points to the viewer."""
    V = observer
    upt = torch.as_tensor(up, dtype=V.dtype, device=V.device).expand_as(V)
    alt = torch.tensor([1.0, 0.0, 0.0], dtype=V.dtype, device=V.device).expand_as(V)
    ey = upt - (upt * V).sum(1, keepdim=True) * V
    small = torch.linalg.vector_norm(ey, dim=1, keepdim=True) < 1e-6
    ey = torch.where(small, alt - (alt * V).sum(1, keepdim=True) * V, ey)
    ey = ey / torch.linalg.vector_norm(ey, dim=1, keepdim=True)
    ex = torch.linalg.cross(ey, V, dim=1)
    return ex, ey


def render(
    mesh: Mesh,
    sun: Vectors,
    observer: Vectors,
    size: int,
    *,
    fov_m: float | None = None,
    brightness: Tensor | None = None,
    up: Sequence[float] = (0.0, 0.0, 1.0),
    dtype: torch.dtype = torch.float32,
    views_per_chunk: int = 128,
    backend: str = "auto",
    progress: bool | None = None,
    **brightness_kwargs: Any,
) -> Tensor:
    """Render ``(T, size, size)`` images of ``mesh`` for body-frame unit vectors ``sun`` and
    ``observer`` (``(T, 3)`` each, from the object).

    ``brightness (T, F)`` are the facet brightnesses to shade with (default:
    :func:`facet_brightness` with ``brightness_kwargs``, e.g. ``shadows=True``); pixel values are
    in the same units (W/m² at the observer), so ``image.sum((1, 2)) == brightness.sum(1)``.
    ``fov_m`` is the side of the square field of view in metres (default :func:`default_fov`).
    Row 0 is the top of the image (``e_y`` up), column 0 the left (``-e_x``).

    ``backend``: ``"torch"`` rasterises all views of a chunk at once with tensor operations (any
    device); ``"numba"`` runs a compiled CPU kernel, one view per thread, with the same rules
    (several times faster on meshes with many sub-pixel facets); ``"auto"`` takes numba for CPU
    tensors when it is installed. ``progress``: a tqdm bar of the views rendered (``None``: on a
    terminal, after a second).
    """
    mesh = as_mesh(mesh)
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
        raise FieldError("size", f"image size must be a positive integer, got {size!r}")
    size = int(size)
    obs = check_unit(observer, "observer")
    T, F = obs.shape[0], len(mesh)
    if brightness is None:
        brightness = facet_brightness(mesh, sun, obs, **brightness_kwargs)
    brightness = torch.as_tensor(brightness)
    if tuple(brightness.shape) != (T, F):
        raise FieldError("brightness", f"expected shape ({T}, {F}), got {tuple(brightness.shape)}")
    if not bool(torch.isfinite(brightness).all()):
        raise FieldError("brightness", "contains NaN or Inf")
    if fov_m is None:
        fov_m = default_fov(mesh)
    if not (isinstance(fov_m, (int, float)) and math.isfinite(fov_m) and fov_m > 0):
        raise FieldError("fov_m", f"must be a positive number of metres, got {fov_m!r}")
    if getattr(mesh, "joints", ()):  # articulated parts (Sun-tracking arrays): each view in its own pose
        sun_t = check_unit(sun, "sun")
        images = None
        for idx, posed in mesh.poses(sun_t):
            sel = torch.as_tensor(idx)
            part = render(posed, sun_t[sel], obs[sel], size, fov_m=fov_m, brightness=brightness[sel.to(brightness.device)],
                          up=up, dtype=dtype, views_per_chunk=views_per_chunk, backend=backend, progress=False)
            if images is None:
                images = torch.zeros((T, size, size), dtype=part.dtype, device=part.device)
            images[sel.to(part.device)] = part
        return images
    dev = brightness.device
    # geometry in float32: pixel coordinates below 10⁴ and depths within the model's size need no more
    obs = obs.to(device=dev, dtype=torch.float64)
    ex, ey = (v.float() for v in image_basis(obs, up))
    obs = obs.float()
    verts = torch.as_tensor(mesh.vertices, dtype=torch.float32, device=dev)
    faces = torch.as_tensor(mesh.faces, device=dev)
    normals = torch.as_tensor(mesh.normals, dtype=torch.float32, device=dev)
    bias = 1e-5 * max(mesh.radius, 1e-12)  # ~100 float32 ulps of a depth
    if backend not in ("auto", "torch", "numba"):
        raise FieldError("backend", f"expected 'auto', 'torch' or 'numba', got {backend!r}")

    use_numba = dev.type == "cpu" and (backend == "numba" or (backend == "auto" and _render_numba.available()))
    images = torch.zeros(T, size, size, dtype=dtype, device=dev)
    bar = progress_bar(T, f"rendering {T} views {size}²", progress, unit="view")
    for s in range(0, T, views_per_chunk):
        e = min(s + views_per_chunk, T)
        if use_numba:
            X, Y, Z = _project(verts, obs[s:e], ex[s:e], ey[s:e], size, float(fov_m))
            back = (obs[s:e] @ normals.T) <= 0
            _render_numba.raster(
                X.numpy(), Y.numpy(), Z.numpy(), faces.numpy(), back.numpy(),
                brightness[s:e].to(dtype).contiguous().numpy(), size, bias,
                images[s:e].view(e - s, -1).numpy(), torch.get_num_threads(),
            )
        else:
            _render_chunk(
                verts, faces, normals, obs[s:e], ex[s:e], ey[s:e], brightness[s:e].to(dtype),
                size, float(fov_m), bias, images[s:e].view(e - s, -1),
            )
        bar.update(e - s)
    bar.close()
    return images


def _project(verts, V, ex, ey, size, fov):
    """Vertex coordinates of each view: pixel columns ``X``, rows ``Y`` (upwards) and depth ``Z``
    towards the viewer, each ``(views, n_vertices)``."""
    scale = size / fov
    vt = verts.T.contiguous()
    half = torch.full((), size / 2, dtype=vt.dtype, device=vt.device)
    return torch.addmm(half, ex, vt, alpha=scale), torch.addmm(half, ey, vt, alpha=scale), V @ vt


def _render_chunk(verts, faces, normals, V, ex, ey, b, size, fov, bias, out):
    Tc, F = b.shape
    dev = verts.device
    X, Y, Z = _project(verts, V, ex, ey, size, fov)  # (Tc, Vn) each
    fidx = faces.reshape(-1)
    fx = X.index_select(1, fidx).view(Tc, F, 3)  # (Tc, F, 3)
    fy = Y.index_select(1, fidx).view(Tc, F, 3)
    x0 = torch.ceil(fx.amin(-1) - 0.5).clamp(min=0)
    y0 = torch.ceil(fy.amin(-1) - 0.5).clamp(min=0)
    w = torch.floor(fx.amax(-1) - 0.5).clamp(max=size - 1) - x0 + 1
    h = torch.floor(fy.amax(-1) - 0.5).clamp(max=size - 1) - y0 + 1
    area2 = (fx[..., 1] - fx[..., 0]) * (fy[..., 2] - fy[..., 0]) - (fx[..., 2] - fx[..., 0]) * (fy[..., 1] - fy[..., 0])
    valid = (w > 0) & (h > 0) & (area2.abs() > 1e-12)
    li = valid.view(-1).nonzero().squeeze(1)  # candidate (view, facet) pairs, flattened

    flat_b = b.reshape(-1)
    counts = torch.zeros(Tc * F, dtype=b.dtype, device=dev)
    if len(li):
        # the candidates' vertices, gathered straight from the projected vertex arrays
        v_c, f_c = li // F, li % F
        vert = v_c[:, None] * X.shape[1] + faces[f_c]  # (n, 3) flat vertex indices
        tx, ty = X.reshape(-1)[vert], Y.reshape(-1)[vert]
        back = ((V[v_c] * normals[f_c]).sum(1) <= 0)  # back-facing facets occlude but lose depth ties
        tz = Z.reshape(-1)[vert] - bias * back[:, None]
        sgn = torch.sign(area2.view(-1)[li])
        # edge functions e_k(x, y) = a_k x + b_k y + c_k (>= 0 inside), edge k opposite vertex k
        j1, j2 = [1, 2, 0], [2, 0, 1]
        A = sgn[:, None] * -(ty[:, j2] - ty[:, j1])  # (n, 3)
        Bc = sgn[:, None] * (tx[:, j2] - tx[:, j1])
        C = -(A * tx[:, j1] + Bc * ty[:, j1])
        box = torch.stack([x0.view(-1)[li], y0.view(-1)[li], w.view(-1)[li], h.view(-1)[li]], 1)
        # per candidate: edge coefficients A, B, C (3 each), vertex depths (3), bbox x0, y0, w, h
        Q = torch.cat([A, Bc, C, tz, box], 1)  # (n, 16)
        ext = torch.maximum(box[:, 2], box[:, 3])
        keys, fids, vids, depths = [], [], [], []
        lo, Bsz = 0, 1
        max_ext = int(ext.max())
        while lo < max_ext:
            sel = ((ext > lo) & (ext <= Bsz)).nonzero().squeeze(1)
            o = torch.arange(Bsz, device=dev, dtype=Q.dtype)
            step = max(1, (1 << 22) // (Bsz * Bsz))
            for c0 in range(0, len(sel), step):
                k = sel[c0 : c0 + step]
                q = Q[k]
                px = (q[:, 12, None, None] + 0.5) + o[None, None, :]  # (m, 1, B) pixel-centre columns
                py = (q[:, 13, None, None] + 0.5) + o[None, :, None]  # (m, B, 1) rows
                inside = (o[None, None, :] < q[:, 14, None, None]) & (o[None, :, None] < q[:, 15, None, None])
                for e in range(3):
                    inside &= (q[:, e, None, None] * px + q[:, 3 + e, None, None] * py + q[:, 6 + e, None, None]) >= 0
                n_i, r_i, c_i = inside.nonzero(as_tuple=True)
                qq = q[n_i]
                colf = qq[:, 12] + c_i
                rowf = qq[:, 13] + r_i
                # depth at the pixel centre from the barycentric weights
                wts = qq[:, 0:3] * (colf + 0.5)[:, None] + qq[:, 3:6] * (rowf + 0.5)[:, None] + qq[:, 6:9]
                depths.append((wts * qq[:, 9:12]).sum(1) / wts.sum(1))
                lik = li[k[n_i]]
                v_ = lik // F
                keys.append(v_ * (size * size) + (size - 1 - rowf.long()) * size + colf.long())
                fids.append(lik % F)
                vids.append(v_)
            lo, Bsz = Bsz, 2 * Bsz
        if keys:
            key = torch.cat(keys)
            fid = torch.cat(fids)
            vid = torch.cat(vids)
            depth = torch.cat(depths)
            zbuf = torch.full((Tc * size * size,), -math.inf, dtype=depth.dtype, device=dev)
            zbuf.scatter_reduce_(0, key, depth, reduce="amax")
            win = depth >= zbuf[key]
            # exact depth ties (shared edges): the highest facet index wins, one facet per pixel
            best = torch.full((Tc * size * size,), -1, dtype=fid.dtype, device=dev)
            best.scatter_reduce_(0, key[win], fid[win], reduce="amax")
            win &= fid == best[key]
            vf = vid[win] * F + fid[win]
            counts.index_add_(0, vf, torch.ones(len(vf), dtype=b.dtype, device=dev))
            out.view(-1).index_add_(0, key[win], flat_b[vf] / counts[vf])
    # lit facets that won no pixel: their brightness goes to the pixel under the centroid
    lost = (counts == 0) & (flat_b != 0)
    if bool(lost.any()):
        li = lost.nonzero().squeeze(1)
        v_, f_ = li // F, li % F
        cx = fx[v_, f_].mean(-1).floor().clamp(0, size - 1).long()
        cy = fy[v_, f_].mean(-1).floor().clamp(0, size - 1).long()
        pix = v_ * (size * size) + (size - 1 - cy) * size + cx
        out.view(-1).index_add_(0, pix, flat_b[li])
