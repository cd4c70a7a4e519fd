"""Period methods by name: a registry of functions that find the period of a light curve, each
returning a :class:`~cssat.inversion.results.PeriodResult`, and the two classical peers of
cssat's own method.

- ``cssat`` (the default): :func:`cssat.inversion.estimate_period` — the period, its 1σ, and
  whether the curve is periodic at all (a false-alarm probability from the track's own noise).
- ``lombscargle``: astropy's ``LombScargle`` with ``nterms`` terms (2) on a grid derived from
  the data (2/span to the Nyquist of the median in-channel step, 10 points a peak): its highest
  peak. A periodogram has no verdict of its own: it states a period on every curve.
- ``pdm``: Stellingwerf's (1978) phase-dispersion minimisation (θ, the pooled within-bin
  variance over the total, ``bins`` phase bins) on the same grid after one quadratic trend:
  its lowest θ. A period on every curve too.

A method is a function ``f(times_s, flux, *, sigma=None, segments=None, zero_points=None,
convention="photometric", min_period_s=None, max_period_s=None, **its_options)`` (``times_s
(T,)`` s, ``flux (T,)`` a flux or a magnitude, ``sigma`` its 1σ, ``segments (T,)`` the track of
each sample, ``zero_points (T,)`` the camera channel of each) that returns a mapping with at least
``period_s``, ``verdict`` and ``periodic``. A new one is one module that calls
:func:`register_period_method` when it is imported; import it before the run (in a script, or
the module that launches the experiment), then ``period.method=<name>``.
"""

from __future__ import annotations

import functools
import inspect
from typing import Any, Callable

import numpy as np

from cssat._checks import FieldError, choice_param, int_param
from cssat.inversion.results import PeriodResult, series_fit

__all__ = ["register_period_method", "period_methods", "period_method", "find_period", "lomb_scargle_period",
           "pdm_period", "frequency_grid", "DEFAULT_METHOD"]

#: the method used when none is named
DEFAULT_METHOD = "cssat"
_METHODS: dict[str, Callable[..., Any]] = {}
#: the options every method receives from the characterise experiment (its own options aside)
COMMON_OPTIONS = ("sigma", "segments", "zero_points", "convention", "min_period_s", "max_period_s")


def register_period_method(name: str, func: Callable[..., Any], *, overwrite: bool = False) -> None:
    """Register ``func`` as the period method ``name`` (the module's docstring: its signature and
    what it returns). A name taken is a FieldError naming ``name`` unless ``overwrite``."""
    if not isinstance(name, str) or not name.isidentifier():
        raise FieldError("name", f"a period method's name is an identifier (letters, digits, _), got {name!r}")
    if not callable(func):
        raise FieldError("func", f"expected a function, got {type(func).__name__}")
    if name in _METHODS and not overwrite:
        raise FieldError("name", f"the period method {name!r} is registered already (overwrite=True replaces it); "
                                 f"the methods: {', '.join(_METHODS)}")
    _METHODS[name] = func


def period_methods() -> dict[str, Callable[..., Any]]:
    """The registered methods by name (a copy; the default first)."""
    return dict(_METHODS)


def period_method(name: str | None = None, *, field: str = "method") -> Callable[..., PeriodResult]:
    """The method ``name`` (``None``: :data:`DEFAULT_METHOD`) as a function that returns a
    :class:`PeriodResult` (its ``method`` the name) and refuses an option it does not take
    with a FieldError naming the option and its options. An unknown name is a FieldError
    naming ``field`` and the registered methods."""
    name = DEFAULT_METHOD if name is None else name
    func = _METHODS.get(name) if isinstance(name, str) else None
    if func is None:
        raise FieldError(field, f"not a period method: {name!r}; the methods: {', '.join(_METHODS)}")
    params = inspect.signature(func).parameters
    open_kw = any(p.kind is p.VAR_KEYWORD for p in params.values())

    @functools.wraps(func)
    def run(times_s: Any, flux: Any, **options: Any) -> PeriodResult:
        bad = [] if open_kw else [k for k in options if k not in params]
        if bad:
            own = [k for k in params if k not in ("times_s", "flux")]
            raise FieldError(bad[0], f"not an option of the period method {name!r}; its options: {', '.join(own)}")
        res = func(times_s, flux, **options)
        res = PeriodResult.from_dict(res)
        return res if res.get("method") is not None else PeriodResult(res, method=name)

    return run


def find_period(times_s: Any, flux: Any, *, method: str | None = None, **options: Any) -> PeriodResult:
    """The period of ``flux (T,)`` at ``times_s (T,)`` (s) by the registered ``method`` (default
    ``cssat``: :func:`~cssat.inversion.estimate_period`), ``options`` its own."""
    return period_method(method)(times_s, flux, **options)


