"""The words of :func:`cssat.inversion.period.estimate_period`'s verdict: its warnings, why the
chosen period won, and the verdict on a constant curve."""

from __future__ import annotations

from typing import Any

import numpy as np

#: the χ²/ν above which a model is said not to fit its data: the period's Fourier series
#: (``model_fits``) and the spin's EGI fit (``SpinSolution.model_fits``)
MODEL_FITS_CHI2 = 3.0

def _warnings(period: float, lo: float, hi: float, longest: float, step: float, alts: list[dict[str, Any]], chi2_n: float,
              m: int) -> tuple[list[str], bool]:
    """The verdict's warnings (too few cycles in the ``longest`` stretch, the period on an edge of
    ``[lo, hi]``, an alias within ΔBIC 6, a misfit ``chi2_n`` of the ``m``-harmonic series) and
    whether the model fits (χ²/ν ≤ :data:`MODEL_FITS_CHI2`)."""
    warns = []
    n_cycles = longest / period
    if n_cycles < 2:
        warns.append(f"the longest stretch holds {n_cycles:.2g} cycles of {period:.6g} s (< 2): weakly constrained")
    if min(abs(period - lo), abs(period - hi)) < 2 * period ** 2 * step:
        warns.append(f"the period {period:.6g} s sits on an edge of the search [{lo:.6g}, {hi:.6g}] s")
    close = [a for a in alts if a["relation"] != "peak" and a["delta_bic"] < 6.0]
    if close:
        warns.append("a close call: " + ", ".join(f"{a['relation']} ({a['period_s']:.6g} s) is within ΔBIC "
                                                  f"{a['delta_bic']:.2g} of the chosen period" for a in close))
    model_fits = bool(chi2_n <= MODEL_FITS_CHI2)
    if not model_fits:
        warns.append(f"χ²/N = {chi2_n:.3g}: the {m}-harmonic series does not fit to the noise (glints, a changing "
                     "curve, or underestimated errors); the period may be an alias")
    return warns, model_fits


def _why(best: dict[str, Any], alts: list[dict[str, Any]]) -> str:
    """One sentence: why the chosen period beat its aliases."""
    parts = []
    for a in alts:
        if a["relation"] == "peak":
            continue
        verdict = "worse" if a["delta_bic"] > 0 else "better"
        parts.append(f"{a['relation']} ({a['period_s']:.6g} s) {verdict} by ΔBIC {abs(a['delta_bic']):.3g}")
    head = (f"{best['k']:g}× the periodogram's peak period with {best['n_harmonics']} harmonics (its odd harmonics pay for "
            "their parameters)" if best["k"] > 1 else f"the periodogram's peak period with {best['n_harmonics']} harmonics")
    return head + ("; " + ", ".join(parts) if parts else "")


def _constant(t: np.ndarray) -> dict[str, Any]:
    """The verdict on a light curve without any variation."""
    nan = float("nan")
    return {"period_s": nan, "period_err_s": nan, "periodic": False, "fap": 1.0, "repeat": nan, "best_period_s": nan,
            "best_period_err_s": nan, "alternatives": [], "why": "the values do not vary", "n_harmonics": 0, "chi2": 0.0,
            "chi2_per_sample": 0.0, "model_fits": True, "n_cycles": 0.0, "min_period_s": nan, "max_period_s": nan,
            "f0_period_s": nan, "doubled": False, "warnings": ["constant light curve"], "noise_sigma": 0.0,
            "n_samples": int(len(t)), "rss": 0.0, "n_nuisance": 1,
            "periodogram": {"frequency_hz": np.zeros(0), "power": np.zeros(0)}}
