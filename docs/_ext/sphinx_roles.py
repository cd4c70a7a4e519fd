"""A griffe extension for the API pages: cssat's docstrings are written with Sphinx roles
(``:func:`name```, ``:class:`~a.b.C```) and reST literal blocks (a paragraph ending in ``::``).
mkdocstrings renders Markdown, so each role becomes a code span of its target (``~`` keeps the
last name, as Sphinx shows it) and ``::`` ends the paragraph with ``:``; the text is otherwise
as written. Loaded by mkdocs.yml (``extensions:``); not part of the cssat package."""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|class|mod|data|meth|attr|obj|exc|const|term|ref):`(~?)([^`]+)`")
LITERAL = re.compile(r"(\S)::[ \t]*$", re.MULTILINE)


def _role(match: re.Match) -> str:
    tilde, target = match.groups()
    target = target.strip()
    if "<" in target and target.endswith(">"):  # :ref:`text <target>`
        target = target.split("<", 1)[0].strip()
    if tilde:
        target = target.rsplit(".", 1)[-1]
    return f"`{target}`"


def markdown(text: str) -> str:
    """The docstring with Sphinx roles as code spans and reST ``::`` as ``:``."""
    return LITERAL.sub(r"\1:", ROLE.sub(_role, text))


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring once, as it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)
