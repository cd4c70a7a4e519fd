"""Compiled CPU kernel of :func:`cssat.optics.render` (optional, numba).

One view per thread at a time: a loop over the facets with the same coverage rule (pixel centres
inside or on the edges), the same depth interpolation, the same tie rule (on equal depth the higher
facet index wins) and the same flat shading and centroid deposit as the torch path, which stays
the reference (and runs on a GPU). The tests compare the two.
"""

from __future__ import annotations

import numpy as np

from cssat._numba import available, kernel

__all__ = ["available"]


def _build(parallel: bool):
    from numba import njit, prange  # heavy: numba, only for _build()

    @njit(parallel=parallel, cache=True, nogil=True)
    def _raster(X, Y, Z, faces, back, b, size, bias, out):
        T = X.shape[0]
        is_parallel = parallel  # a closure cell: numba's cache keys the two variants apart  # noqa: F841
        F = faces.shape[0]
        npix = size * size
        for t in prange(T):
            zbuf = np.full(npix, -np.inf, dtype=np.float32)
            fbuf = np.full(npix, -1, dtype=np.int64)
            for f in range(F):
                i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
                x0, x1, x2 = X[t, i0], X[t, i1], X[t, i2]
                y0, y1, y2 = Y[t, i0], Y[t, i1], Y[t, i2]
                area2 = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
                if abs(area2) <= 1e-12:
                    continue
                bx0 = max(np.ceil(min(x0, x1, x2) - 0.5), 0.0)
                bx1 = min(np.floor(max(x0, x1, x2) - 0.5), size - 1.0)
                by0 = max(np.ceil(min(y0, y1, y2) - 0.5), 0.0)
                by1 = min(np.floor(max(y0, y1, y2) - 0.5), size - 1.0)
                if bx1 < bx0 or by1 < by0:
                    continue
                sg = np.float32(1.0) if area2 > 0 else np.float32(-1.0)
                # edge k opposite vertex k: e_k = a_k x + b_k y + c_k
                a0 = sg * -(y2 - y1)
                b0 = sg * (x2 - x1)
                c0 = -(a0 * x1 + b0 * y1)
                a1 = sg * -(y0 - y2)
                b1 = sg * (x0 - x2)
                c1 = -(a1 * x2 + b1 * y2)
                a2 = sg * -(y1 - y0)
                b2 = sg * (x1 - x0)
                c2 = -(a2 * x0 + b2 * y0)
                zb = np.float32(bias) if back[t, f] else np.float32(0.0)
                z0, z1, z2 = Z[t, i0] - zb, Z[t, i1] - zb, Z[t, i2] - zb
                for ry in range(int(by0), int(by1) + 1):
                    py = np.float32(ry + 0.5)
                    for cx in range(int(bx0), int(bx1) + 1):
                        px = np.float32(cx + 0.5)
                        e0 = a0 * px + b0 * py + c0
                        e1 = a1 * px + b1 * py + c1
                        e2 = a2 * px + b2 * py + c2
                        if e0 >= 0 and e1 >= 0 and e2 >= 0:
                            depth = (e0 * z0 + e1 * z1 + e2 * z2) / (e0 + e1 + e2)
                            p = (size - 1 - ry) * size + cx
                            if depth > zbuf[p] or (depth == zbuf[p] and f > fbuf[p]):
                                zbuf[p] = depth
                                fbuf[p] = f
            counts = np.zeros(F, dtype=np.int64)
            for p in range(npix):
                if fbuf[p] >= 0:
                    counts[fbuf[p]] += 1
            for p in range(npix):
                f = fbuf[p]
                if f >= 0:
                    out[t, p] += b[t, f] / counts[f]
            for f in range(F):
                if counts[f] == 0 and b[t, f] != 0:
                    i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
                    cxf = min(max(np.floor((X[t, i0] + X[t, i1] + X[t, i2]) / 3.0), 0.0), size - 1.0)
                    cyf = min(max(np.floor((Y[t, i0] + Y[t, i1] + Y[t, i2]) / 3.0), 0.0), size - 1.0)
                    out[t, (size - 1 - int(cyf)) * size + int(cxf)] += b[t, f]

    return _raster


def raster(X, Y, Z, faces, back, b, size: int, bias: float, out, threads: int) -> None:
    """Fill ``out (T, size²)`` in place; arrays are C-contiguous numpy (coordinates float32)."""
    kernel(_build, threads)(X, Y, Z, faces, back, b, size, bias, out)
