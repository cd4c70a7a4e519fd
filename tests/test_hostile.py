"""A hostile user's inputs (issue 21, points 1–5): no silent-wrong result, every command-line
mistake exits 2 in one line naming the key and what is allowed, value crashes become checks
before work, environment faults end in one line (exit 1), adversarial cache entries."""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from conftest import run_cli

APP = [sys.executable, "-m", "cssat.app"]
SMALL = ["target.size=16", "threads=1", "denoiser=none"]


def run_app(args, cwd, timeout=300):
    res = subprocess.run(APP + list(args), capture_output=True, text=True, cwd=cwd, timeout=timeout)
    lines = [ln for ln in (res.stdout + res.stderr).splitlines() if ln.strip()]
    return res.returncode, lines


# ------------------------------------------------------------------ 2. command-line mistakes

CLI_MISTAKES = [
    (["foo=1"], "foo", "cs, "),
    (["cs.foo=1"], "cs.foo", "m, ratio"),
    (["solver.foo=1"], "solver.foo", "n_nonzero_coefs"),
    (["atmosphere=nonexistent"], "atmosphere", "gaussian, lognormal"),
    (["noise=loud"], "noise", "photometric"),
    (["solver=magic"], "solver", "l1, landweber"),
    (["denoiser=magic"], "denoiser", "sparse_ksvd"),
    (["target=mars"], "target", "camera"),
    (["experiment=nonexistent"], "experiment", "sim1, sim2, sim3"),
    (["denoiser=null"], "denoiser", "sparse_ksvd"),
    (["scenario.tle=x"], "scenario.tle", "no such key"),
    (["cs.m=[1"], "cs.m", "cannot parse"),
    (["-m", "solver=omp,l1,bogus"], "solver", "'bogus'"),
    (["optimized_metric=psnrr"], "optimized_metric", "'psnr'"),
]


#: the mistakes run in a process of their own, as a user's shell sees them (a composition error and a
#: sweep's); the others through the console script's ``main()`` in this process (``conftest.run_cli``),
#: which gives the same exit code and lines without a process's start-up (a few seconds each)
IN_A_PROCESS = (0, 12)


def test_a_command_line_mistake_exits_2_in_one_line(tmp_path):
    failures = []
    for i, (args, key, allowed) in enumerate(CLI_MISTAKES):
        run = run_app if i in IN_A_PROCESS else run_cli
        code, lines = run([*args, f"hydra.run.dir={tmp_path / f'r{i}'}", f"hydra.sweep.dir={tmp_path / f's{i}'}"], tmp_path)
        if not (code == 2 and len(lines) == 1 and key in lines[0] and allowed in lines[0]
                and "Traceback" not in lines[0] and "HYDRA_FULL_ERROR" not in lines[0]):
            failures.append(f"{args}: exit {code}: {lines}")
    assert not failures, "\n".join(failures)


def test_help_and_cfg_keep_working(tmp_path):
    """Hydra's own flags through ``main()`` in this process (``--help`` in a process of its own:
    test_packaging.py)."""
    code, lines = run_cli(["--help"], tmp_path)
    assert code == 0 and any("experiment" in ln for ln in lines)
    code, lines = run_cli(["--cfg", "job", "cs.m=100"], tmp_path)
    assert code == 0 and any(ln.strip() == "m: 100" for ln in lines)


# ------------------------------------------------------------------ 3. value crashes: checks before work

