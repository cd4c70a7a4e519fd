"""The scripts in examples/ run, at small sizes, as a user would run them."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(tmp_path, name, *args):
    res = subprocess.run([sys.executable, str(EXAMPLES / name), *args], capture_output=True, text=True,
                         cwd=tmp_path, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "Warning" not in res.stderr, res.stderr
    return res.stdout


def db(text, label):
    return float(re.search(label + r"\s*:?\s*PSNR\s+([\d.]+) dB", text).group(1))


def test_every_example_is_tested():
    tested = {"light_curve_of_a_mesh.py", "reconstruction.py", "custom_solver.py", "training_pairs.py"}
    assert {p.name for p in EXAMPLES.glob("*.py")} == tested


def test_light_curve_of_a_mesh(tmp_path):
    out = run(tmp_path, "light_curve_of_a_mesh.py", "--steps", "60", "--size", "32", "--out", "fig.png")
    lo, hi = (float(v) for v in re.search(r"V = ([\d.]+) \.\. ([\d.]+)", out).groups())
    assert 3 < lo <= hi < 20  # a lit GEO satellite of a few metres: magnitude ~10
    assert (tmp_path / "fig.png").read_bytes()[:4] == b"\x89PNG"


def flat_psnr(size):
    """The PSNR of the flat image (every pixel the mean) of the TESS target at ``size``: what the
    total flux alone gives, the floor a reconstruction must beat."""
    import numpy as np

    from cssat.data import load_target

    t = load_target("tess", size)
    return 10 * np.log10(1 / np.mean((t - t.mean()) ** 2))


@pytest.mark.slow
def test_reconstruction(tmp_path):
    out = run(tmp_path, "reconstruction.py", "--size", "32", "--ratio", "0.6", "--out", "rec.png")
    assert db(out, r"K = \d+") > flat_psnr(32) + 3  # 14.6 dB flat; OMP gives ~19
    assert (tmp_path / "rec.png").stat().st_size > 1000


def test_custom_solver(tmp_path):
    out = run(tmp_path, "custom_solver.py", "--size", "24")
    floor = flat_psnr(24)
    assert db(out, "flat image") == pytest.approx(floor, abs=0.01)
    for name, above in (("Tikhonov", 1.5), ("OMP", 3), ("TV", 10), ("Landweber", 2.5)):
        assert db(out, name) > floor + above, out


def test_training_pairs(tmp_path):
    out = run(tmp_path, "training_pairs.py", "--size", "24", "--n", "64")
    assert "batch (64, 1, 24, 24) -> light curves (64, 288)" in out
    ls, flat = (float(v) for v in re.search(r"median PSNR ([\d.]+) dB \(flat images: ([\d.]+) dB\)", out).groups())
    assert ls > flat + 2  # 23.7 dB against 19.9 for the flat images of the same batch
