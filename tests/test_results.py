"""A run's results are one set: kills, stale or damaged files, changed inputs, two runs at once,
the user's umask (issue 13)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_module

from cssat.experiments import run_experiment
from cssat.experiments.results import check_complete, load_saved

APP = [sys.executable, "-m", "cssat.app"]
SMALL = ["target.size=16", "threads=1", "denoiser.n_iter=2"]


def cfg_of(*overrides):
    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def consistent(d: Path) -> bool:
    """A directory is either without a complete set, or its metrics describe its files."""
    saved = load_saved(d)
    if saved is None or saved.get("status") != "ok":
        return True
    arrays = np.load(d / "arrays.npz")
    return len(arrays["y"]) == saved["m"] and check_complete(d, saved, saved["config_sha"], cfg_of(*SMALL, f"cs.m={saved['m']}")) is None


@pytest.mark.slow
def test_a_kill_while_writing_never_leaves_new_arrays_beside_old_metrics(tmp_path):
    d = tmp_path / "run"
    assert subprocess.run(APP + SMALL + ["cs.m=200", f"hydra.run.dir={d}"], capture_output=True, cwd=tmp_path).returncode == 0
    before = (d / "arrays.npz").stat().st_mtime_ns
    proc = subprocess.Popen(APP + SMALL + ["cs.m=100", f"hydra.run.dir={d}"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t = time.time()
    while time.time() - t < 120 and proc.poll() is None:  # kill as soon as arrays.npz changes
        try:  # stat once: the file may vanish between an exists() and a stat() (the new run retracting the old)
            changed = (d / "arrays.npz").stat().st_mtime_ns != before
        except FileNotFoundError:
            changed = True  # removed: the new run is replacing it, kill now
        if changed:
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.002)
    proc.wait()
    assert consistent(d)
    assert load_saved(d) is None or load_saved(d)["m"] == 100
    # the old run's config is not "complete" any more: it runs again
    res = subprocess.run(APP + SMALL + ["cs.m=200", f"hydra.run.dir={d}"], capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 0 and "skipped" not in res.stdout + res.stderr
    assert consistent(d) and load_saved(d)["m"] == 200


def test_moving_another_set_aside_retracts_its_status_before_its_files(tmp_path, monkeypatch):
    """``move_aside`` interrupted after its first move (a kill, simulated: the second
    ``os.replace`` raises) leaves no ``ok`` status beside a set whose files are gone — the race
    the kill test above hits once in a while when it kills just as ``arrays.npz`` vanishes."""
    import cssat.experiments.results as R

    for name in ("arrays.npz", "lightcurve.csv"):
        (tmp_path / name).write_bytes(b"x")
    saved = {"status": "ok", "experiment": "sim1", "config_sha": "aaa", "files": {"arrays.npz": "h", "lightcurve.csv": "h"}}
    (tmp_path / "metrics.json").write_text("{}")
    moved, real = [], os.replace

    def replace_then_die(src, dst):
        if moved:
            raise KeyboardInterrupt("killed")
        moved.append(Path(src).name)
        real(src, dst)

    monkeypatch.setattr(R.os, "replace", replace_then_die)
    with pytest.raises(KeyboardInterrupt):
        R.move_aside(tmp_path, saved, "sim1", "bbb")
    assert moved == ["metrics.json"] and not (tmp_path / "metrics.json").exists()
    assert (tmp_path / "arrays.npz").exists() and (tmp_path / "previous" / "sim1-aaa" / "metrics.json").exists()


@pytest.mark.parametrize("delay", [0.3, 1.0, 2.0, 3.0])
def test_kills_at_any_moment_then_resume(tmp_path, delay):
    d = tmp_path / "run"
    proc = subprocess.Popen(APP + SMALL + ["cs.m=150", f"hydra.run.dir={d}"], cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(delay)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    if d.exists():
        assert consistent(d)
    if d.exists():
        assert wait_until(lambda: not list(d.rglob(".*.tmp")))  # the kill left no temporary file
    # the rerun through the library in this process (the kill is what needs a process of its own)
    assert run_experiment(cfg_of(*SMALL, "cs.m=150"), d)["status"] == "ok"
    assert consistent(d) and load_saved(d)["status"] == "ok"
    assert not list(d.rglob(".*.tmp"))


def wait_until(cond, seconds=120.0) -> bool:
    """Poll ``cond`` until it holds (an asynchronous event: the guardian's clean-up after a kill);
    ``False`` only if it never does within a limit far beyond any load — no speed is asserted."""
    t = time.time()
    while not cond():
        if time.time() - t > seconds:
            return False
        time.sleep(0.02)
    return True


# A writer killed in the middle of writing a file: its temporary file exists, then is gone.
WRITER = """
import sys, time
from pathlib import Path
from cssat._tmpfiles import atomic_write as _atomic
def w(tmp):
    Path(tmp).write_text("part")
    Path(sys.argv[2]).write_text(tmp)  # tell the test where
    time.sleep(600)
_atomic(Path(sys.argv[1]), w)
"""


@pytest.mark.parametrize("how", ["SIGKILL", "SIGKILL to the process group", "SIGTERM", "exception"])
def test_a_killed_writer_leaves_no_temporary_file(tmp_path, how):
    target, where = tmp_path / "out" / "metrics.json", tmp_path / "where"
    code = WRITER if how != "exception" else WRITER.replace("time.sleep(600)", "raise SystemExit(3)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(target), str(where)], start_new_session=True)
    assert wait_until(lambda: where.exists() and where.read_text() or proc.poll() is not None, 60)
    tmp = Path(where.read_text())
    assert tmp.parent == target.parent and tmp.name.startswith(".metrics.json.") and tmp.name.endswith(".tmp")
    if how == "SIGKILL":
        proc.send_signal(signal.SIGKILL)
    elif how == "SIGTERM":
        proc.send_signal(signal.SIGTERM)
    elif how == "SIGKILL to the process group":
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert wait_until(lambda: not tmp.exists()), f"{tmp} left behind"
    assert not target.exists()  # nothing half-written where the result is expected


@pytest.mark.parametrize("damage", ["truncate arrays", "delete figure", "replace image", "zero arrays", "edit psnr",
                                    "edit a file hash"])
def test_resume_skips_only_a_complete_current_set_and_says_why(tmp_path, damage, caplog):
    from PIL import Image

    img = tmp_path / "target.png"
    Image.fromarray((np.arange(256).reshape(16, 16) % 251).astype(np.uint8)).save(img)
    over = [*SMALL, "cs.m=150", f"target.image={img}"]
    d = tmp_path / "run"
    run_experiment(cfg_of(*over), d)
    with caplog.at_level("INFO", logger="cssat"):
        run_experiment(cfg_of(*over), d)
    assert "skipped" in caplog.text
    caplog.clear()
    if damage == "truncate arrays":
        data = (d / "arrays.npz").read_bytes()
        (d / "arrays.npz").write_bytes(data[: len(data) // 2])
    elif damage == "zero arrays":
        data = bytearray((d / "arrays.npz").read_bytes())
        data[100:200] = bytes(100)
        (d / "arrays.npz").write_bytes(bytes(data))
    elif damage == "delete figure":
        (d / "figures" / "fig9_sim1.png").unlink()
    elif damage in ("edit psnr", "edit a file hash"):  # metrics.json itself, edited by hand (still valid JSON)
        import json

        saved = json.loads((d / "metrics.json").read_text())
        if damage == "edit psnr":
            saved["psnr"] = 99.0
        else:  # the manifest made to agree with a replaced array file
            (d / "arrays.npz").write_bytes(b"not the arrays")
            from cssat.experiments.results import file_hash

            saved["files"]["arrays.npz"] = file_hash(d / "arrays.npz")
        (d / "metrics.json").write_text(json.dumps(saved, indent=2))
    else:  # the image behind target.image replaced at the same path
        Image.fromarray((255 - np.arange(256).reshape(16, 16) % 251).astype(np.uint8)).save(img)
    with caplog.at_level("INFO", logger="cssat"):
        met = run_experiment(cfg_of(*over), d)
    assert "skipped" not in caplog.text and "running again" in caplog.text
    reason = {"truncate arrays": "arrays.npz", "zero arrays": "arrays.npz", "delete figure": "fig9_sim1.png",
              "replace image": "input file", "edit psnr": "metrics.json changed",
              "edit a file hash": "metrics.json changed"}[damage]
    assert reason in caplog.text
    assert met["status"] == "ok" and check_complete(d, load_saved(d), met["config_sha"], cfg_of(*over)) is None
    assert load_saved(d)["psnr"] != 99.0


@pytest.mark.slow
def test_two_runs_into_one_directory_one_is_refused(tmp_path):
    refused = 0
    for trial in range(3):
        d = tmp_path / f"run{trial}"
        procs = [subprocess.Popen(APP + SMALL + [f"cs.m={m}", f"hydra.run.dir={d}"], cwd=tmp_path,
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) for m in (150, 200)]
        outs = [p.communicate(timeout=300)[0] for p in procs]
        codes = sorted(p.returncode for p in procs)
        if codes == [0, 0]:  # the second started after the first had finished: both ran, in turn
            pass
        else:
            assert codes == [0, 2], outs
            refused += 1
            loser = outs[[p.returncode for p in procs].index(2)]
            assert "hydra.run.dir" in loser and "in use by another cssat run" in loser
        saved = load_saved(d)
        overrides = (d / ".hydra" / "overrides.yaml").read_text()
        assert f"cs.m={saved['m']}" in overrides  # the results and .hydra/ belong to the same run
        assert consistent(d)
        if refused:  # the race happened and was refused: the trials after it would only repeat it
            break
    assert refused >= 1  # the race happened (both start at once; a run takes seconds)


def test_result_files_follow_the_umask(tmp_path):
    d = tmp_path / "run"
    res = subprocess.run(["bash", "-c", f"umask 022 && {' '.join(APP + SMALL)} cs.m=100 hydra.run.dir={d}"],
                         capture_output=True, text=True, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    for name in ("metrics.json", "arrays.npz", "figures/fig9_sim1.png"):
        assert (d / name).stat().st_mode & 0o777 == 0o644, name


SIM3 = ["experiment=sim3", "target.size=16", "cs.m=200", "threads=1", "reference.pool=300", "reference.n=200",
        "reference.repeats=1", "reference.n_nonzero_coefs=10", "reference.baseline=false", "denoiser=none",
        "denoiser@denoiser3d=none"]


@pytest.mark.parametrize("damage", ["zero half in place", "truncate", "garbage", "empty", "swap with another entry"])
def test_a_damaged_cache_entry_is_logged_removed_and_rendered_again(tmp_path, damage, caplog):
    """Through the cache itself (the experiments read their reference sets through it): a damaged
    entry is named in a warning, rendered again to the same images, and stored again intact."""
    from cssat.experiments.refsets import reference_set
    from cssat.scene.models import astra_like

    cache, mesh = str(tmp_path / "cache"), astra_like()
    args = dict(size=16, n=300, seed=0, noise=0.01, shadows=True, progress=False)
    first, read = reference_set(cache, mesh=mesh, **args)
    assert not read
    (entry,) = (tmp_path / "cache").glob("refs-*.npy")
    if damage == "zero half in place":
        with open(entry, "r+b") as f:
            size = entry.stat().st_size
            f.seek(size // 2)
            f.write(bytes(size - size // 2))
    elif damage == "truncate":
        entry.write_bytes(entry.read_bytes()[:1000])
    elif damage == "garbage":
        entry.write_bytes(os.urandom(5000))
    elif damage == "empty":
        entry.write_bytes(b"")
    else:  # a valid array of the right shape, but not this entry's
        np.save(entry, np.zeros((300, 16, 16), np.float32))
    with caplog.at_level("WARNING", logger="cssat"):
        again, read = reference_set(cache, mesh=mesh, **args)
    assert str(entry) in caplog.text and "damaged" in caplog.text
    assert not read and np.array_equal(again.numpy(), first.numpy())  # rendered again: the same images
    third, read = reference_set(cache, mesh=mesh, **args)
    assert read and np.array_equal(third.numpy(), first.numpy())  # and stored again, intact


def test_concurrent_runs_share_one_cache_entry(tmp_path):
    cache = tmp_path / "cache"
    procs = [subprocess.Popen(APP + SIM3 + [f"cache_dir={cache}", f"hydra.run.dir={tmp_path / str(i)}"], cwd=tmp_path,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for i in range(2)]
    assert [p.wait(timeout=300) for p in procs] == [0, 0]
    met = [load_saved(tmp_path / str(i)) for i in range(2)]
    assert sorted(m["reference_cached"] for m in met) == [False, True]  # one rendered, the other waited and read it
    assert met[0]["psnr"] == met[1]["psnr"]
    assert len(list(cache.glob("refs-*.npy"))) == 1 and len(list(cache.glob("refs-*.json"))) == 1
    mask = os.umask(0)
    os.umask(mask)
    for p in [*cache.glob("refs-*.npy"), *cache.glob("refs-*.json")]:
        assert p.stat().st_mode & 0o777 == 0o666 & ~mask  # shared with collaborators as the umask says