VALUE_CRASHES = [
    (["target.size=2"], "target.size"),
    (["target.size=6", "denoiser=sparse_ksvd"], "target.size"),
    (["target.size=12", "denoiser=sparse_ksvd", "denoiser.block_size=16"], "denoiser.block_size"),
    (["memory_limit_gb=1e308"], "memory_limit_gb"),
    (["atmosphere.mean=1e30"], "phi"),
    (["atmosphere=phase_screen", "atmosphere.site_altitude_m=1e9"], "site_altitude_m"),
    (["experiment=sim2", "model@reference.model=file"], "reference.model.path"),
    (["experiment=lightcurve", "scenario.step_s=1e12"], "scenario.step_s"),
    (["experiment=realism", "grid.axes.1.values=[]"], "grid.axes"),
    (["atmosphere.std=0"], "atmosphere.std"),
    (["cs.m=100", "cs.ratio=5"], "cs.ratio"),
    (["solver.k_ratio=0"], "solver.k_ratio"),
    (["experiment=sim3", "reference.ratio=0"], "reference.ratio"),
    (["experiment=lightcurve", "render.fov_m=0"], "render.fov_m"),
    (["experiment=lightcurve", "model.scale=1e30"], "model.scale"),
    (["experiment=lightcurve", "model.scale=0"], "model.scale"),
    (["experiment=lightcurve", "model.scale=-1"], "model.scale"),
    (["experiment=lightcurve", "model=tess_like", "scenario.n_steps=1000000", "memory_limit_gb=8"], "memory"),
    (["experiment=sim3", "target.size=16", "denoiser3d.block_size=20"], "denoiser3d.block_size"),
    (["denoiser=sparse_ksvd", "denoiser.atom_sparsity=1000"], "denoiser.atom_sparsity"),
    (["denoiser=sparse_ksvd", "denoiser.n_atoms=5000"], "denoiser.n_atoms"),
]


def test_a_bad_value_is_refused_before_any_work_naming_its_field(tmp_path):
    """Each case through the console script's ``main()`` in this process (``conftest.run_cli``):
    exit 2, one ``bad input`` line naming the field, no traceback, no arrays."""
    failures = []
    for i, (args, field) in enumerate(VALUE_CRASHES):
        small = ["threads=1", "denoiser=none"] if "experiment=lightcurve" in args else SMALL
        base = [a for a in small if not any(a.split("=")[0] == b.split("=")[0] for b in args)]
        d = tmp_path / f"r{i}"
        code, lines = run_cli([*base, *args, f"hydra.run.dir={d}"], tmp_path)
        bad = [ln for ln in lines if "bad input" in ln]
        if not (code == 2 and len(bad) == 1 and field in bad[0] and not any("Traceback" in ln for ln in lines)
                and not (d / "arrays.npz").exists()):
            failures.append(f"{args}: exit {code}: {lines}")
    assert not failures, "\n".join(failures)


def test_a_tiny_image_file_is_refused(tmp_path):
    from PIL import Image

    from cssat._checks import FieldError
    from cssat.data.images import load_target

    Image.fromarray(np.zeros((1, 1), np.uint8)).save(tmp_path / "px.png")
    with pytest.raises(FieldError, match="target.image.*1×1"):
        load_target(str(tmp_path / "px.png"), 16)


# ------------------------------------------------------------------ 1. no silent-wrong result

def test_photon_counts_beyond_int64_follow_the_normal_law():
    from cssat.physics.noise import POISSON_NORMAL_ABOVE, _poisson

    gen = torch.Generator().manual_seed(0)
    rate = torch.tensor([1e20] * 4000 + [3.0] * 4000, dtype=torch.float64)
    c = _poisson(rate, gen)
    big, small = c[:4000], c[4000:]
    assert bool(torch.isfinite(c).all()) and float(big.min()) > 0
    # mean and variance of N(λ, λ), against 5-sigma bounds of the sample statistics
    assert abs(float(big.mean()) - 1e20) < 5 * math.sqrt(1e20 / 4000)
    assert abs(float(big.var()) / 1e20 - 1) < 5 * math.sqrt(2 / 4000)
    assert float(small.mean()) == pytest.approx(3.0, abs=5 * math.sqrt(3 / 4000))
    assert bool((small == small.round()).all())  # integer counts below the threshold
    assert POISSON_NORMAL_ABOVE < 9.2e18


