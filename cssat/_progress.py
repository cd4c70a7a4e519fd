"""Progress bars: tqdm, one convention for every long stage.

``progress`` (the argument of every library function with a long loop, and the top-level
``progress`` of the config): ``None`` (default) shows a bar only on a terminal (tqdm's
``disable=None``) and only for a stage that has run more than a second; ``True`` always shows
it (a log file gets its lines too); ``False`` never does. A finished top-level bar stays (its
line records the stage's time), nested ones are cleared (tqdm's ``leave=None``). A notebook's
output is not a terminal: pass ``progress=True`` there, and ``tqdm.auto`` draws a widget when
ipywidgets is installed.
"""

from __future__ import annotations

import sys
import warnings
from typing import Any

from tqdm.auto import tqdm

from cssat._checks import progress_param

__all__ = ["progress_bar"]


class _Off:
    """A bar that is not shown, with tqdm's interface and none of its cost (K-SVD calls
    :func:`cssat.sparse.batch_omp` thousands of times; a disabled tqdm costs ~40 µs each)."""

    disable = True
    n = 0

    def __init__(self, iterable: Any = None):
        self.iterable = iterable

    def __iter__(self):
        return iter(self.iterable)

    def update(self, n: float = 1) -> None:
        pass

    def set_postfix(self, *args: Any, **kwargs: Any) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> "_Off":
        return self

    def __exit__(self, *exc: Any) -> bool:
        return False


def _on_terminal() -> bool:
    err = sys.stderr
    return err is not None and hasattr(err, "isatty") and err.isatty()


def progress_bar(total: int | None, desc: str, progress: bool | None = None, unit: str = "it", **kwargs: Any):
    """A ``tqdm`` bar of ``total`` ``unit``\\ s named ``desc``, shown as ``progress`` says (a
    no-op object with the same methods when it is not shown)."""
    if progress_param(progress) is False or (progress is None and not _on_terminal()):
        return _Off(kwargs.get("iterable"))

    with warnings.catch_warnings():  # tqdm.auto in a notebook without ipywidgets: the text bar is fine
        warnings.filterwarnings("ignore", message=".*IProgress not found.*")
        return tqdm(total=total, desc=desc, unit=unit, disable=False,
                    delay=1.0 if progress is None else 0.0, leave=None, dynamic_ncols=True, **kwargs)
