"""The shadowed box-wing's own spin: the pole, phase and period refined by gradient through the
parametric family's soft-shadowed light curve (:mod:`cssat.inversion.parametric`,
:mod:`cssat.inversion.soft_shadow`), its shape held or refined with it — the step the convex
EGI's spin search (:func:`cssat.inversion.estimate_spin`) cannot take on a self-shadowing
satellite.

The body frame of a spin about body +z is :func:`cssat.scene.attitude.spin_frame`'s
``v_body = R_z(φ₀ + ω t) R_y(90° − β) R_z(λ) E v`` (:func:`spin_frames`, the same in torch, so
that the Sun's and the observer's body-frame directions — and with them the light curve and
its shadows — are differentiable in ``(λ, β, φ₀, ω)``). :func:`refine_spin` minimises the
fit's soft-L1 loss (:func:`~cssat.inversion.parametric_fit.fit_box_wing`'s, the albedos
solved at every evaluation by :func:`~cssat.inversion.parametric_fit.profile_albedos`) over
those four numbers with L-BFGS-B, at shadow edge softnesses ``τ`` decreasing towards the hard
shadows, and gives a Gauss–Newton covariance of the spin with the family's geometry free
beside it (the Jacobian by central differences).

ASSUMPTIONS: the satellite spins uniformly about its body +z (a principal axis); the family's
frame is that body frame turned so that the bus is on its axes and the panels along ±y (the
phase ``φ₀`` holds that turn); the start is within the basin of the right pole (a local
refinement, not a search: a few degrees on the box-wings of ``benchmarks/bench_shadow_fit.py``);
the 1σ is the curvature's at the minimum ⊕ the move between the last two shadow softnesses and
is NOT yet calibrated at 68 %: in its model class (a box-wing without dishes started 2° off,
``benchmarks/bench_spin_refine_coverage.py``, 100 fresh seeds, run to convergence) it holds the
pole in its 68.27 / 95.45 % circles on 61.7 / 93.6 % of the 94 reliable (the curvature's alone
60.6 / 90.4 %), the worst miss 2.2× its 1σ (at 40 iterations a softness, whose answers rounding
set, 62.8 / 91.8 % of 183 with misses to 8σ); the period's 1σ under-covers more (62 / 86 %
within 1σ / 2σ).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, bool_param, choice_param, float_param, int_param
from cssat.inversion.parametric import box_wing_light_curve, param_names
from cssat.inversion.parametric_fit import (LOG_SIZE_BOUNDS, SIZE_NAMES, _to_p, _to_z, _transform, profile_albedos,
                                            shadow_defect, soft_l1)
from cssat.inversion.soft_shadow import soft_visibility
from cssat.optics.shadow_sampling import check_resolution
from cssat.scene.attitude import OBLIQUITY_DEG

__all__ = ["spin_frames", "refine_spin"]


def _rz(a: torch.Tensor) -> torch.Tensor:
    c, s, z, o = torch.cos(a), torch.sin(a), torch.zeros_like(a), torch.ones_like(a)
    return torch.stack([torch.stack([c, s, z], -1), torch.stack([-s, c, z], -1), torch.stack([z, z, o], -1)], -2)


def _ry(a: torch.Tensor) -> torch.Tensor:
    c, s, z, o = torch.cos(a), torch.sin(a), torch.zeros_like(a), torch.ones_like(a)
    return torch.stack([torch.stack([c, z, -s], -1), torch.stack([z, o, z], -1), torch.stack([s, z, c], -1)], -2)


def spin_frames(times_s: Any, spin: torch.Tensor, frame: str = "ecliptic") -> torch.Tensor:
    """Body frames ``(T, 3, 3)`` at ``times_s (T,)`` of the spin ``spin = (λ, β, φ₀, ω)`` (rad,
    rad, rad, rad/s; a tensor, differentiable): :func:`cssat.scene.attitude.spin_frame` with
    ``pole_lon_deg = λ``, ``pole_lat_deg = β``, ``phase_deg = φ₀``, ``period_s = 2π/ω``, in
    torch (``spin``'s dtype and device)."""
    frame = choice_param(frame, "frame", ("ecliptic", "equatorial"))
    spin = torch.as_tensor(spin)
    if spin.shape != (4,):
        raise FieldError("spin", f"expected (lon, lat, phase, omega) of shape (4,), got {tuple(spin.shape)}")
    t = torch.as_tensor(np.asarray(times_s, dtype=np.float64), dtype=spin.dtype, device=spin.device)
    fixed = _ry(math.pi / 2 - spin[1]) @ _rz(spin[0])
    if frame == "ecliptic":
        ce, se = math.cos(math.radians(OBLIQUITY_DEG)), math.sin(math.radians(OBLIQUITY_DEG))
        fixed = fixed @ torch.tensor([[1.0, 0.0, 0.0], [0.0, ce, se], [0.0, -se, ce]], dtype=spin.dtype, device=spin.device)
    return _rz(spin[2] + spin[3] * t) @ fixed


def _body(x: torch.Tensor, t: np.ndarray, Si: torch.Tensor, Oi: torch.Tensor, c: dict) -> tuple[torch.Tensor, ...]:
    """The body-frame Sun and observer ``(T, 3)`` of the inertial ``Si, Oi`` in the spin ``x (4,)``."""
    R = spin_frames(t, x, c["frame"])
    return torch.einsum("tij,tj->ti", R, Si), torch.einsum("tij,tj->ti", R, Oi)


def _by_part(x: torch.Tensor, p: torch.Tensor, t: np.ndarray, Si: torch.Tensor, Oi: torch.Tensor, tau: float,
             c: dict, defect: torch.Tensor | None = None) -> torch.Tensor:
    """Each part's soft-shadowed curve at unit albedo ``(T, P)``, the family ``p`` in the spin ``x (4,)``,
    plus a fixed ``defect (T, P)`` (the resolved cast curve's difference, :func:`_defect`)."""
    S, V = _body(x, t, Si, Oi, c)
    vis = soft_visibility(p, S, V, tau=tau, front_only=True, **c["geo"])
    Y = box_wing_light_curve(p, S, V, vis, by_part=True, range_km=1e-3, irradiance=1.0, **c["geo"])
    return Y if defect is None else Y + defect


def _defect(x: torch.Tensor, p: torch.Tensor, t: np.ndarray, Si: torch.Tensor, Oi: torch.Tensor, tau: float,
            c: dict) -> torch.Tensor | None:
    """``(T, P)``: :func:`~cssat.inversion.parametric_fit.shadow_defect` (rays ``c["resolution_m"]``
    apart) in the spin ``x``; None without a resolution."""
    if c["resolution_m"] is None:
        return None
    with torch.no_grad():
        S, V = _body(x, t, Si, Oi, c)
    return shadow_defect(p, S, V, tau, c["resolution_m"], **c["geo"])


def _model(x: torch.Tensor, p: torch.Tensor, t: np.ndarray, Si: torch.Tensor, Oi: torch.Tensor, tau: float, c: dict,
           albedos: bool = False) -> Any:
    """The light curve ``(T,)`` of the family ``p`` in the spin ``x (4,)``, the free albedos solved
    against ``c["y"]`` (``albedos``: ``(curve, albedos (P,))``)."""
    Y = _by_part(x, p, t, Si, Oi, tau, c, c.get("defect"))
    a = profile_albedos(Y, c["y"], c["sigma"], p[c["cd_idx"]], c["cd_free"])
    return (Y @ a, a) if albedos else Y @ a


def refine_spin(times_s: Any, flux: Any, sun: Any, obs: Any, p: Any, pole_lon_deg: float, pole_lat_deg: float,
                period_s: float, phase_deg: float = 0.0, *, sigma: Any = None, frame: str = "ecliptic", fixed: Any = (),
                shape: bool = False, heldout: Any = None, huber: float = 3.0,
                softness: tuple[float, ...] = (0.05, 0.02, 0.01), maxiter: int = 200, panels: int = 2,
                divisions: int = 4, dishes: int = 0, dish_rings: int = 12, dish_segments: int = 40,
                device: Any = None, resolution_m: float | None = None, **parts: Any) -> dict[str, Any]:
    """The spin ``(λ, β, P, φ₀)`` that best fits ``flux (T,)`` (per unit irradiance at 1 m, m²)
    at ``times_s (T,)`` with the family ``p`` (:func:`~cssat.inversion.parametric.param_names`'
    order for ``dishes`` and ``parts``) held — or, with ``shape``, its geometry (every parameter
    but the albedos and those in ``fixed``) refined jointly with the spin, in
    :func:`~cssat.inversion.parametric_fit.fit_box_wing`'s variables, after a first run of the
    spin alone at the first ``τ`` (the joint minimum, which an alternation of shape fits and spin
    refinements reaches only slowly — the pole and the shape are correlated — and a joint run
    from a start degrees off can stall short of) — from the start ``pole_lon_deg, pole_lat_deg,
    period_s, phase_deg``; ``sun, obs (T, 3)`` the inertial unit directions from the object
    (``frame``'s axes: GCRS, its pole read as ecliptic or equatorial); ``sigma (T,)`` the 1σ
    (None: ones). The albedos not named in ``fixed`` are solved at every evaluation (module
    docstring). ``softness``: the shadow edges' ``τ``, each a fraction of ``p``'s mean bus
    half-size, one L-BFGS-B run of at most ``maxiter`` iterations at each, in turn (runs of 40 ended
    where the arithmetic's last bits had led them: a start moved by 1e-9° moved the answer by up to
    0.27°, above its 1σ, and an earlier session's machine gave other answers for the same code and
    seeds; at 200 by at most 0.009° on the same six in-class seeds — BENCHMARKS.md, "Converged").
    ``resolution_m`` (m; None: the soft shadows at the sub-facets' centroids): each run adds to
    the soft model the defect of each part's curve with its sub-facets' shadows resolved by rays
    this far apart (held fixed through the run, a defect correction: at a fixed point the model
    is the resolved one, the gradient the soft one's; the last softness run twice), and the loss,
    the 1σ's residuals and the held-out verdict are the resolved model's — a grid of ``divisions``
    cells a face misses a converged light curve by up to ~1σ at a 1.5 % floor (BENCHMARKS.md,
    "Converged shadows"). ``device``: where
    the light curves, shadows and gradients are computed (default the CPU; e.g. ``"cuda"``) —
    the inputs are moved there and the results come back as NumPy arrays and floats (the
    optimiser's steps, the Jacobian's differences and the 1σ are small and stay on the CPU).

    Returns ``pole_lon_deg, pole_lat_deg, period_s, phase_deg``, ``loss`` and
    ``rms_over_noise`` (at the last ``τ``; ``start_loss`` and ``refined_loss`` the start's and
    the refinement's there — where the start's is lower the start is returned, ``kept_start``
    True: the schedule of softnesses can lead the descent into a worse minimum than the one it
    started in, and a refinement is never worse than its start), ``params`` (the family's, ``p``
    itself without ``shape``; the free albedos as solved), and the 1σ: the Gauss–Newton one with
    the geometry of ``p`` free beside the spin (``cov (4, 4)`` of ``(λ, β, φ₀, ω)`` scaled by the
    reduced χ² where above 1; ``formal_pole_err_deg`` the pole's radial 1σ, ``√(σ²_{λ cos β} + σ²_β)``,
    and ``formal_period_err_s``, given whatever the verdict) added in quadrature to the
    softness term — the pole's and the period's move between the last two softnesses'
    solutions (``softness_pole_shift_deg``, ``softness_period_shift_s``; 0 with one softness):
    the soft shadows' bias, which shrinks with ``τ`` (a move of the same order is left at the
    last), and the truncated runs' unfinished descent, neither of which the curvature sees —
    ``pole_err_deg`` and ``period_err_s``.

    The verdict (:func:`cssat.inversion.spin_errors.verdict_keys`, as
    :func:`~cssat.inversion.estimate_spin`'s): ``heldout = (times_s, flux, sun, obs, sigma)`` of
    samples not fitted (e.g. a night), predicted with the fitted spin, shape and albedos and
    tested against the χ² the noise allows there; ``verdict`` ``"unreliable"`` (and
    ``pole_err_deg``, ``period_err_s`` NaN: no 1σ) when it fails, when ``sigma`` is None, or —
    nothing held out — when the fitted samples' χ² is above the noise's. Keys ``verdict``,
    ``verdict_why``, ``heldout_chi2``, ``heldout_n``, ``heldout_threshold``."""
    names = param_names(dishes, **parts)
    dev = _device(device)
    pt = torch.as_tensor(np.asarray(p, dtype=np.float64))
    if pt.shape != (len(names),) or not bool(torch.isfinite(pt).all()):
        raise FieldError("p", f"expected {len(names)} finite values {names}, got {pt.tolist()}")
    fixed = _checked_fixed(fixed, names)
    huber = float_param(huber, "huber", 0.0, open_lo=True)
    maxiter = int_param(maxiter, "maxiter", 1, 10_000)
    pole_lon_deg, pole_lat_deg, period_s, phase_deg, softness = _checked_start(pole_lon_deg, pole_lat_deg, period_s,
                                                                               phase_deg, softness)
    shape = bool_param(shape, "shape")
    divisions = int_param(divisions, "divisions", 1, 16)
    t, y, Si, Oi, sg = _series((times_s, flux, sun, obs, sigma), "flux", "sigma", dev)
    held = _held_series(heldout, dev)
    cds = [n for n in names if n.startswith("cd_")]
    c = dict(frame=frame, y=y, sigma=sg, defect=None, resolution_m=check_resolution(resolution_m),
             cd_idx=torch.as_tensor([names.index(n) for n in cds], device=dev),
             cd_free=torch.as_tensor([n not in fixed for n in cds], device=dev),
             geo=dict(panels=panels, divisions=divisions, **parts,
                      **(dict(dishes=dishes, dish_rings=dish_rings, dish_segments=dish_segments) if dishes else {})))
    span = float(t.max() - t.min()) or 1.0  # ω scaled by the span: one unit turns the last sample by one radian
    scale_np = np.array([1.0, 1.0, 1.0, 1.0 / span])
    x0 = np.array([math.radians(pole_lon_deg), math.radians(pole_lat_deg), math.radians(phase_deg),
                   2 * math.pi / period_s]) / scale_np
    free = [n not in fixed and not n.startswith("cd_") for n in names]  # the geometry the 1σ marginalises
    bool_free = [bool(shape) and f for f in free]  # ... and the fit refines, with shape
    transform = _transform(names)
    z0 = _to_z(pt.numpy(), transform)
    x0 = np.concatenate([x0, z0.numpy()[bool_free]])
    pt, z0, scale = pt.to(dev), z0.to(dev), torch.as_tensor(scale_np, device=dev)
    transform = tuple(v.to(dev) for v in transform)
    free_idx = torch.as_tensor(np.flatnonzero(bool_free), dtype=torch.long, device=dev)
    bounds = [(None, None)] * 4 + [LOG_SIZE_BOUNDS if n in SIZE_NAMES else (None, None)
                                   for n, f in zip(names, bool_free) if f]
    bus = float(pt[:3].mean())

    def unpack(x):  # (spin (4,), p)
        return x[:4] * scale, (_to_p(z0.index_put((free_idx,), x[4:]), transform) if len(free_idx) else pt)

    def correct(x, tau):  # the resolved shadows' defect at x, held through the next run
        if c["resolution_m"] is not None:
            sp, q = unpack(torch.as_tensor(x, device=dev))
            c["defect"] = _defect(sp, q, t, Si, Oi, tau, c)

    def loss(x, tau):
        sp, q = unpack(x)
        return soft_l1((y - _model(sp, q, t, Si, Oi, tau, c)) / sg, huber)

    def value_and_grad(x, tau):
        xt = torch.as_tensor(x, dtype=torch.float64, device=dev).requires_grad_(True)
        f = loss(xt, tau)
        (g,) = torch.autograd.grad(f, xt)
        return float(f.detach()), g.cpu().numpy()

    from scipy.optimize import minimize  # heavy: scipy.optimize

    def run(x, tau, k):  # L-BFGS-B over the first k variables, the rest held (the defect at x held too)
        correct(x, tau)

        def vg(xs):
            f, g = value_and_grad(np.concatenate([xs, x[k:]]), tau)
            return f, g[:k]

        xs = minimize(vg, x[:k], jac=True, method="L-BFGS-B", bounds=bounds[:k], options=dict(maxiter=maxiter)).x
        return np.concatenate([xs, x[k:]])

    def loss_at(v, tau):  # the loss with the defect at v itself: the resolved model's
        correct(v, tau)
        return float(loss(torch.as_tensor(v, device=dev), tau))

    x = run(x0, softness[0] * bus, 4) if len(free_idx) else x0  # the spin alone first: a joint start stalls
    spins = []  # the spin after each τ: the last two's difference is the softness term of the 1σ
    for s in list(softness) + ([softness[-1]] if c["resolution_m"] is not None else []):  # resolved: a last pass again
        x = run(x, s * bus, len(x))
        spins.append((x[:4] * scale_np).copy())
    tau = float(softness[-1]) * bus
    with torch.no_grad():  # never worse than the start: the softness schedule can lead the descent off
        start_loss, end_loss = loss_at(x0, tau), loss_at(x, tau)
        kept_start = start_loss < end_loss
        x = x0 if kept_start else x
        if kept_start:  # the defect at x0 again (loss_at left x's)
            correct(x, tau)
        sp, q = unpack(torch.as_tensor(x, device=dev))
        spin = sp.cpu().numpy()
        m, a = _model(sp, q, t, Si, Oi, tau, c, albedos=True)
        q = q.index_put((c["cd_idx"],), a)
        out = dict(loss=min(start_loss, end_loss), start_loss=start_loss, refined_loss=end_loss, kept_start=kept_start,
                   rms_over_noise=float(((y - m) / sg).pow(2).mean().sqrt()), params=q.cpu().numpy().copy())
    if held is not None:  # the held-out nights predicted with the same resolved shadows
        c["defect_h"] = _defect(sp, q, held[0], held[2], held[3], tau, c)
    J, r0, J_h, r_h = _jacobians(spin, q, t, Si, Oi, tau, c, free, held)
    from cssat.inversion.spin_errors import verdict_keys  # local: scipy.stats, only for a verdict

    verdict = verdict_keys(J, len(r0), float(r0 @ r0), sigma is not None, None if held is None else (r_h, J_h),
                           "the pole")
    cov, formal_pole, formal_period = _formal(J, r0, spin)
    lon, lat, ph, om = spin
    shift_pole, shift_period = _softness_shift(spins[:len(softness) - 1] + spins[-1:])
    ok = verdict["verdict"] == "reliable"
    return dict(out, **verdict, pole_lon_deg=math.degrees(lon) % 360.0, pole_lat_deg=math.degrees(lat),
                period_s=float(2 * math.pi / om), phase_deg=math.degrees(ph) % 360.0,
                pole_err_deg=math.hypot(formal_pole, shift_pole) if ok else math.nan,
                period_err_s=math.hypot(formal_period, shift_period) if ok else math.nan,
                formal_pole_err_deg=formal_pole, formal_period_err_s=formal_period,
                softness_pole_shift_deg=shift_pole, softness_period_shift_s=shift_period, cov=cov)


def _checked_fixed(fixed: Any, names: tuple) -> list[str]:
    """``fixed`` as a list of parameter names among ``names`` (a single name too), else a
    :class:`FieldError` naming ``fixed``."""
    fixed = [fixed] if isinstance(fixed, str) else list(fixed or ()) if isinstance(fixed, (list, tuple, set)) else fixed
    if not isinstance(fixed, list) or [n for n in fixed if n not in names]:
        raise FieldError("fixed", f"expected names among {list(names)}, got {fixed}")
    return fixed


def _held_series(heldout: Any, dev: Any) -> tuple | None:
    """The held-out ``(times_s, flux, sun, obs, sigma)`` checked (:func:`_series`, every field named
    ``heldout``), or None."""
    if heldout is None:
        return None
    if len(heldout) != 5:
        raise FieldError("heldout", f"expected (times_s, flux, sun, obs, sigma), got {len(heldout)} items")
    return _series(heldout, "heldout", "heldout", dev)


def _device(device: Any) -> torch.device:
    """The light curves' and the gradients' device (the optimiser's steps and the 1σ stay on the
    CPU), tried: a :class:`FieldError` naming ``device`` where this machine or build has none."""
    try:
        dev = torch.device("cpu" if device is None else device)
        torch.zeros(1, dtype=torch.float64, device=dev).sum().item()
    except (RuntimeError, TypeError, AssertionError, NotImplementedError) as e:  # no such device, or not in this build
        raise FieldError("device", f"expected a torch device this machine has, such as 'cpu' or 'cuda', got {device!r} "
                                   f"({type(e).__name__}: {str(e)[:80]})") from e
    return dev


def _checked_start(lon: Any, lat: Any, period: Any, phase: Any, softness: Any) -> tuple:
    """The start ``(λ°, β°, P s, φ₀°)`` and the softnesses as floats, each refused by name where
    it is not a number in range (``β`` in [−90, 90], ``P`` finite and non-zero; the softnesses a
    non-empty sequence of finite fractions > 0)."""
    lon, phase = float_param(lon, "pole_lon_deg"), float_param(phase, "phase_deg")
    lat = float_param(lat, "pole_lat_deg", -90.0, 90.0)
    period = float_param(period, "period_s")
    if period == 0:
        raise FieldError("period_s", "expected a non-zero finite period (s), got 0")
    try:
        soft = tuple(float_param(v, "softness", 0.0, open_lo=True) for v in softness)
    except TypeError as e:
        raise FieldError("softness", f"expected a sequence of positive fractions of the bus size, got {softness!r}") from e
    if not soft:
        raise FieldError("softness", f"expected positive fractions of the bus size, got {softness!r}")
    return lon, lat, period, phase, soft


def _formal(J: np.ndarray, r0: np.ndarray, spin: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The Gauss–Newton covariance ``(4, 4)`` of ``(λ, β, φ₀, ω)`` from the Jacobian ``J (T, 4 +
    G)`` and residuals ``r0 (T,)`` (the geometry marginalised; scaled by the reduced χ² where above
    1), and the pole's radial 1σ (degrees) and the period's (s) at ``spin``."""
    dof = max(len(r0) - J.shape[1], 1)
    cov = np.linalg.pinv(J.T @ J)[:4, :4] * max(1.0, float(r0 @ r0) / dof)
    cb = math.cos(spin[1])
    pole = math.degrees(math.sqrt(max(cov[0, 0] * cb * cb + cov[1, 1], 0.0)))
    return cov, pole, float(2 * math.pi / spin[3] ** 2 * math.sqrt(max(cov[3, 3], 0.0)))


def _softness_shift(spins: list[np.ndarray]) -> tuple[float, float]:
    """The pole's move (degrees) and the period's (s) between the last two softnesses' solutions
    (each ``(λ, β, φ₀, ω)`` in radians, rad/s); ``(0, 0)`` with one softness (no term measured)."""
    if len(spins) < 2:
        return 0.0, 0.0
    from cssat.inversion.spin_errors import separation_deg  # local: beside the verdict's

    (l0, b0, _, w0), (l1, b1, _, w1) = spins[-2], spins[-1]
    pole = separation_deg((math.degrees(l0), math.degrees(b0)), (math.degrees(l1), math.degrees(b1)))
    return float(pole), float(abs(2 * math.pi / w1 - 2 * math.pi / w0))


def _series(series: Any, field: str, sigma_field: str, device: torch.device) -> tuple:
    """``(times_s, flux, sun, obs, sigma)`` checked (``sigma`` None: ones), as ``(t, y, sun, obs,
    sigma)`` arrays and tensors; errors name ``field`` (shapes) or ``sigma_field`` (a 1σ ≤ 0)."""
    t = np.asarray(series[0], dtype=np.float64)
    y, S, O = (torch.as_tensor(np.asarray(v, dtype=np.float64)) for v in series[1:4])
    sg = torch.ones_like(y) if series[4] is None else torch.as_tensor(np.asarray(series[4], dtype=np.float64))
    if not (t.shape == y.shape == sg.shape and S.shape == O.shape == (len(t), 3)):
        raise FieldError(field, f"expected times, flux, sigma (T,) and sun, obs (T, 3) alike, got {t.shape}, "
                                f"{tuple(y.shape)}, {tuple(sg.shape)}, {tuple(S.shape)}, {tuple(O.shape)}")
    names = ("times_s", field, "sun", "obs", sigma_field) if field == "flux" else (field,) * 5
    for name, v in zip(names, (t, y, S, O, sg)):
        if not np.all(np.isfinite(np.asarray(v))):
            raise FieldError(name, "contains NaN or Inf")
    if bool((sg <= 0).any()):
        raise FieldError(sigma_field, "expected positive 1σ values")
    return t, y.to(device), S.to(device), O.to(device), sg.to(device)


def _jacobians(spin: np.ndarray, p: torch.Tensor, t: np.ndarray, Si: torch.Tensor, Oi: torch.Tensor, tau: float,
               c: dict, free: list[bool], held: tuple | None) -> tuple:
    """``(J, r, J_held, r_held)``: the noise-normalised residuals of the fitted samples ``r (T,)`` and
    their Jacobian ``J (T, 4 + G)`` in the spin and the free geometry of ``p`` (central differences,
    the albedos solved again at each step: the variable projection's), and the same of the
    held-out samples predicted with the fitted samples' albedos (None without ``held``)."""
    theta = np.concatenate([spin, p.cpu().numpy()[free]])
    idx = torch.as_tensor(np.flatnonzero(free), dtype=torch.long, device=p.device)
    steps = np.concatenate([[1e-6, 1e-6, 1e-6, 1e-6 * abs(spin[3])], 1e-6 * np.maximum(np.abs(theta[4:]), 1e-2)])

    def residuals(th):
        q = p.index_put((idx,), torch.as_tensor(th[4:], device=p.device))
        x = torch.as_tensor(th[:4], device=p.device)
        m, a = _model(x, q, t, Si, Oi, tau, c, albedos=True)
        r = ((c["y"] - m) / c["sigma"]).cpu().numpy()
        if held is None:
            return r, None
        th_, y_h, S_h, O_h, sg_h = held
        return r, ((y_h - _by_part(x, q, th_, S_h, O_h, tau, c, c.get("defect_h")) @ a) / sg_h).cpu().numpy()

    with torch.no_grad():
        r0, rh0 = residuals(theta)
        J = np.empty((len(r0), len(theta)))
        J_h = None if held is None else np.empty((len(rh0), len(theta)))
        for k, h in enumerate(steps):
            e = np.zeros_like(theta)
            e[k] = h
            (rp, hp), (rm, hm) = residuals(theta + e), residuals(theta - e)
            J[:, k] = (rp - rm) / (2 * h)
            if J_h is not None:
                J_h[:, k] = (hp - hm) / (2 * h)
    return J, r0, J_h, rh0