def test_a_bright_target_gives_a_finite_noisy_curve(tmp_path):
    from hydra import compose, initialize_config_module

    from cssat.experiments import run_experiment

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=[*SMALL, "noise=photometric", "noise.magnitude=-40"])
    met = run_experiment(cfg, tmp_path)
    y = np.load(tmp_path / "arrays.npz")["y"]
    assert met["status"] == "ok" and np.isfinite(y).all() and met["psnr"] > 10


OBJ = "".join(f"v {x} {y} {z}\n" for x, y, z in [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)])
OBJ += "f 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\nf 2 3 5\nf 3 4 5\n"


@pytest.mark.parametrize("damage, match", [
    ("cut", "ends in the middle of a line"),
    ("two refs", "line 11: a face needs at least 3"),
    ("bad ref", "line 7: a face with a vertex reference"),
    ("past end", "vertex reference 9 outside"),
])
def test_a_cut_or_malformed_obj_is_refused(tmp_path, damage, match):
    from cssat._checks import FieldError
    from cssat.scene import load_mesh

    text = {"cut": OBJ[:-1], "two refs": OBJ.replace("f 3 4 5", "f 3 4"),
            "bad ref": OBJ.replace("f 1 2 4", "f 1 x 4"), "past end": OBJ.replace("f 3 4 5", "f 3 4 9")}[damage]
    (tmp_path / "m.obj").write_text(text)
    with pytest.raises(FieldError, match=match):
        load_mesh(tmp_path / "m.obj", field="model.path")
    (tmp_path / "ok.obj").write_text(OBJ)
    assert len(load_mesh(tmp_path / "ok.obj").faces) == 6


def test_the_shared_tess_mesh_loads_every_triangle():
    path = Path(__file__).resolve().parents[2] / "shared" / "models" / "tess.obj"
    if not path.exists():
        pytest.skip("../shared/models/tess.obj is not here")
    from cssat.scene import load_mesh

    text = path.read_text(errors="replace").splitlines()
    expected = sum(len(ln.split()) - 3 for ln in text if ln.startswith("f "))  # fan triangulation
    assert len(load_mesh(path).faces) == expected


def test_model_scale_scales_procedural_models():
    from cssat.scene import get_model

    a, b = get_model("astra_like"), get_model("astra_like", scale=2.0)
    np.testing.assert_allclose(b.vertices, 2 * a.vertices)
    assert b.areas.sum() == pytest.approx(4 * a.areas.sum())


def _tle(inclination=None, mean_motion=None, epoch=None):
    from sgp4.io import compute_checksum

    from cssat.scene import ASTRA_1KR_SYNTHETIC_TLE

    l1, l2 = ASTRA_1KR_SYNTHETIC_TLE
    if epoch is not None:
        l1 = l1[:18] + epoch + l1[32:]
    if inclination is not None:
        l2 = l2[:8] + f"{inclination:8.4f}" + l2[16:]
    if mean_motion is not None:
        l2 = l2[:52] + f"{mean_motion:11.8f}" + l2[63:]
    return [l1[:68] + str(compute_checksum(l1)), l2[:68] + str(compute_checksum(l2))]


@pytest.mark.parametrize("kw, match", [({"inclination": 999.0}, "inclination 999"),
                                       ({"mean_motion": 17.0}, "perigee")])
def test_impossible_elements_are_refused(kw, match):
    from cssat._checks import FieldError
    from cssat.scene import make_scenario

    with pytest.raises(FieldError, match=match):
        make_scenario(_tle(**kw), n_steps=2)


def test_elements_far_from_their_epoch_warn(caplog):
    from cssat.scene import make_scenario

    with caplog.at_level("WARNING", logger="cssat"):
        make_scenario(_tle(), start_utc="2020-04-02T00:00:00", n_steps=2)
    assert "epoch" not in caplog.text
    with caplog.at_level("WARNING", logger="cssat"):
        make_scenario(_tle(), start_utc="2021-04-01T00:00:00", n_steps=2)
    assert "365 days after the element set's epoch" in caplog.text


