"""Figures a scientist can publish: colour bars with units, error maps, a scale bar in metres,
a UTC time axis, sweep axes in words, pdf/svg output (issue 14)."""

import numpy as np
import pytest
from hydra import compose, initialize_config_module

from cssat import plots


def images_of(fig):
    """``{title: (array, colour-bar label)}`` of the image panels of ``fig``."""
    out = {}
    for ax in fig.axes:
        if ax.images and ax.get_title():
            cbar = ax.images[0].colorbar
            out[ax.get_title()] = (np.asarray(ax.images[0].get_array()), cbar.ax.get_ylabel() if cbar else None)
    return out


def test_sim1_figure_has_colour_bars_and_true_error_maps():
    rng = np.random.default_rng(0)
    truth = rng.uniform(0, 1, (16, 16))
    rec, den = truth + rng.normal(0, 0.2, truth.shape), truth + rng.normal(0, 0.05, truth.shape)
    metrics = {"m": 100, "n": 16, "psnr": 14.0, "ssim": 0.5, "psnr_denoised": 26.0, "ssim_denoised": 0.9,
               "denoiser": "tv", "solver": "omp", "solver_n_nonzero_coefs": 20}
    panels = images_of(plots.sim1_figure(rng.normal(size=100), rec, den, truth, metrics))
    err_rec, label = panels["|x̂ − x|: reconstruction"]
    np.testing.assert_allclose(err_rec, np.abs(rec - truth))  # the map is the error, computed apart
    np.testing.assert_allclose(panels["|x̂ − x|: denoised"][0], np.abs(den - truth))
    assert "error" in label
    for title, (_, label) in panels.items():
        assert label, f"panel {title!r} has no labelled colour bar"
    assert "intensity" in panels["truth (16×16)"][1] and "flux" in panels["light curve y (m = 100)"][1]


@pytest.mark.parametrize("fov,expected", [(20.0, "5 m"), (3.0, "50 cm"), (41.0, "10 m")])
def test_rendered_satellites_carry_a_scale_bar_in_metres(fov, expected):
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    times = np.datetime64("2020-04-01T00:00") + np.arange(10) * np.timedelta64(1, "m")
    fig = plots.lightcurve_figure(np.arange(10.0), np.linspace(5, 6, 10), np.ones((2, 32, 32)), [2, 7], times,
                                  np.ones(10), fov_m=fov)
    bars = [a for ax in fig.axes for a in ax.artists if isinstance(a, AnchoredSizeBar)]
    assert len(bars) == 2
    text = bars[0].txt_label.get_text()
    assert text == expected
    metres = float(text.split()[0]) * (0.01 if text.endswith("cm") else 1.0)
    width = bars[0].size_bar.get_children()[0].get_width()  # in pixels of the image
    assert width == pytest.approx(metres / fov * 32)
    assert fig.axes[-1].get_xlabel() == "minutes since 2020-04-01 00:00 UTC"


def test_fig5_names_its_axes_plainly():
    fig = plots.atmosphere_figure(np.arange(5.0), np.ones(5), np.ones(5), np.ones(5), epoch=np.datetime64("2020-04-01T06:30"))
    ax = fig.axes[0]
    assert ax.get_xlabel() == "minutes since 2020-04-01 06:30 UTC"
    assert "flux" in ax.get_ylabel() and "magnitude" in ax.get_ylabel()


def test_sweep_plots_are_titled_in_words():
    rows = [{"status": "ok", "cs.m": m, "n_pixels": 1024, "psnr": p, "psnr_denoised": p + 1}
            for m, p in ((256, 15.0), (512, 20.0), (768, 25.0))]
    from cssat.summary import plot_values

    values, names, labels = plot_values(rows, ["cs.m"])  # the summary gives the plot values and words
    ax = plots.sweep_figure(values, names, labels=labels).axes[0]
    assert ax.get_xlabel() == "m / N (measurement ratio)" and ax.get_ylabel() == "PSNR (dB)"
    assert "cs.m" not in ax.get_title() and ax.get_title() == "PSNR against m / N"
    np.testing.assert_allclose(ax.lines[0].get_xdata(), [0.25, 0.5, 0.75])
    grid = [{"status": "ok", "cs.m": m, "reference.n": r, "n_pixels": 256, "psnr": 1.0} for m in (64, 128) for r in (128, 256)]
    values, names, labels = plot_values(grid, ["cs.m", "reference.n"])
    ax = plots.sweep_figure(values, names, labels=labels).axes[0]
    assert ax.get_title() == "PSNR over m / N × N_ref / N"
    # plots know no config keys: values and labels come from the caller
    ax = plots.sweep_figure(rows, ["cs.m"], labels={"cs.m": "samples"}).axes[0]
    assert ax.get_xlabel() == "samples" and list(ax.lines[0].get_xdata()) == [256, 512, 768]


@pytest.mark.parametrize("fmt,magic", [("pdf", b"%PDF"), ("svg", b"<?xml")])
def test_figure_format_writes_vector_figures(tmp_path, fmt, magic):
    from cssat.experiments import run_experiment

    with initialize_config_module(config_module="cssat.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["target.size=16", "threads=1", "denoiser=none", f"figure_format={fmt}"])
    met = run_experiment(cfg, tmp_path)
    fig = tmp_path / "figures" / f"fig9_sim1.{fmt}"
    assert fig.read_bytes().startswith(magic) and f"figures/fig9_sim1.{fmt}" in met["files"]
    assert not (tmp_path / "figures" / "fig9_sim1.png").exists()
    with pytest.raises(ValueError, match=r"figure_format: expected one of \['png', 'pdf', 'svg'\]"):
        plots.save_figure(plots.sweep_figure([{"status": "ok", "a": 1, "psnr": 1.0}], ["a"]), tmp_path / "x.jpg")
