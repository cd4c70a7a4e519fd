"""What every stage of a run shares: the run's settings, its timings and its error fields.

A :class:`Run` is made once per experiment from the top-level settings (``seed``, ``dtype``,
``device``, ``progress``, ``figure_format``, ``memory_limit_gb``) and handed to every stage, so no
stage reads another group's config. :meth:`Run.stage` times a stage into ``seconds_<stage>``;
:func:`as_field` turns a library error raised while a stage reads its group into a
:class:`~cssat._checks.FieldError` under that group's name.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator

from cssat._checks import FieldError, choice_param, device_param, dtype_param, float_param, int_param, progress_param
from cssat._threads import one_thread  # re-exported: where the stages import it from

if TYPE_CHECKING:
    import torch

__all__ = ["Run", "as_field", "one_thread", "FIGURE_FORMATS", "StageOrderError"]

#: the figure file formats (``figure_format``)
FIGURE_FORMATS = ("png", "pdf", "svg")


class StageOrderError(RuntimeError):
    """A forward model's stage run before a stage it needs, or reading the result of a stage it
    does not declare in its model's ``needs``."""


@contextmanager
def as_field(prefix: str) -> Iterator[None]:
    """Within the block, a :class:`FieldError` gets ``prefix`` before its field and any other
    ``ValueError`` becomes a ``FieldError`` of ``prefix`` (the library's message kept)."""
    try:
        yield
    except FieldError as err:
        raise err.within(prefix) from err
    except ValueError as err:
        raise FieldError(prefix, str(err)) from err


@dataclass
class Run:
    """The settings of one run and what it accumulates (``seconds``: stage → time)."""

    out_dir: Path
    dtype: torch.dtype
    device: torch.device
    seed: int
    progress: bool | None = None
    figure_format: str = "png"
    memory_limit_gb: float | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    stages_done: list[str] = field(default_factory=list)  #: the forward model's stages run so far, in order
    results: dict[str, Any] = field(default_factory=dict)  #: each stage's result (what its method returned), by stage
    needs: dict[str, tuple[str, ...]] = field(default_factory=dict)  #: the running model's declared needs
    current: str | None = None  #: the stage running now

    @classmethod
    def from_config(cls, cfg: Any, out_dir: str | Path) -> Run:
        """The top-level settings of ``cfg``, each checked (a :class:`FieldError` naming it)."""
        limit = cfg.get("memory_limit_gb")
        return cls(
            out_dir=Path(out_dir),
            dtype=dtype_param(cfg.get("dtype", "float32")),
            device=device_param(cfg.get("device", "cpu")),
            seed=int_param(cfg.get("seed", 0), "seed", 0, 2**63 - 1),
            progress=progress_param(cfg.get("progress")),
            figure_format=choice_param(cfg.get("figure_format", "png"), "figure_format", FIGURE_FORMATS),
            memory_limit_gb=None if limit is None else float_param(limit, "memory_limit_gb", 0.0, 1e6, open_lo=True),
        )

    @property
    def dtype_name(self) -> str:
        return str(self.dtype).replace("torch.", "")

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block into ``seconds[name]`` (added up over repeated stages)."""
        t = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t

    def result(self, stage: str) -> Any:
        """The result of ``stage`` (what its method returned) for the stage running now, which must
        declare ``stage`` among its model's ``needs`` (a :class:`StageOrderError` otherwise)."""
        if self.current is not None and stage not in self.needs.get(self.current, ()):
            raise StageOrderError(f"stage {self.current!r} reads the result of {stage!r}, which its model's needs do not "
                                  f"declare ({self.current!r} needs {self.needs.get(self.current, ())!r})")
        if stage not in self.results:
            raise StageOrderError(f"the result of {stage!r} is asked for before {stage!r} ran")
        return self.results[stage]

    def add_seconds(self, name: str, value: float) -> None:
        self.seconds[name] = self.seconds.get(name, 0.0) + float(value)

    def timings(self) -> dict[str, float]:
        """``{"seconds_<stage>": time}`` of every stage so far."""
        return {f"seconds_{k}": v for k, v in self.seconds.items()}

    def figure(self, stem: str) -> Path:
        """``out_dir/figures/<stem>.<figure_format>``."""
        return self.out_dir / "figures" / f"{stem}.{self.figure_format}"