@pytest.mark.parametrize("dtype, scale", [(torch.float32, 1e19), (torch.float32, 1e-30), (torch.float64, 1e200),
                                          (torch.float64, 1e-200)])
def test_batch_omp_is_scale_invariant(dtype, scale):
    from cssat.sparse import batch_omp

    g = torch.Generator().manual_seed(0)
    D = torch.randn(40, 60, generator=g, dtype=torch.float64)
    X = torch.zeros(5, 60, dtype=torch.float64)
    X[:, :3] = torch.randn(5, 3, generator=g, dtype=torch.float64)
    Y = X @ D.T
    ref = batch_omp(D.to(dtype), Y.to(dtype), n_nonzero_coefs=3)
    got = batch_omp((D * scale).to(dtype), (Y * scale).to(dtype), n_nonzero_coefs=3)
    assert bool(torch.isfinite(got).all())
    assert torch.equal(got != 0, ref != 0)  # the same atoms
    torch.testing.assert_close(got.double(), ref.double(), rtol=1e-4, atol=0)
    big = batch_omp((D * scale).to(dtype), Y.to(dtype), n_nonzero_coefs=3)  # D scaled alone: γ / scale
    torch.testing.assert_close((big.double() * scale), ref.double(), rtol=1e-4, atol=1e-12)


def test_batch_omp_refuses_bad_precomputed_inputs_and_complex_data():
    from cssat._checks import FieldError
    from cssat.sparse import batch_omp, ksvd_denoise

    g = torch.Generator().manual_seed(1)
    D, Y = torch.randn(20, 30, generator=g), torch.randn(4, 20, generator=g)
    G = D.T @ D
    bad = G.clone()
    bad[0, 0] = float("nan")
    with pytest.raises(FieldError, match="gram"):
        batch_omp(D, Y, n_nonzero_coefs=3, gram=bad)
    with pytest.raises(FieldError, match="Dty"):
        batch_omp(D, Y, n_nonzero_coefs=3, gram=G, Dty=torch.full((4, 30), float("nan")))
    with pytest.raises(FieldError, match="gram: is not DᵀD"):
        batch_omp(D, Y, n_nonzero_coefs=3, gram=2 * G)
    with pytest.raises(FieldError, match="Dty: is not DᵀY"):
        batch_omp(D, Y, n_nonzero_coefs=3, gram=G, Dty=-(Y @ D))
    with pytest.raises(TypeError, match="Y.*real"):
        batch_omp(D, Y.to(torch.complex64), n_nonzero_coefs=3)
    with pytest.raises(TypeError, match="real"):
        ksvd_denoise(torch.rand(16, 16).to(torch.complex64), 0.1)


@pytest.mark.slow
def test_vector_figures_are_byte_reproducible_across_processes(tmp_path):
    """Two processes, each a sweep over the figure formats (svg, pdf): the same bytes."""
    outs = []
    for k in range(2):
        d = tmp_path / f"sweep{k}"
        code, lines = run_app(["-m", *SMALL, "figure_format=svg,pdf", f"hydra.sweep.dir={d}"], tmp_path)
        assert code == 0, lines
        outs.append({fmt: (d / str(job) / "figures" / f"fig9_sim1.{fmt}").read_bytes() for job, fmt in enumerate(("svg", "pdf"))})
    for fmt in ("svg", "pdf"):
        assert outs[0][fmt] == outs[1][fmt], fmt


def test_threads_are_part_of_the_config_hash():
    from hydra import compose, initialize_config_module

    from cssat.experiments import config_sha

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        a, b = (compose(config_name="config", overrides=[f"threads={t}"]) for t in (1, 2))
        c = compose(config_name="config", overrides=["threads=1", "progress=true"])
    assert config_sha(a) != config_sha(b) and config_sha(a) == config_sha(c)


