"""A MkDocs hook for the API pages: a line ``<!-- exports: cssat.<package> -->`` becomes one
``::: cssat.<package>.<name>`` entry per name of that package's ``__all__``, read from the source
(nothing is imported). A new public name is documented by exporting it: no page to edit.
Loaded by mkdocs.yml (``hooks:``); not part of the cssat package."""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
MARKER = re.compile(r"^<!-- exports: (cssat(?:\.\w+)*) -->$", re.M)


def exports(module: str) -> list[str]:
    """``module.__all__`` from its source file (a package's ``__init__.py`` or a module)."""
    base = ROOT.joinpath(*module.split("."))
    path = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return [ast.literal_eval(e) for e in node.value.elts]
    raise ValueError(f"{module} has no __all__ ({path})")


def entries(module: str) -> list[str]:
    """The object paths of ``module``'s exports. A name that is also a submodule's
    (``cssat.inversion.egi``, the function, beside ``cssat/inversion/egi.py``) is given by the module
    it is imported from, so that the entry is the function or class, not the module."""
    base = ROOT.joinpath(*module.split("."))
    source = {}
    if base.is_dir():
        for node in ast.parse((base / "__init__.py").read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ImportFrom) and node.module:
                source.update({a.asname or a.name: f"{node.module}.{a.name}" for a in node.names})
    paths = []
    for name in exports(module):
        shadowed = base.is_dir() and ((base / f"{name}.py").exists() or (base / name / "__init__.py").exists())
        paths.append(source[name] if shadowed and name in source else f"{module}.{name}")
    return paths


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    return MARKER.sub(lambda m: "\n\n".join(f"::: {path}" for path in entries(m.group(1))), markdown)
