"""The config of the paper's pixel sensing (``forward: pixels``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from cssat._checks import FieldError

__all__ = ["PixelsConfig", "DTYPES", "check_dtype"]

#: the precisions of Φ, x and y
DTYPES = ("float32", "float64")


def check_dtype(value: Any, field: str) -> None:
    """``value`` is null or one of :data:`DTYPES`, else a :class:`FieldError` naming ``field``."""
    if value is not None and value not in DTYPES:
        raise FieldError(field, f"expected one of {sorted(DTYPES)}, got {value!r}")


@dataclass
class PixelsConfig:
    """The paper's forward model (Eq. 12–15): the unknown is the target image, each pixel's flux
    scaled per sample by the atmosphere's weights, ``y = noise(Φx)``
    (:class:`cssat.experiments.forward.PixelSensing`)."""

    _target_: str = "cssat.experiments.forward.PixelSensing"
    #: the precision of Φ, x and y; null: the run's dtype (an operator estimate may ask for float64)
    dtype: Optional[str] = None
    #: the dtype Φ is drawn in (then held exactly in dtype); null: dtype
    draw_dtype: Optional[str] = None

    def __post_init__(self) -> None:
        check_dtype(self.dtype, "forward.dtype")
        check_dtype(self.draw_dtype, "forward.draw_dtype")