def test_relative_error_of_a_zero_reference_and_dataset_indices():
    from cssat._checks import FieldError
    from cssat.data import ReferenceImages
    from cssat.reference import relative_error
    from cssat.scene import get_model

    with pytest.raises(FieldError, match="phi"):
        relative_error(torch.ones(3, 3), torch.zeros(3, 3))
    ds = ReferenceImages(get_model("astra_like"), 8, 4, seed=0)
    for bad in (1.7, True, "1"):
        with pytest.raises(TypeError, match="index"):
            ds[bad]
    assert torch.equal(ds[np.int64(1)], ds[1]) and torch.equal(ds[-1], ds[3])


# ------------------------------------------------------------------ 4. environment faults

def _mount_tmpfs(path: Path, size: str, readonly: bool = False) -> bool:
    path.mkdir(parents=True, exist_ok=True)
    opts = f"size={size}" + (",ro" if readonly else "")
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(path)], capture_output=True).returncode == 0
    return ok


def _umount(path: Path) -> None:
    subprocess.run(["umount", "-l", str(path)], capture_output=True)


def test_an_output_path_that_is_a_file_exits_1_in_one_line(tmp_path):
    (tmp_path / "taken").write_text("a file")
    code, lines = run_app([*SMALL, f"hydra.run.dir={tmp_path / 'taken'}"], tmp_path)
    assert code == 1 and len(lines) == 1 and str(tmp_path / "taken") in lines[0] and "not a directory" in lines[0]


def test_a_read_only_directory_exits_1_in_one_line(tmp_path):
    ro = tmp_path / "ro"
    if not _mount_tmpfs(ro, "1m", readonly=True):
        pytest.skip("cannot mount a read-only tmpfs here")
    try:
        code, lines = run_app([*SMALL, f"hydra.run.dir={ro / 'run'}"], tmp_path)
    finally:
        _umount(ro)
    assert code == 1 and len(lines) == 1 and str(ro) in lines[0] and "not writable" in lines[0], lines


def test_a_full_disk_exits_1_in_one_line_and_leaves_no_accepted_set(tmp_path):
    full = tmp_path / "full"
    if not _mount_tmpfs(full, "200k"):
        pytest.skip("cannot mount a small tmpfs here")
    try:
        d = full / "run"
        code, lines = run_app(["target.size=64", "threads=1", "denoiser=none", f"hydra.run.dir={d}"], tmp_path)
        msg = [ln for ln in lines if "cannot write the results" in ln]
        assert code == 1 and len(msg) == 1 and "No space left on device" in msg[0], lines
        assert not any("Traceback" in ln for ln in lines)
        from cssat.experiments.results import load_saved

        saved = load_saved(d)
        assert saved is None or saved.get("status") != "ok"
        assert not list(d.rglob(".*.tmp"))
    finally:
        _umount(full)


# ------------------------------------------------------------------ 5. adversarial cache entries

def _entry(cache: Path):
    (npy,) = cache.glob("refs-*.npy")
    return npy, npy.with_suffix(".json"), npy.with_suffix(".lock")


def _sim2(cache, out):
    from hydra import compose, initialize_config_module

    from cssat.experiments import run_experiment

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["experiment=sim2", "target.size=8", "cs.m=32", "threads=1",
                                                       "denoiser=none", f"cache_dir={cache}"])
    return run_experiment(cfg, out)


@pytest.mark.parametrize("damage", ["meta list", "meta null", "object array", "huge header", "fifo", "dir entry",
                                    "dir lock", "fortran"])
