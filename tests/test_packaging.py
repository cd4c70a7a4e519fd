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
    root = Path(cssat.__file__).resolve().parent.parent
    if not (root / "pyproject.toml").exists():  # installed, not a checkout
        return
    for name in ("LICENSE", "CITATION.cff", "CHANGELOG.md", "cssat/py.typed"):
        assert (root / name).exists(), name
    assert "BSD 3-Clause" in (root / "LICENSE").read_text()


def test_cli_version_and_help():
    out = subprocess.run([sys.executable, "-m", "cssat.app", "--version"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == f"cssat {cssat.__version__}"
    out = subprocess.run([sys.executable, "-m", "cssat.app", "--help"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0
    for word in ("Experiments", "sim1", "realism", "atmosphere: ", "phase_screen", "Examples", "cssat -m sweep=m"):
        assert word in out.stdout, word
