"""Numpy in, numpy out: the decorator that lets tensor functions take what users hold."""

from __future__ import annotations

import functools

import numpy as np
import torch
from torch import Tensor

__all__ = ["numpy_io", "as_float_tensor"]


def as_float_tensor(a):
    """``a`` (a numpy array or a tensor) as a tensor; integers and booleans promoted to torch's
    default float dtype instead of integer arithmetic."""
    t = torch.as_tensor(a)
    return t if (t.is_floating_point() or t.is_complex()) else t.to(torch.get_default_dtype())


def _to_tensor(a):
    return as_float_tensor(a) if isinstance(a, np.ndarray) else a


def _to_numpy(o):
    return o.detach().cpu().numpy() if isinstance(o, Tensor) else o


def numpy_io(fn):
    """Wrap ``fn`` so that numpy arrays among its positional arguments (the data: operators,
    signals, images) become tensors (integers promoted to the default float dtype) and, when any
    was given, its tensor results come back as numpy (element-wise for a returned tuple). Keyword
    arguments (settings such as a σ schedule) are passed as they are; tensor calls are untouched."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if not any(isinstance(a, np.ndarray) for a in args):
            return fn(*args, **kwargs)
        out = fn(*(_to_tensor(a) for a in args), **kwargs)
        if type(out) is tuple:
            return tuple(_to_numpy(o) for o in out)
        return _to_numpy(out)

    return wrapper
