"""The light-curve experiment's figures: the paper's Fig. 4 (renders and light curve) and Fig. 5."""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np

from cssat.plots.base import _figure, _scale_bar

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def lightcurve_figure(minutes: np.ndarray, mag: np.ndarray, images: np.ndarray, marks: Sequence[int], times: np.ndarray,
                      sunlit: np.ndarray, fov_m: float | None = None) -> Figure:
    """The paper's Fig. 4: rendered images at the marked steps (pixel flux in W/m² at the
    observer, a scale bar in metres when ``fov_m``, the field of view, is given) above the
    atmosphere-free light curve in magnitudes, with the Earth's shadow shaded."""
    n = len(marks)
    fig = _figure((2.5 * n, 6.4))
    gs = fig.add_gridspec(2, n, height_ratios=[1, 1.25])
    for k, (step, img) in enumerate(zip(marks, images)):
        ax = fig.add_subplot(gs[0, k])
        im = ax.imshow(img, cmap="gray", interpolation="nearest", vmin=0, vmax=max(float(img.max()), 1e-300))
        ax.set_title(f"({k + 1}) {str(times[step])[11:16]} UTC", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
        cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03, orientation="horizontal")
        cb.set_label("pixel flux (W/m²)", fontsize=7)
        cb.ax.tick_params(labelsize=6)
        if fov_m is not None:
            _scale_bar(ax, float(fov_m), img.shape[-1])
    ax = fig.add_subplot(gs[1, :])
    ax.plot(minutes, mag, color="k", lw=1)
    ax.plot(minutes[marks], mag[marks], "o", color="tab:red")
    for k, step in enumerate(marks):
        ax.annotate(f"({k + 1})", (minutes[step], mag[step]), textcoords="offset points", xytext=(4, 6), fontsize=8, color="tab:red")
    ecl = np.asarray(sunlit) < 1
    if ecl.any():
        ax.axvspan(minutes[ecl][0], minutes[ecl][-1], color="0.85", label="Earth shadow")
        ax.legend(loc="lower right", fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel(_since(times[0]))
    ax.set_ylabel("apparent magnitude (V; brighter up)")
    ax.set_title("(b) simulated atmosphere-free light curve", fontsize=10)
    fig.suptitle("(a) synthetic images of the satellite at the marked times", fontsize=10, y=0.99)
    fig.tight_layout()
    return fig


def _since(epoch) -> str:
    return "minutes since " + str(epoch)[:16].replace("T", " ") + " UTC"


def atmosphere_figure(minutes: np.ndarray, mag: np.ndarray, mag_facetwise: np.ndarray, mag_pixelwise: np.ndarray,
                      atmosphere: str = "gaussian", epoch: np.datetime64 | str | None = None) -> Figure:
    """The paper's Fig. 5: the atmosphere-free light curve against the facet-wise (Eq. 11) and
    pixel-wise (Eq. 12) attenuated noisy ones, as magnitudes of the flux's size ``|I|`` (the
    paper's zero-mean Φ makes the attenuated flux negative at times); ``epoch`` (UTC) labels the
    time axis."""
    fig = _figure((9, 4))
    ax = fig.subplots()
    ax.plot(minutes, mag_pixelwise, color="tab:orange", lw=0.6, label=f"simplified attenuated noisy LC (pixel-wise, Eq. 12, {atmosphere})")
    ax.plot(minutes, mag_facetwise, color="tab:blue", lw=0.6, label=f"attenuated noisy LC (facet-wise, Eq. 11, {atmosphere})")
    ax.plot(minutes, mag, color="k", lw=1.2, label="atmosphere-free (Eq. 10)")
    ax.invert_yaxis()
    ax.set_xlabel(_since(epoch) if epoch is not None else "minutes")
    ax.set_ylabel("measured flux |I| as apparent magnitude\n(V; brighter up)")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Atmosphere-free light curve and attenuated noisy light curves", fontsize=10)
    fig.tight_layout()
    return fig



def observations_figure(hours: np.ndarray, measured: np.ndarray, errors: np.ndarray | None, simulated: np.ndarray,
                        epoch: np.datetime64 | str | None = None, label: str = "") -> Figure:
    """A measured light curve (magnitudes, 1σ error bars) beside the simulated one on its time
    stamps, over their residuals (measured − simulated); ``hours`` since ``epoch``. Gaps in the
    time stamps are drawn as gaps (points, no lines across them)."""
    fig = _figure((9, 5.2))
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.3]})
    top.errorbar(hours, measured, yerr=errors, fmt=".", ms=3, lw=0.6, color="k", label=f"measured {label}".strip())
    top.plot(hours, simulated, ".", ms=2, color="tab:orange", label="simulated (atmosphere-free, Eq. 10)")
    top.invert_yaxis()
    top.set_ylabel("V magnitude (brighter up)")
    top.legend(fontsize=8, loc="best")
    res = measured - simulated
    bottom.errorbar(hours, res, yerr=errors, fmt=".", ms=2, lw=0.5, color="tab:blue")
    bottom.axhline(0, color="0.5", lw=0.8)
    bottom.invert_yaxis()
    bottom.set_ylabel("measured − simulated\n(mag)")
    bottom.set_xlabel(("hours since " + str(epoch)[:19].replace("T", " ") + " UTC") if epoch is not None else "hours")
    finite = np.isfinite(res)
    rms = float(np.sqrt(np.mean(res[finite] ** 2))) if finite.any() else float("nan")
    top.set_title(f"Measured and simulated light curves: {int(finite.sum())} time stamps, residual rms {rms:.3f} mag",
                  fontsize=10)
    fig.tight_layout()
    return fig
