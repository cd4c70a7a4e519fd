"""The layer order of DESIGN.md — data flows down the list, nothing imports upward — read from
the source itself: every ``import`` of every module, function-local ones included (issue 35,
point 3). The arrows that remain to be undone are listed, so no new one can come in unseen."""

from __future__ import annotations

import ast
from pathlib import Path

ORDER = ["scene", "optics", "data", "sparse", "reference", "physics", "inversion", "occultation", "plots", "recon",
         "experiments", "app"]
APP = {"app", "summary", "smoke", "_cli_check"}  # the command line's modules; conf/ is configuration (data files)
#: upward arrows still in the code, to be undone by issue 35 (a forward-model protocol): the
#: occultation's linear solve builds a recon problem; the light-curve datasets measure through
#: the physics layer's atmospheres
KNOWN = {("cssat.data.datasets", "cssat.physics"), ("cssat.occultation.linear", "cssat.recon"),
         ("cssat.occultation.linear", "cssat.recon.problem")}


def _layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "cssat" or len(parts) < 2:
        return None
    if parts[1] in APP:
        return "app"
    return parts[1] if parts[1] in ORDER else None  # base modules (_checks, _record, metrics, …) sit below all


def upward_arrows(root: Path) -> set[tuple[str, str]]:
    """``(importer, imported)`` for every import from a layer into one below it in ``ORDER``."""
    out = set()
    for f in root.rglob("*.py"):
        module = ".".join(f.relative_to(root.parent).with_suffix("").parts).removesuffix(".__init__")
        src = _layer(module)
        if src is None:
            continue
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                dst = _layer(name)
                if dst is not None and ORDER.index(dst) > ORDER.index(src):
                    out.add((module, name))
    return out


def test_no_new_upward_import():
    import cssat

    found = upward_arrows(Path(cssat.__file__).parent)
    assert found <= KNOWN, f"imports against DESIGN.md's layer order: {sorted(found - KNOWN)}"


def test_the_reader_sees_an_upward_import(tmp_path):
    """The check itself: a scene module importing the experiments layer is caught."""
    pkg = tmp_path / "cssat"
    (pkg / "scene").mkdir(parents=True)
    (pkg / "scene" / "bad.py").write_text("def f():\n    from cssat.experiments.files import write_csv\n")
    (pkg / "optics").mkdir()
    (pkg / "optics" / "ok.py").write_text("import numpy\nfrom cssat.scene import orbit\n")
    assert upward_arrows(pkg) == {("cssat.scene.bad", "cssat.experiments.files")}
