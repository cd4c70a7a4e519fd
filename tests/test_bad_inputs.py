"""Every input error exits 2 with one line naming the field (issue 13, point 6): a table of bad
inputs, each run through the console script's ``main()`` (in this process: ``conftest.run_cli``)."""

import numpy as np
import pytest
from conftest import run_cli

GOOD_L1 = "1 29055U 06012A   20092.00000000  .00000104  00000-0  00000-0 0  9998"
GOOD_L2 = "2 29055   0.0291 247.7716 0004915 319.3582   1.8831  1.00273365 24812"


def checksum(line: str) -> str:
    s = sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68])
    return line[:68] + str(s % 10)


def files(tmp):
    from PIL import Image

    (tmp / "text.png").write_text("not an image")
    Image.fromarray(np.zeros((10, 12), np.uint8)).save(tmp / "oblong.png")
    good_obj = "".join(f"v {x} {y} {z}\n" for x, y, z in [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)])
    good_obj += "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    (tmp / "cut.obj").write_text(good_obj[: good_obj.index("f 2 3 4")] + "f 2 3 9\n")  # cut mid-file: a face past the vertices
    return tmp


LIGHT = ["experiment=lightcurve", "scenario.n_steps=3", "render.size=8"]
SIM1 = ["target.size=16", "cs.m=100"]
SIM3 = ["experiment=sim3", "target.size=16", "cs.m=100", "reference.n=100", "reference.pool=200"]
CASES = [
    ([*SIM1, "target.image=/nonexistent.png"], "target.image"),
    ([*SIM1, "target.image={tmp}/text.png"], "target.image"),
    ([*SIM1, "target.image={tmp}/oblong.png"], "target.image"),
    ([*SIM1, "target.image={tmp}/bomb.png"], "target.image"),  # 14000² px: PIL's decompression-bomb guard
    ([*SIM1, "seed=18446744073709551616"], "seed"),
    ([*LIGHT, "model=file", "model.path={tmp}/cut.obj"], "model.path"),
    ([*LIGHT, "model=file", "model.path={tmp}/missing.obj"], "model.path"),
    ([*LIGHT, "scenario.start_utc=2090-01-01T00:00:00"], "scenario.start_utc"),
    ([*LIGHT, "scenario.start_utc=yesterday"], "scenario.start_utc"),
    ([*LIGHT, "scenario.observer.alt_m=-1e7"], "scenario.observer.alt_m"),
    ([*LIGHT, "scenario.observer.lat_deg=100"], "scenario.observer.lat_deg"),
    ([*LIGHT, "scenario.n_steps=0"], "scenario.n_steps"),
    ([*LIGHT, "magnitudes.band=B"], "magnitudes.band"),
    ([*LIGHT, f"scenario.tle=['{checksum(GOOD_L1[:18] + '20X92.00000000' + GOOD_L1[32:])}','{GOOD_L2}']"], "scenario.tle.line1"),
    ([*LIGHT, f"scenario.tle=['{GOOD_L1[:-1] + '0'}','{GOOD_L2}']"], "scenario.tle.line1"),
    ([*SIM3, "denoiser3d.n_iter=0"], "denoiser3d.n_iter"),
    ([*SIM3, "reference.model.cd=-1"], "reference.model.cd"),
    ([*SIM1, "atmosphere=phase_screen", "geometry.range_km=0"], "geometry.range_km"),
    ([*SIM1, "noise=photometric", "noise.throughput=2"], "noise.throughput"),
    ([*SIM3, "figure_format=jpg"], "figure_format"),
    ([*SIM3, "progress=sometimes"], "progress"),
    ([*SIM1, "solver.progress=1"], "solver.progress"),
]


@pytest.mark.parametrize("overrides, field", CASES, ids=[c[1] + ":" + c[0][-1][:40] for c in CASES])
def test_a_bad_input_exits_2_naming_its_field(tmp_path, overrides, field):
    files(tmp_path)
    if any("bomb.png" in o for o in overrides):
        from PIL import Image

        Image.new("L", (14000, 14000)).save(tmp_path / "bomb.png")
    args = [o.format(tmp=tmp_path) for o in overrides]
    run = tmp_path / "run"
    code, lines = run_cli(["threads=1", *args, f"hydra.run.dir={run}"], tmp_path)
    assert code == 2, lines
    assert not any("Traceback" in line for line in lines)
    assert [line for line in lines if f"{field}:" in line], lines
    # refused before any work: nothing but the run's bookkeeping where results are expected
    made = [p.name for p in run.rglob("*") if p.is_file() and ".hydra" not in p.parts
            and p.name not in ("metrics.json", "app.log", ".cssat.lock", ".cssat.lock.pid")]
    assert not made, made


def test_an_obj_with_a_non_utf8_comment_is_read(tmp_path):
    from cssat.scene import load_mesh

    obj = b"# caf\xe9 \xff\n" + b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    (tmp_path / "latin1.obj").write_bytes(obj)
    assert len(load_mesh(tmp_path / "latin1.obj")) == 4


def test_a_constant_target_writes_valid_json(tmp_path):
    import json

    from PIL import Image

    Image.fromarray(np.full((16, 16), 128, np.uint8)).save(tmp_path / "flat.png")
    code, lines = run_cli(["target.size=16", "cs.m=256", "threads=1", "solver.epsilon=1e-9", "dtype=float64",
                           "denoiser=none", f"target.image={tmp_path / 'flat.png'}", f"hydra.run.dir={tmp_path / 'run'}"],
                          tmp_path)
    assert code == 0, lines
    text = (tmp_path / "run" / "metrics.json").read_text()
    assert "Infinity" not in text and "NaN" not in text
    json.loads(text)  # strict JSON


def test_inward_facing_mesh_warns(tmp_path, caplog):
    import trimesh

    from cssat.scene import load_mesh

    box = trimesh.creation.box((1, 1, 1))
    box.invert()
    box.export(tmp_path / "inside_out.obj")
    with caplog.at_level("WARNING", logger="cssat"):
        load_mesh(tmp_path / "inside_out.obj")
    assert "face inward" in caplog.text
    caplog.clear()
    trimesh.creation.box((1, 1, 1)).export(tmp_path / "fine.obj")
    with caplog.at_level("WARNING", logger="cssat"):
        load_mesh(tmp_path / "fine.obj")
    assert "face inward" not in caplog.text


def test_render_and_brightness_refuse_bad_values():
    import torch

    from cssat.optics import facet_brightness, render
    from cssat.scene import astra_like

    m = astra_like()
    d = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="^sunlit"):
        facet_brightness(m, d, d, sunlit=1.5)
    b = torch.zeros(1, len(m), dtype=torch.float64)
    b[0, 0] = float("nan")
    with pytest.raises(ValueError, match="^brightness"):
        render(m, d, d, 8, brightness=b)
