"""Progress bars: tqdm, one convention for every long stage.

``progress`` (the argument of every library function with a long loop, and the top-level
``progress`` of the config): ``None`` (default) shows a bar only on a terminal (tqdm's
``disable=None``) and only for a stage that has run more than a second; ``True`` always shows
it (a log file gets its lines too); ``False`` never does. A finished top-level bar stays (its
line records the stage's time), nested ones are cleared (tqdm's ``leave=None``). In a notebook
``tqdm.auto`` draws a widget when ipywidgets is installed.
"""

from __future__ import annotations

from typing import Any

__all__ = ["progress_bar"]


def progress_bar(total: int | None, desc: str, progress: bool | None = None, unit: str = "it", **kwargs: Any):
    """A ``tqdm`` bar of ``total`` ``unit``\\ s named ``desc``, shown as ``progress`` says."""
    import warnings

    from tqdm.auto import tqdm

    if progress is not None and not isinstance(progress, bool):
        raise ValueError(f"progress: expected true, false or null (on a terminal), got {progress!r}")
    with warnings.catch_warnings():  # tqdm.auto in a notebook without ipywidgets: the text bar is fine
        warnings.filterwarnings("ignore", message=".*IProgress not found.*")
        return tqdm(total=total, desc=desc, unit=unit, disable=None if progress is None else not progress,
                    delay=1.0 if progress is None else 0.0, leave=None, dynamic_ncols=True, **kwargs)
