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


def _why(best: dict[str, Any], alts: list[dict[str, Any]], k_conv: int = 1, n_max: int = 2) -> str:
    """One sentence: why the chosen period beat its aliases, and the convention's doubling."""
    parts = []
    for a in alts:
        if a["relation"] == "peak":
            continue
        verdict = "worse" if a["delta_bic"] > 0 else "better"
        parts.append(f"{a['relation']} ({a['period_s']:.6g} s) {verdict} by ΔBIC {abs(a['delta_bic']):.3g}")
    k = best.get("k", 1)
    head = (f"{k:g}× the periodogram's peak period with {best['n_harmonics']} harmonics" if k != 1
            else f"the periodogram's peak period with {best['n_harmonics']} harmonics")
    if k_conv == 2:
        head += (f"; its fold shows {n_max} significant maximum, so the full turn of a double-peaked body is twice it "
                 "(convention double_peaked)")
    return head + ("; " + ", ".join(parts) if parts else "")


#: a variation too slow for ``min_cycles`` (no surrogate test tells it from red noise) is
#: "undetermined" when it beats white noise and its rms reaches this many single-sample noise σ
#: (weaker: "not periodic", as MMT's "not variable" after its quadratic detrend)
MIN_VARIATION_SNR = 2.0


def _verdict(null: dict[str, Any], fap_white: float, fap_max: float, n_cycles: float, min_cycles: float, gap: float,
             max_gap: float, period: float, rep: float, min_repeat: float | None, lo: float, hi: float,
             variation_snr: float) -> tuple[str, str]:
    """The verdict word and its reason (:func:`cssat.inversion.estimate_period`, point 7):
    ``null`` the surrogates' FAPs, ``fap_white`` the white-noise F-test's, ``variation_snr`` the
    fitted series' rms over the single-sample noise."""
    fap = null["fap"]
    sur = f"{null['n']} surrogates of the track's own noise"
    if fap < fap_max:
        if n_cycles < min_cycles:
            return "undetermined", (f"a signal stands out (FAP {fap:.2g}, {sur}) but its period {period:.6g} s spans "
                                    f"{n_cycles:.2g} cycles of the track, fewer than {min_cycles:g}")
        if gap > max_gap:
            return "undetermined", (f"a signal stands out (FAP {fap:.2g}) but the fold at {period:.6g} s leaves "
                                    f"{gap:.0%} of a cycle unsampled: too sparse to show the period")
        if min_repeat is not None and not rep >= min_repeat:
            return "undetermined", (f"a period of {period:.6g} s stands out (FAP {fap:.2g}) but the cycles do not repeat "
                                    f"(repeat {rep:.2g} < min_repeat {min_repeat:g})")
        return "periodic", (f"P = {period:.6g} s stands out of the track's own noise (FAP {fap:.2g} from {sur}) over "
                            f"{n_cycles:.3g} cycles")
    slow = n_cycles < min_cycles and fap_white < fap_max  # more than white noise, too slow to test
    if slow and variation_snr >= MIN_VARIATION_SNR:
        return "undetermined", (f"the curve varies (rms {variation_snr:.2g}× the noise) on the scale of the track: its "
                                f"best period {period:.6g} s spans {n_cycles:.2g} cycles, fewer than {min_cycles:g}, "
                                "too few to tell a period from a slow change")
    note = (f"; a variation on the scale of the track (best {period:.6g} s, {n_cycles:.2g} cycles, rms "
            f"{variation_snr:.2g}× the single-sample noise, under {MIN_VARIATION_SNR:g}×) is not called a period"
            if slow else "")
    return "not periodic", (f"no period between {lo:.4g} and {hi / max(min_cycles, 1.0):.4g} s ({min_cycles:g}+ cycles) "
                            f"stands out of the track's own noise (FAP {fap:.2g}, {sur}){note}")


def _constant(t: np.ndarray, convention: str = "photometric") -> dict[str, Any]:
    """The verdict on a light curve without any variation."""
    nan = float("nan")
    return {"verdict": "not periodic", "periodic": False, "verdict_why": "the values do not vary",
            "period_s": nan, "period_err_s": nan, "photometric_period_s": nan, "convention": convention, "n_maxima": 0,
            "fap": 1.0, "fap_all": 1.0, "fap_surrogates_exceeding": 0, "n_surrogates": 0, "fap_white": 1.0,
            "repeat": nan, "best_period_s": nan, "best_period_err_s": nan, "alternatives": [], "fringes": [],
            "why": "the values do not vary", "n_harmonics": 0, "chi2": 0.0, "chi2_per_sample": 0.0, "model_fits": True,
            "n_cycles": 0.0, "min_period_s": nan, "max_period_s": nan, "cadence_s": nan, "f0_period_s": nan,
            "doubled": False, "warnings": ["constant light curve"], "noise_sigma": 0.0, "n_samples": int(len(t)),
            "rss": 0.0, "n_nuisance": 1, "periodogram": {"frequency_hz": np.zeros(0), "power": np.zeros(0)}}
