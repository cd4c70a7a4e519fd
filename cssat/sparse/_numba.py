"""The numba plumbing the sparse kernels use: :mod:`cssat._numba` (a base module, so that the
optics renderer shares it without importing the sparse layer)."""

from cssat._numba import KERNELS, available, kernel  # noqa: F401  (one cache of kernels for all)