def frequency_grid(times_s: Any, channels: Any = None, min_period_s: float | None = None,
                   max_period_s: float | None = None) -> np.ndarray:
    """``(F,)`` Hz: 2/span to the Nyquist of the median in-channel step (``channels (T,)``;
    ``None``: one channel), 10 points a peak (0.1/span apart), within ``[1/max_period_s,
    1/min_period_s]`` where given."""
    t = np.asarray(times_s, dtype=np.float64)
    ch = np.zeros(len(t)) if channels is None else np.asarray(channels)
    steps = np.concatenate([np.diff(np.sort(t[ch == c])) for c in np.unique(ch)])
    d = float(np.median(steps[steps > 0]))
    span = float(t[-1] - t[0])
    f = np.arange(2.0 / span, 0.5 / d, 0.1 / span)
    if min_period_s is not None or max_period_s is not None:
        lo = 0.0 if max_period_s is None else 1.0 / float(max_period_s)
        hi = np.inf if min_period_s is None else 1.0 / float(min_period_s)
        f = f[(f >= lo) & (f <= hi)]
        if not len(f):
            raise FieldError("min_period_s", f"no trial period within [{min_period_s}, {max_period_s}] s on the "
                                             f"data's grid (periods {d * 2:.6g} to {span / 2:.6g} s)")
    return f


def _sorted(times_s: Any, flux: Any, sigma: Any, segments: Any, zero_points: Any) -> tuple:
    """The inputs as float arrays sorted by time (a stable sort: sorted input is kept as it is)."""
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    y = np.asarray(flux, dtype=np.float64).reshape(-1)
    if y.shape != t.shape or len(t) < 8:
        raise FieldError("flux", f"expected times and values of one length (T,) with T >= 8, got {t.shape} and {y.shape}")
    if not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise FieldError("flux", "the times and values must be finite")
    order = np.argsort(t, kind="stable")
    if (order == np.arange(len(t))).all():
        order = None

    def take(a: Any) -> Any:
        if a is None:
            return None
        a = np.broadcast_to(np.asarray(a), t.shape) if np.ndim(a) == 0 else np.asarray(a).reshape(-1)
        return a if order is None else a[order]

    return (t, y, take(sigma), take(segments), take(zero_points)) if order is None else \
        (t[order], y[order], take(sigma), take(segments), take(zero_points))


def _peer_result(name: str, t: np.ndarray, y: np.ndarray, sigma: Any, segments: Any, zero_points: Any, f: np.ndarray,
                 power: np.ndarray, best: int, n_harmonics: int, detrend: int, convention: str, what: str) -> PeriodResult:
    """A plain method's result: its best period, the series of ``n_harmonics`` terms fitted there
    (with each stretch's trend and each channel's zero point: :func:`series_fit`) for ``.model``
    and χ², its next peaks as alternatives, and "periodic" — a periodogram states a period on
    every curve."""
    from cssat.inversion.period_verdict import MODEL_FITS_CHI2  # local: the threshold estimate_period uses, for a peer's result

    P = 1.0 / float(f[best])
    fit = series_fit(t, y, P, n_harmonics, sigma=sigma, segments=segments, detrend=detrend, zero_points=zero_points)
    res = PeriodResult({"period_s": P, "verdict": "periodic", "periodic": True}, **fit)
    from cssat.inversion.fourier import light_curve_scatter  # heavy: cssat.inversion.fourier imports torch

    resid = y - res.model(t, channels=zero_points)
    n_par = 2 * n_harmonics + sum(len(s["coefficients"]) for s in fit["trend"]) + len(fit["zero_points"] or [1]) - 1
    nu = max(len(t) - n_par, 1)
    scat = max(light_curve_scatter(t, y), 1e-9 * float(np.std(y)), 1e-150)
    chi2 = float(np.sum((resid / sigma) ** 2)) if sigma is not None else float(np.sum(resid ** 2)) / scat ** 2
    n = len(t)
    local = np.flatnonzero((power[1:-1] > power[:-2]) & (power[1:-1] >= power[2:])) + 1
    others = [int(i) for i in local[np.argsort(-power[local])] if i != best][:4]
    seg = np.zeros(n) if segments is None else np.unique(np.asarray(segments).astype(str), return_inverse=True)[1]
    longest = max(float(np.ptp(t[seg == s])) for s in np.unique(seg))
    why = f"the {what}'s {'lowest θ' if name == 'pdm' else 'highest peak'}; it states a period on every curve (no significance test)"
    return PeriodResult(res, method=name, verdict_why=why, why=why, period_err_s=float("nan"), best_period_s=P,
                        best_period_err_s=float("nan"), photometric_period_s=P, convention=convention,
                        n_harmonics=n_harmonics, fap=float("nan"), repeat=float("nan"), chi2=chi2,
                        chi2_per_sample=chi2 / nu, model_fits=bool(chi2 / nu <= MODEL_FITS_CHI2),
                        n_cycles=longest / P, min_period_s=float(1.0 / f[-1]), max_period_s=float(1.0 / f[0]),
                        alternatives=[{"relation": "peak", "period_s": float(1.0 / f[i]), "power": float(power[i])}
                                      for i in others],
                        warnings=[], n_samples=n, periodogram={"frequency_hz": f, "power": power})


