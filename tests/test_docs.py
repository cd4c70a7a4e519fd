"""The documentation site (``docs/``, ``mkdocs.yml``): it builds without a warning (broken links
and anchors included: ``mkdocs.yml`` makes them warnings, ``--strict`` makes warnings errors),
every exported name has an API entry (generated from ``__all__``), the tables of experiments and config groups are the
YAML files of ``conf/``, and the pages carry no issue numbers. The build is skipped where MkDocs
is not installed (``pip install -e '.[docs]'``); CI installs it and also runs the build itself."""

from __future__ import annotations

import ast
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: the packages whose public API (``__all__``) has a page ``docs/api/<name>.md``
API = ("data", "inversion", "catalogue", "occultation", "recon", "sparse", "physics", "optics", "scene", "reference",
       "metrics", "plots")


def _exported(package: str) -> list[str]:
    """``cssat.<package>.__all__``, read from the source (nothing imported)."""
    path = ROOT / "cssat" / package / "__init__.py"
    if not path.exists():
        path = ROOT / "cssat" / f"{package}.py"
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return [ast.literal_eval(e) for e in node.value.elts]
    raise AssertionError(f"cssat.{package} has no __all__")


def _pages() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if "_ext" not in p.parts)


@pytest.mark.slow  # ~10 s: the whole site with its API pages
@pytest.mark.skipif(not all(importlib.util.find_spec(m) for m in ("mkdocs", "mkdocstrings_handlers.python", "material")),
                    reason="the docs extra is not installed: pip install -e '.[docs]'")
def test_site_builds_strict(tmp_path):
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    assert not re.search(r"^WARNING", out.stderr, re.M), out.stderr[-3000:]
    site = tmp_path / "site"
    for page in ("index.html", "guides/light-curves/index.html", "api/inversion/index.html"):
        assert (site / page).exists(), page
    # every exported name has its entry, with the docstring read from the source
    # (a name that is also a submodule's, e.g. the function cssat.inversion.egi beside egi.py, is
    # documented under its defining module's path: the entry must be the function, not the module)
    for package in API:
        html = (site / "api" / package / "index.html").read_text(encoding="utf-8")
        kinds = {m.group(2): m.group(1) for m in re.finditer(
            rf'<div class="doc doc-object doc-(\w+)">\s*<h2 id="cssat\.{package}\.(?:\w+\.)?(\w+)"', html)}
        missing = [n for n in _exported(package) if n not in kinds]
        assert not missing, f"cssat.{package}: no API entry for {missing}"
        modules = [n for n in _exported(package) if kinds[n] == "module"]
        assert not modules, f"cssat.{package}: the entry of {modules} shows a module, not the exported object"
    api = (site / "api" / "inversion" / "index.html").read_text(encoding="utf-8")
    assert "not periodic" in api  # estimate_period's docstring, not a placeholder
    assert ":func:`" not in api and ":class:`" not in api  # Sphinx roles rendered as code


def test_every_package_has_an_api_page():
    """Each API page lists its package's exports (``docs/_ext/api_pages.py`` expands the marker
    from ``__all__`` at build time: a new public name needs no page edit)."""
    import importlib
    import importlib.util as iu

    spec = iu.spec_from_file_location("api_pages", DOCS / "_ext" / "api_pages.py")
    hook = iu.module_from_spec(spec)
    spec.loader.exec_module(hook)
    for package in API:
        page = (DOCS / "api" / f"{package}.md").read_text(encoding="utf-8")
        assert f"<!-- exports: cssat.{package} -->" in page, package
        expanded = hook.on_page_markdown(page)
        # the package's exports, then those of any of its modules given a section of their own
        modules = re.findall(rf"^<!-- exports: (cssat\.{package}\.\w+) -->$", page, re.M)
        assert re.findall(rf"^::: cssat\.{package}\.(?:\w+\.)?(\w+)$", expanded, re.M) == _exported(package) + [
            n for m in modules for n in importlib.import_module(m).__all__]
    pages = {p.stem for p in (DOCS / "api").glob("*.md")} - {"index"}
    assert pages == set(API)


def test_every_page_is_in_the_navigation():
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for page in _pages():
        assert f": {page.relative_to(DOCS).as_posix()}" in nav, page


def test_experiment_and_group_tables_are_conf():
    guide = (DOCS / "guides" / "experiments.md").read_text(encoding="utf-8")
    every = guide.split("## Every experiment", 1)[1].split("\n## ", 1)[0]
    listed = re.findall(r"^\| `(\w+)` \|", every, re.M)
    assert sorted(listed) == sorted(p.stem for p in (ROOT / "conf" / "experiment").glob("*.yaml"))
    groups = guide.split("## Config groups", 1)[1].split("\n## ", 1)[0]
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^\| `(\w+)` \| (.*?) \|", groups, re.M)}
    for group in sorted(p for p in (ROOT / "conf").iterdir() if p.is_dir() and list(p.glob("*.yaml"))):
        assert group.name in rows, f"config group {group.name} missing from the table"
        options = set(re.findall(r"`(\w+)`", rows[group.name]))
        for yaml in group.glob("*.yaml"):
            assert yaml.stem in options, f"{group.name}={yaml.stem} missing from the table"


def test_figures_are_shown():
    text = "".join(p.read_text(encoding="utf-8") for p in _pages())
    for png in DOCS.glob("*.png"):
        assert f"]({png.name})" in text or f"](../{png.name})" in text, f"{png.name} is on no page"


def test_cited_benchmark_sections_exist():
    """A page that sends the reader to BENCHMARKS.md names a section that is there."""
    from test_readme import benchmark_sections, cited_sections

    titles = benchmark_sections()
    cited = [(page.name, title) for page in _pages() for title in cited_sections(page.read_text(encoding="utf-8"))]
    assert len(cited) >= 10
    for page, title in cited:
        assert any(t.startswith(title) for t in titles), f"{page}: BENCHMARKS.md has no section '{title}'"


def test_no_issue_numbers_in_the_pages():
    for page in _pages():
        text = page.read_text(encoding="utf-8")
        found = re.findall(r".{0,40}\b[Ii]ssues? ?#?\d+.{0,20}|.{0,40}(?<![\w&`])#\d+\b.{0,20}", text)
        assert not found, f"{page.relative_to(ROOT)}: {found}"