def test_an_adversarial_cache_entry_is_logged_removed_and_rendered_again(tmp_path, damage, caplog):
    cache = tmp_path / "cache"
    first = _sim2(cache, tmp_path / "a")
    npy, meta, lock = _entry(cache)
    good = np.load(npy)
    if damage == "meta list":
        meta.write_text("[]")
    elif damage == "meta null":
        meta.write_text("null")
    elif damage == "object array":
        np.save(npy, np.array([{"a": 1}] * 3, dtype=object), allow_pickle=True)
    elif damage == "huge header":
        header = {"descr": "<f4", "fortran_order": False, "shape": (10**9, 10**4)}
        with open(npy, "wb") as f:
            np.lib.format.write_array_header_1_0(f, header)
    elif damage == "fortran":
        np.save(npy, np.asfortranarray(good))
    elif damage == "fifo":
        npy.unlink()
        os.mkfifo(npy)
    elif damage == "dir entry":
        npy.unlink()
        npy.mkdir()
    else:
        lock.unlink(missing_ok=True)
        lock.mkdir()
    with caplog.at_level("WARNING", logger="cssat"):
        again = _sim2(cache, tmp_path / "b")
    # a damaged entry is rendered again; a directory in place of the lock costs only the lock
    assert again["status"] == "ok" and again["reference_cached"] is (damage == "dir lock")
    assert "reference cache" in caplog.text
    np.testing.assert_array_equal(np.load(npy), good)  # the same set
    assert again["psnr"] == first["psnr"]


def test_a_read_only_cache_with_a_valid_entry_is_used(tmp_path):
    cache = tmp_path / "cache"
    first = _sim2(cache, tmp_path / "a")
    ro = tmp_path / "ro"
    if not _mount_tmpfs(ro, "4m"):
        pytest.skip("cannot mount a tmpfs here")
    try:
        for p in cache.iterdir():
            if p.suffix in (".npy", ".json"):
                (ro / p.name).write_bytes(p.read_bytes())
        subprocess.run(["mount", "-o", "remount,ro", str(ro)], check=True)
        again = _sim2(ro, tmp_path / "b")
    finally:
        _umount(ro)
    assert again["status"] == "ok" and again["reference_cached"] is True and again["psnr"] == first["psnr"]


def test_a_full_cache_disk_costs_the_entry_not_the_run(tmp_path, caplog):
    full = tmp_path / "full"
    if not _mount_tmpfs(full, "8k"):
        pytest.skip("cannot mount a small tmpfs here")
    try:
        with caplog.at_level("WARNING", logger="cssat"):
            met = _sim2(full, tmp_path / "a")
        assert met["status"] == "ok" and "could not write" in caplog.text
        assert not list(full.glob("refs-*.npy")) and not list(full.glob(".*.tmp"))
    finally:
        _umount(full)


def test_measurement_and_dataset_resample_fresh_reproducible_noise():
    from cssat.data import ReferenceImages
    from cssat.physics import GaussianNoise, Measurement
    from cssat.scene import get_model
    from cssat.sparse import GaussianSensing

    op = GaussianSensing(20, 64, seed=0)
    x = torch.rand(64)
    fixed = Measurement(op, GaussianNoise(sigma=0.1), seed=3)
    assert torch.equal(fixed(x), fixed(x))
    fresh, again = (Measurement(op, GaussianNoise(sigma=0.1), seed=3, resample=True) for _ in range(2))
    a1, a2 = fresh(x), fresh(x)
    assert not torch.equal(a1, a2)
    assert torch.equal(again(x), a1) and torch.equal(again(x), a2)  # the same sequence in another run
    fresh.reset()
    assert torch.equal(fresh(x), a1)
    ds = ReferenceImages(get_model("astra_like"), 8, 3, seed=0, noise=0.05, resample=True)
    e0 = ds[0]
    ds.set_epoch(1)
    e1 = ds[0]
    ds.set_epoch(0)
    assert not torch.equal(e0, e1) and torch.equal(ds[0], e0)
    plain = ReferenceImages(get_model("astra_like"), 8, 3, seed=0, noise=0.05)
    plain.set_epoch(5)
    assert torch.equal(plain[0], ReferenceImages(get_model("astra_like"), 8, 3, seed=0, noise=0.05)[0])


def test_subpackages_are_attributes_of_cssat_lazily():
    code = ("import sys, cssat\nassert 'cssat.physics' not in sys.modules\n"
            "import cssat as c\nprint(type(c.physics).__name__, type(c.recon).__name__, type(c.scene).__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.split() == ["module"] * 3, out.stderr