def lomb_scargle_period(times_s: Any, flux: Any, *, sigma: Any = None, segments: Any = None, zero_points: Any = None,
                        convention: str = "photometric", min_period_s: float | None = None,
                        max_period_s: float | None = None, nterms: int = 2, detrend: int = 2) -> PeriodResult:
    """astropy's ``LombScargle(t, y, dy=sigma, nterms=nterms)`` on :func:`frequency_grid` (the
    grid's step by ``zero_points``, the camera channels): the period of its highest peak,
    ``verdict`` always ``periodic`` (a periodogram states a period on every curve); ``.model``
    the ``nterms`` series there with each track's polynomial of order ``detrend``.
    ``convention`` is recorded, not applied (the peak's own period)."""
    from astropy.timeseries import LombScargle  # heavy: astropy, only for lomb_scargle_period()

    convention = choice_param(convention, "convention", ("photometric", "double_peaked"))
    nterms = int_param(nterms, "nterms", 1, 12)
    t, y, sig, seg, zp = _sorted(times_s, flux, sigma, segments, zero_points)
    f = frequency_grid(t, zp, min_period_s, max_period_s)
    p = LombScargle(t, y, dy=sig, nterms=nterms).power(f)
    return _peer_result("lombscargle", t, y, sig, seg, zp, f, p, int(np.argmax(p)), nterms, detrend, convention,
                        f"{nterms}-term Lomb-Scargle periodogram")


def pdm_theta(t: np.ndarray, y: np.ndarray, f: np.ndarray, bins: int = 10) -> np.ndarray:
    """``(F,)`` Stellingwerf's θ at each frequency of ``f``: the pooled variance within ``bins``
    phase bins (those with 2 samples or more) over the variance of ``y``."""
    var = y.var(ddof=1)
    theta = np.empty(len(f))
    for k, fi in enumerate(f):
        b = np.floor(((t * fi) % 1.0) * bins).astype(int)
        n = np.bincount(b, minlength=bins)
        s = np.bincount(b, y, minlength=bins)
        s2 = np.bincount(b, y * y, minlength=bins)
        ok = n > 1
        within = (s2[ok] - s[ok] ** 2 / n[ok]).sum() / max(n[ok].sum() - ok.sum(), 1)
        theta[k] = within / var
    return theta


def pdm_period(times_s: Any, flux: Any, *, sigma: Any = None, segments: Any = None, zero_points: Any = None,
               convention: str = "photometric", min_period_s: float | None = None, max_period_s: float | None = None,
               bins: int = 10, detrend: int = 2) -> PeriodResult:
    """Phase-dispersion minimisation (Stellingwerf 1978): θ (:func:`pdm_theta`, ``bins`` phase
    bins) on :func:`frequency_grid` after one quadratic trend over the whole curve; the period of
    the lowest θ (the first where several tie), ``verdict`` always ``periodic``. The
    periodogram's ``power`` is ``1 − θ``; ``.model`` a 2-term series at that period with each
    track's polynomial of order ``detrend``. ``sigma`` weighs only the model's fit;
    ``convention`` is recorded, not applied."""
    convention = choice_param(convention, "convention", ("photometric", "double_peaked"))
    bins = int_param(bins, "bins", 2, 1000)
    t, y, sig, seg, zp = _sorted(times_s, flux, sigma, segments, zero_points)
    yy = y - np.polyval(np.polyfit(t - t.mean(), y, 2), t - t.mean())
    f = frequency_grid(t, zp, min_period_s, max_period_s)
    theta = pdm_theta(t, yy, f, bins)
    best = int(np.argmin(np.where(np.isnan(theta), np.inf, theta)))  # the first lowest θ
    return _peer_result("pdm", t, y, sig, seg, zp, f, 1.0 - theta, best, 2, detrend, convention,
                        f"phase-dispersion minimisation ({bins} bins)")


def _register_builtins() -> None:
    from cssat.inversion.period import estimate_period  # local: registered when the registry is first read

    @functools.wraps(estimate_period)
    def cssat_method(times_s: Any, flux: Any, **options: Any) -> Any:
        from cssat.inversion import period  # local: its name looked up at each call (a patched estimate_period runs)

        return period.estimate_period(times_s, flux, **options)

    register_period_method(DEFAULT_METHOD, cssat_method)
    register_period_method("lombscargle", lomb_scargle_period)
    register_period_method("pdm", pdm_period)


_register_builtins()
