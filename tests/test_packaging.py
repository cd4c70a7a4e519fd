"""What a plain install gives: the fast (numba) path, the wavelet denoiser, cssat's own CLI."""

import subprocess
import sys
from importlib import metadata
from pathlib import Path

import cssat


def test_numba_and_pywavelets_are_core_requirements():
    core = [r for r in metadata.requires("cssat") if "extra ==" not in r]
    names = {r.split(";")[0].split(">")[0].split("=")[0].split("<")[0].strip().lower() for r in core}
    assert {"numba", "pywavelets", "torch", "charset-normalizer"} <= names
    from cssat.sparse import _numba

    assert _numba.available()  # the README's install gives the compiled OMP and render kernels


def test_project_files_exist():
    root = Path(__file__).resolve().parents[1]  # the tests are part of the checkout they test
    for name in ("pyproject.toml", "README.md", "LICENSE", "CITATION.cff", "CHANGELOG.md", "BENCHMARKS.md", ".ci/run",
                 "cssat/py.typed", "conf/config.yaml"):
        assert (root / name).exists(), name
    assert "BSD 3-Clause" in (root / "LICENSE").read_text()


def test_cli_version_and_help():
    out = subprocess.run([sys.executable, "-m", "cssat.app", "--version"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == f"cssat {cssat.__version__}"
    out = subprocess.run([sys.executable, "-m", "cssat.app", "--help"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0
    for word in ("Experiments", "atmosphere: ", "phase_screen", "Examples", "cssat -m sweep=m"):
        assert word in out.stdout, word
    # the experiments are listed from conf/experiment/: every YAML there, and nothing else
    from cssat.experiments import experiment_names

    listed = next(line for line in out.stdout.splitlines() if line.startswith("experiment: "))
    assert listed.split(": ", 1)[1].split(", ") == experiment_names()


def test_every_public_function_has_type_hints():
    """Every argument and return of the public API is annotated (modules and names without a
    leading underscore; ``self``/``cls`` and ``__init__``'s return excepted)."""
    import ast

    root = Path(cssat.__file__).parent
    missing, seen = [], 0
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root)
        if any(part.startswith("_") and part != "__init__.py" for part in rel.parts):
            continue

        def visit(node, prefix="", in_class=False):
            nonlocal seen
            for n in ast.iter_child_nodes(node):
                if isinstance(n, ast.ClassDef) and not n.name.startswith("_"):
                    visit(n, f"{prefix}{n.name}.", True)
                elif isinstance(n, ast.FunctionDef) and (not n.name.startswith("_") or n.name in ("__init__", "__call__")):
                    seen += 1
                    args = n.args.posonlyargs + n.args.args + n.args.kwonlyargs
                    if in_class and args and args[0].arg in ("self", "cls"):
                        args = args[1:]
                    args += [a for a in (n.args.vararg, n.args.kwarg) if a is not None]
                    bad = [a.arg for a in args if a.annotation is None]
                    if n.returns is None and n.name != "__init__":
                        bad.append("return")
                    if bad:
                        missing.append(f"{rel}:{n.lineno} {prefix}{n.name}: {', '.join(bad)}")

        visit(ast.parse(f.read_text()))
    assert seen > 200
    assert not missing, "\n".join(missing)


def test_every_package_directory_is_found_by_setuptools():
    """setup.py finds the packages (``find_packages``: directories with an ``__init__.py``): every
    directory of ``cssat/`` and ``conf/`` that holds code or configs must have one, or the wheel
    leaves it out (``cssat.inversion`` and ``cssat.occultation`` once were). The CI runs every
    experiment from the built wheel (``python -m cssat.smoke``)."""
    root = Path(__file__).resolve().parents[1]
    missing = []
    for top, kinds in (("cssat", ("*.py",)), ("conf", ("*.py", "*.yaml"))):
        for d in [root / top, *sorted(p for p in (root / top).rglob("*") if p.is_dir())]:
            if d.name == "__pycache__" or d.relative_to(root).as_posix() == "cssat/_hydra_plugin":
                continue  # the launcher ships as hydra_plugins.cssat_launcher (mapped in setup.py)
            if any(next(d.glob(k), None) for k in kinds) and not (d / "__init__.py").is_file():
                missing.append(d.relative_to(root).as_posix())
    assert not missing, f"no __init__.py (setuptools would leave them out of the wheel): {missing}"


def test_every_experiment_has_a_smoke_size():
    from cssat.experiments import experiment_names
    from cssat.smoke import TINY

    assert sorted(TINY) == experiment_names()
