"""Fitting the parametric box-wing (:mod:`cssat.inversion.parametric`) to a light curve, started
from the convex EGI solution.

The fit minimises a robust (soft-L1) loss of the noise-normalised residuals
``r_t = (y_t − m_t(p)) / σ_t``: ``Σ 2 (sqrt(1 + (r_t/k)²) − 1) k²`` with ``k = huber`` (a glint
many σ above the diffuse model costs linearly, not quadratically). Outer iterations recast the
Embree visibility at the current parameters; inner iterations are L-BFGS-B steps (scipy, the
gradient by torch autograd) with it fixed.
Sizes and albedos are fitted as logarithms (kept positive; L-BFGS-B bounds keep the albedos at
most 1 and the sizes within 1 mm – 1 km), the hinge as an angle, the gap as ``softplus``.

ASSUMPTIONS (beyond the model's): the body frame is the attitude's (known or estimated by
:func:`cssat.inversion.estimate_spin`) and the bus is aligned with its axes, the panels along
±y; flux scales as ``C_d × area``, so size and albedo are separated only through the shadows'
geometry and the bus/panel ratios — an absolute size needs an albedo prior (``cd0``).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import torch

from cssat._checks import FieldError, choice_param, float_param, int_param
from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility, param_names
from cssat.optics.shadow_sampling import check_resolution

__all__ = ["best_box_wing_yaw", "box_wing_start", "box_wing_starts", "box_wing_yaw", "fit_box_wing", "profile_albedos",
           "soft_l1"]

#: the parameters fitted as logarithms of a length (m)
SIZE_NAMES = ("a", "b", "c", "length", "width", "dish_radius", "dish_depth", "dish2_radius", "dish2_depth", "panel_gap",
              "boom_width", "deck_a", "deck_b", "deck_h")
#: the log sizes' bounds (1 mm – 1 km): a long L-BFGS step would otherwise underflow a size to 0
LOG_SIZE_BOUNDS = (math.log(1e-3), math.log(1e3))


def soft_l1(r: torch.Tensor, huber: float) -> torch.Tensor:
    """The fit's robust loss of noise-normalised residuals ``r``: the mean of
    ``2 k² (sqrt(1 + (r/k)²) − 1)``, ``k = huber`` (module docstring)."""
    return (2 * huber**2 * (torch.sqrt(1 + (r / huber) ** 2) - 1)).mean()


def _pooled_egi(normals: Any, areas: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """An EGI checked, ``(N (K, 3), a (K,), near (K, K), pooled (K,))``: ``near`` the pairs of normals
    within 15° of each other or of each other's antipode, ``pooled`` each normal's area with theirs."""
    N, a = np.asarray(normals, dtype=np.float64), np.asarray(areas, dtype=np.float64)
    if N.ndim != 2 or N.shape[1] != 3 or a.shape != (len(N),) or a.sum() <= 0:
        raise FieldError("areas", f"expected K normals (K, 3) and K areas with a positive sum, got {N.shape}, {a.shape}")
    near = np.abs(N @ N.T) >= math.cos(math.radians(15))
    return N, a, near, near @ a


def box_wing_yaw(normals: Any, areas: Any, *, panels: int = 2) -> tuple[float, ...]:
    """The turns ψ (rad) about the body z axis that may bring a box-wing's panels along ±y, from an
    EGI (``normals (K, 3)``, ``areas (K,)``), the likeliest first: the family holds its bus and
    panels on the body axes, but a searched spin's body frame
    (:meth:`~cssat.inversion.results.SpinSolution.frames`) has z on the pole and an arbitrary phase
    about it. Turning the frame by ``R_z(−ψ)`` (vectors ``v @ R.T``) puts the panels' normal in the
    x–z plane.

    ψ is the azimuth of the heaviest direction (antipodal normals pooled within 15°; their
    area-weighted mean direction, so not quantised to the grid of normals): the panels' normal
    where they outweigh the bus — but a bus face where they do not (the spacebus-like of
    ``benchmarks/_platforms.py`` from its searched spin: the heaviest direction a side face, ψ off
    by 90°, its box-wing start χ²/n 4075 against 361 a quarter turn on), so ψ + 90° is returned
    too, second. Where that direction is within 15° of the pole (panels facing ±z: a Lambertian
    EGI does not see their in-plane axis), the heaviest direction within 30° of the x–y plane is
    used instead — a bus face, ψ and ψ + 90° again. With ``panels=1`` (one panel, at +y) each
    ψ + 180° too (a mirror pair is symmetric under that turn, one panel is not). The caller picks
    among them (e.g. by the start's loss, as the experiment's parametric stage does).

    ASSUMPTION: the spin axis is perpendicular to the panels' axis (a box-wing rotating about its
    largest moment of inertia, or any axis in the panels' normal plane)."""
    N, a, near, pooled = _pooled_egi(normals, areas)
    panels = int_param(panels, "panels", 1, 2)

    def mean_direction(k):  # the area-weighted mean of the normals pooled at k, folded onto N[k]'s side
        v = ((near[k] * a * np.sign(N @ N[k]))[:, None] * N).sum(0)
        return v / np.linalg.norm(v)

    n = mean_direction(int(np.argmax(pooled)))
    if math.hypot(n[0], n[1]) < math.sin(math.radians(15)):
        side = np.abs(N[:, 2]) <= math.sin(math.radians(30))
        n = mean_direction(int(np.argmax(np.where(side, pooled, -1))))
    out = [math.atan2(n[1], n[0]), math.atan2(n[1], n[0]) + math.pi / 2]
    if panels == 1:
        out += [psi + math.pi for psi in out]
    return tuple(float((psi + math.pi) % (2 * math.pi) - math.pi) for psi in out)


def best_box_wing_yaw(normals: Any, areas: Any, flux: Any, sun: Any, obs: Any, sigma: Any = None, *,
                      yaws: Any = None, panels: int = 2, divisions: int = 4, cd0: float = 0.3,
                      brief: int = 0) -> tuple[float, np.ndarray]:
    """The turn ψ (rad) among ``yaws`` (default :func:`box_wing_yaw`'s candidates) whose box-wing
    start fits ``flux (T,)`` best, and that start ``p (9,)``: the first of
    :func:`box_wing_starts` at one aspect. A start's cubic bus cannot show a bus heavier than its
    panels, and where the EGI's heaviest direction is such a bus's face the start a quarter turn
    off can misfit less than the right one (``tests/test_parametric_yaw.py``); a brief fit
    (``brief`` > 0) gives the bus its sizes first."""
    _, psi, p0 = box_wing_starts(normals, areas, flux, sun, obs, sigma, yaws=yaws, panels=panels,
                                 divisions=divisions, cd0=cd0, brief=brief)[0]
    return psi, p0


def box_wing_starts(normals: Any, areas: Any, flux: Any, sun: Any, obs: Any, sigma: Any = None, *,
                    yaws: Any = None, aspects: Any = (3.75,), panels: int = 2, divisions: int = 4,
                    cd0: float = 0.3, brief: int = 0) -> list[tuple[float, float, np.ndarray]]:
    """Every box-wing start ``(loss, ψ, p (9,))``, lowest ``loss`` first (the first on a tie), one
    for each turn ψ (rad) among ``yaws`` (default :func:`box_wing_yaw`'s candidates) and each wing
    aspect (length ÷ width) among ``aspects``: the EGI (``normals (K, 3)``, ``areas (K,)``) turned
    by ``R_z(−ψ)`` (vectors ``v @ R.T``) gives :func:`box_wing_start` (``panels``, ``cd0``,
    ``aspect``), whose light curve with Embree's shadows (``divisions``) at the body-frame unit
    directions ``sun, obs (T, 3)`` turned alike is scored by ``Σ ((flux − m) / sigma)²``
    (``sigma (T,)``, None: ones; flux per unit irradiance at 1 m, m²) — or, with ``brief = k >
    0``, by the loss of :func:`fit_box_wing` run from it for one outer iteration of ``k`` L-BFGS-B
    steps (the start itself is returned). A single candidate is returned unscored (loss 0).
    Several starts are a multi-start for a fit whose basin the start decides: the wings' aspect is
    not in the EGI (a convex shape has no shadows), and on a shadowed box-wing a start a noise's
    change away can end in another basin."""
    from cssat.scene.attitude import rot_z  # heavy: cssat.scene imports torch

    brief = int_param(brief, "brief", 0, 10_000)
    yaws = box_wing_yaw(normals, areas, panels=panels) if yaws is None else tuple(float(v) for v in yaws)
    aspects = (aspects,) if isinstance(aspects, (int, float)) else tuple(aspects)
    if not yaws:
        raise FieldError("yaws", "expected at least one turn (rad)")
    if not aspects:
        raise FieldError("aspects", "expected at least one wing aspect (length ÷ width)")
    aspects = tuple(float_param(a, "aspects", 0.0, 100.0, open_lo=True) for a in aspects)
    y = np.asarray(flux, dtype=np.float64)
    S0, V0 = np.asarray(sun, dtype=np.float64), np.asarray(obs, dtype=np.float64)
    if S0.shape != (len(y), 3) or V0.shape != S0.shape:
        raise FieldError("sun", f"expected sun and obs (T, 3) with flux (T,), got {S0.shape}, {V0.shape}, {y.shape}")
    if sigma is not None:
        sigma = np.asarray(sigma, dtype=np.float64)
        if sigma.shape != y.shape or not bool((sigma > 0).all()):
            raise FieldError("sigma", f"expected positive 1σ values of flux's shape {y.shape}, got {sigma.shape}")
    N = np.asarray(normals, dtype=np.float64)
    scored = len(yaws) * len(aspects) > 1
    out = []
    for psi, aspect in itertools.product(yaws, aspects):
        R = rot_z(np.array([psi]))[0]
        p0 = box_wing_start(N @ R.T, areas, panels=panels, cd0=cd0, aspect=aspect)
        loss = 0.0
        if scored:  # the Sun and observer turned alike
            S, V = S0 @ R.T, V0 @ R.T
            if brief:
                loss = fit_box_wing(y, S, V, p0, sigma=sigma, outer=1, inner=brief, panels=panels,
                                    divisions=divisions)[1]["loss"]
            else:
                m = box_wing_light_curve(torch.as_tensor(p0), S, V,
                                         box_wing_visibility(p0, S, V, panels=panels, divisions=divisions),
                                         range_km=1e-3, irradiance=1.0, panels=panels, divisions=divisions).numpy()
                loss = float(np.sum(((y - m) / (1.0 if sigma is None else sigma)) ** 2))
        out.append((float(loss), float(psi), p0))
    return sorted(out, key=lambda c: c[0])  # stable: the first on a tie


def box_wing_start(normals: Any, areas: Any, *, panels: int = 2, cd0: float = 0.3, aspect: float = 3.75) -> np.ndarray:
    """A starting box-wing ``p (9,)`` from an EGI (``normals (K, 3)``, ``areas (K,)`` in m² × albedo):
    the panel normal is the heaviest axis (antipodal areas pooled) perpendicular to y within 30°,
    which gives the hinge; the panels take that direction's area (one side), the rest is a cubic
    bus; sizes are ``area / cd0``; a panel's length is ``aspect`` × its width."""
    N, a, _, pooled = _pooled_egi(normals, areas)
    cd0 = float_param(cd0, "cd0", 0.0, 1.0, open_lo=True)
    side = np.abs(N[:, 1]) <= math.sin(math.radians(30))
    k = int(np.argmax(np.where(side, pooled, -1)))
    n = N[k] * np.sign(N[k, 0] if abs(N[k, 0]) > 1e-9 else 1.0)
    hinge = math.atan2(-n[2], n[0])
    total = a.sum() / cd0
    panel_one_side = min(0.45 * pooled[k] / cd0, 0.8 * total / 2)
    width = math.sqrt(max(panel_one_side / panels / aspect, 1e-6))
    h = math.sqrt(max(total - 2 * panel_one_side, 0.05 * total) / 24)
    return np.array([h, h, h, aspect * width, width, hinge, 0.5 * h, cd0, cd0])


def _transform(names: tuple[str, ...]) -> tuple[torch.Tensor, torch.Tensor]:
    """The indices of ``names`` fitted as logarithms (sizes, albedos) and of the gap (``softplus``);
    every other (angles, positions) is fitted as it is."""
    log = [k for k, n in enumerate(names) if n in SIZE_NAMES or n.startswith("cd_")]
    return torch.as_tensor(log, dtype=torch.long), torch.as_tensor([names.index("gap")], dtype=torch.long)


def _to_p(z: torch.Tensor, transform: tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
    """The free variables ``z`` (log sizes and albedos, softplus⁻¹ gap, angles and positions as
    they are) as ``p``; ``transform``: :func:`_transform`'s indices."""
    log, gap = transform
    return z.index_put((log,), z[log].exp()).index_put((gap,), torch.nn.functional.softplus(z[gap]))


def _to_z(p: np.ndarray, transform: tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
    log, gap = transform
    z = np.array(p, dtype=np.float64)
    g = max(float(p[int(gap[0])]), 1e-6)
    z[log.numpy()] = np.log(z[log.numpy()])
    z[int(gap[0])] = g + math.log(-math.expm1(-g))  # softplus⁻¹
    return torch.as_tensor(z, dtype=torch.float64)


def profile_albedos(Y: torch.Tensor, y: torch.Tensor, sigma: torch.Tensor, cd: torch.Tensor,
                    free: torch.Tensor) -> torch.Tensor:
    """The albedos ``(P,)`` that fit ``y (T,)`` best in the σ-weighted least-squares sense given each
    part's curve at unit albedo ``Y (T, P)`` (:func:`~cssat.inversion.parametric.box_wing_light_curve`'s
    ``by_part``): the ``free (P,)`` bool entries solved within [1e-4, 1], the others held at
    ``cd (P,)``. Exact bounded least squares: every assignment of the free albedos to "solved",
    "at 1e-4" or "at 1" (3^P ≤ 27 small solves, P ≤ 3) is tried and the feasible one of least cost
    kept (the unconstrained solution at once when it is within them). Differentiable in ``Y`` (a
    variable projection: the fit's gradient sees the albedos follow the geometry). Least squares,
    not a robust loss: a glint the model lacks pulls them."""
    lo, hi = 1e-4, 1.0
    Yw, yw = Y / sigma[:, None], y / sigma
    k = torch.nonzero(free).flatten().tolist()
    if len(k) > 6:
        raise FieldError("free", f"at most 6 albedos solved (3^P active sets are tried), got {len(k)}")
    best: tuple[float, torch.Tensor] = (math.inf, cd)
    for state in itertools.product((0, 1, 2), repeat=len(k)):
        c = cd.clone()
        c[[j for j, s in zip(k, state) if s == 1]] = lo
        c[[j for j, s in zip(k, state) if s == 2]] = hi
        solve = [j for j, s in zip(k, state) if s == 0]
        if solve:
            A = Yw[:, solve]
            rest = [j for j in range(len(cd)) if j not in solve]
            G = A.T @ A
            G = G + 1e-12 * G.diagonal().max().clamp(min=1e-300) * torch.eye(len(solve), dtype=G.dtype, device=G.device)
            sol = torch.linalg.solve(G, A.T @ (yw - Yw[:, rest] @ c[rest]))
            if bool(((sol < lo) | (sol > hi)).any()):
                continue
            c = c.index_put((torch.as_tensor(solve, device=c.device),), sol)
        if not any(state):  # the unconstrained optimum is within the bounds: it is the bounded one (a convex problem)
            return c
        cost = float(((yw - Yw @ c) ** 2).sum().detach())
        if cost < best[0]:
            best = (cost, c)
    return best[1]


def shadow_defect(p: torch.Tensor, sun: Any, observer: Any, tau: float, resolution_m: float, **geo: Any) -> torch.Tensor:
    """``(T, P)``: each part's curve at unit albedo with its sub-facets' shadows resolved (rays
    ``resolution_m`` apart: :func:`~cssat.inversion.parametric.box_wing_visibility`) less its soft
    one at softness ``tau`` (:func:`~cssat.inversion.soft_shadow.soft_visibility`), at the family
    ``p`` (``geo`` its keywords) and body-frame ``sun, observer (T, 3)`` — the defect that
    :func:`fit_box_wing` and :func:`~cssat.inversion.parametric_spin.refine_spin` add to the soft
    model, fixed (no gradient)."""
    from cssat.inversion.soft_shadow import soft_visibility  # local: only for soft shadows resolved

    kw = dict(geo, by_part=True, range_km=1e-3, irradiance=1.0)
    with torch.no_grad():
        cast = box_wing_visibility(p, sun, observer, resolution_m=resolution_m, **geo).to(p.device)
        soft = soft_visibility(p, sun, observer, tau=tau, front_only=True, **geo)
        return box_wing_light_curve(p, sun, observer, cast, **kw) - box_wing_light_curve(p, sun, observer, soft, **kw)


def fit_box_wing(y: Any, sun: Any, observer: Any, p0: Any, *, sigma: Any = None, panels: int = 2, divisions: int = 4,
                 outer: int = 5, inner: int = 40, huber: float = 3.0, dishes: int = 0, dish_rings: int = 12,
                 dish_segments: int = 40, fixed: Any = (), visibility: str = "cast",
                 softness: float = 0.1, albedos: str = "fit", resolution_m: float | None = None,
                 **parts: Any) -> tuple[np.ndarray, dict[str, Any]]:
    """The box-wing ``p (9,)`` fitting ``y (T,)`` (flux per unit irradiance at 1 m, i.e. m²) at
    body-frame ``sun, observer (T, 3)``, from ``p0 (9,)``; ``sigma (T,)`` the 1σ (None: ones).
    With ``dishes`` (1 or 2, :mod:`cssat.inversion.parametric`), ``p0`` and ``p`` are ``(17,)``:
    the reflector dishes' position, axis, size and albedo fitted too; ``parts`` (``dish_pair``,
    ``wing_panels``, ``booms``, ``deck``: :func:`~cssat.inversion.parametric.box_wing`) add their
    parameters (:func:`~cssat.inversion.parametric.param_names`). ``fixed``: names of
    parameters (:func:`~cssat.inversion.parametric.param_names`) held at ``p0`` (e.g. a bus whose
    size is known). Returns ``(p, info)`` with ``info``: ``loss``, ``rms_over_noise`` (the fit's
    χ-rms) and ``params`` (a name → value dict).

    ``visibility``: ``"cast"`` (default) holds each outer iteration's Embree visibility fixed
    through its L-BFGS-B run (the gradient does not see a shadow move: ∂y/∂gap = 0); ``"soft"``
    makes it a differentiable function of ``p`` inside the loss
    (:func:`~cssat.inversion.soft_shadow.soft_visibility`), its edge softness ``softness`` × the
    start's mean bus half-size at the first outer iteration, halved at each next one (a
    continuation towards the hard shadows; the start is scored too, so it ends no worse than
    it began). Either way each outer iteration is scored, and the best kept, with the cast
    visibility (``loss``, ``rms_over_noise``: the hard-shadowed model's).

    ``resolution_m`` (m; None: one ray a sub-facet): the cast visibility resolved below a
    sub-facet (:func:`~cssat.inversion.parametric.box_wing_visibility`: each one's fraction lit
    and seen), so the scored and returned model is that of a fine grid while the gradient runs on
    ``divisions`` cells; with ``"soft"`` each outer iteration adds to the soft model the defect
    ``Y_cast − Y_soft`` of each part's curve at its start (held fixed through the run: a defect
    correction — at a fixed point the model is the resolved cast one, the gradient the soft one's).

    ``albedos``: ``"fit"`` (default) fits the albedos by gradient with the rest; ``"profile"`` solves
    them at every evaluation (:func:`profile_albedos`: σ-weighted least squares, the light curve being
    linear in them; those in ``fixed`` held) — the gradient steps move the geometry alone, along
    the size–albedo valley too; the geometry's loss stays the soft-L1 one, but the albedos are the
    least-squares ones (a glint the family lacks pulls them)."""
    names = param_names(dishes, **parts)
    transform = _transform(names)
    fixed = [fixed] if isinstance(fixed, str) else list(fixed or ())
    unknown = [n for n in fixed if n not in names]
    if unknown:
        raise FieldError("fixed", f"expected names among {list(names)}, got {unknown}")
    outer = int_param(outer, "outer", 1, 100)
    inner = int_param(inner, "inner", 1, 1000)
    huber = float_param(huber, "huber", 0.0, open_lo=True)
    visibility = choice_param(visibility, "visibility", ("cast", "soft"))
    profile = choice_param(albedos, "albedos", ("fit", "profile")) == "profile"
    softness = float_param(softness, "softness", 0.0, open_lo=True)
    resolution_m = check_resolution(resolution_m)
    yt = torch.as_tensor(np.asarray(y, dtype=np.float64))
    sg = torch.ones_like(yt) if sigma is None else torch.as_tensor(np.asarray(sigma, dtype=np.float64))
    if sg.shape != yt.shape or bool((sg <= 0).any()):
        raise FieldError("sigma", f"expected {tuple(yt.shape)} positive values, got {tuple(sg.shape)}")
    S, V = np.asarray(sun, dtype=np.float64), np.asarray(observer, dtype=np.float64)
    geo = dict(panels=panels, divisions=divisions, **parts, **(dict(dishes=dishes, dish_rings=dish_rings,
                                                                    dish_segments=dish_segments) if dishes else {}))
    kw = dict(geo, range_km=1e-3, irradiance=1.0)
    from scipy.optimize import minimize  # heavy: scipy.optimize (torch.optim would import torch._dynamo, ~4 s)

    def cast(z):
        return box_wing_visibility(_to_p(z, transform), S, V, resolution_m=resolution_m, **geo)

    def loss_of(z, vis, defect=None):
        if isinstance(vis, float):  # the soft visibility's τ (m): the shadows differentiable
            from cssat.inversion.soft_shadow import soft_visibility  # local: only for visibility="soft"

            vis = soft_visibility(_to_p(z, transform), S, V, tau=vis, front_only=True, **geo)
        return soft_l1((yt - model(_to_p(z, transform), vis, defect)) / sg, huber)

    cd_idx = torch.as_tensor([names.index(n) for n in names if n.startswith("cd_")])
    cd_free = torch.as_tensor([n not in fixed for n in names if n.startswith("cd_")])

    def model(p, vis, defect=None):
        if not profile and defect is None:
            return box_wing_light_curve(p, S, V, vis, **kw)
        Y = box_wing_light_curve(p, S, V, vis, by_part=True, **kw)
        Y = Y if defect is None else Y + defect
        return Y @ (profile_albedos(Y, yt, sg, p[cd_idx], cd_free) if profile else p[cd_idx])

    p0 = np.asarray(p0, dtype=np.float64)
    if p0.shape != (len(names),):
        raise FieldError("p0", f"expected {len(names)} values {names}, got shape {p0.shape}")
    z0 = _to_z(p0, transform)
    free = np.array([n not in fixed and not (profile and n.startswith("cd_")) for n in names])

    free_idx = torch.as_tensor(np.flatnonzero(free))
    # the albedos (fitted as logarithms) at most 1: a diffuse surface reflects no more than arrives; the sizes
    # (logarithms) within LOG_SIZE_BOUNDS
    bounds = [(None, 0.0) if n.startswith("cd_") else LOG_SIZE_BOUNDS if n in SIZE_NAMES else (None, None)
              for n, f in zip(names, free) if f]

    def full(x):
        """All of ``z``: the free variables ``x`` (differentiable) among the fixed ones of ``p0``."""
        xt = torch.as_tensor(x, dtype=torch.float64)
        return xt if free.all() else z0.index_put((free_idx,), xt)

    def value_and_grad(x, vis, defect):
        xt = torch.as_tensor(x, dtype=torch.float64).requires_grad_(True)
        z = full(xt)
        loss = loss_of(z, vis, defect)
        (g,) = torch.autograd.grad(loss, xt)
        return float(loss.detach()), g.numpy()

    z = z0
    best = (math.inf, z)
    if visibility == "soft":  # the start scored too (its cast visibility): a continuation ends no worse than it began
        with torch.no_grad():
            best = (float(loss_of(z0, cast(z0))), z0)
    tau0 = softness * float(np.mean(p0[:3]))
    for k in range(outer):
        vis = tau0 * 0.5**k if visibility == "soft" else cast(z)
        defect = shadow_defect(_to_p(z, transform), S, V, vis, resolution_m, **geo) \
            if visibility == "soft" and resolution_m is not None and free.any() else None
        if free.any():  # nothing free (every geometry held, the albedos profiled): only scored
            z = full(minimize(value_and_grad, z.numpy()[free], args=(vis, defect), jac=True, method="L-BFGS-B",
                              bounds=bounds, options={"maxiter": inner}).x)
        with torch.no_grad():  # score with the visibility recast at the new parameters
            val = float(loss_of(z, cast(z)))
        if val < best[0]:
            best = (val, z)
    p = _to_p(best[1], transform)
    vis = cast(best[1])
    if profile:  # the albedos the loss used
        p = p.index_put((cd_idx,), profile_albedos(box_wing_light_curve(p, S, V, vis, by_part=True, **kw), yt, sg,
                                                   p[cd_idx], cd_free))
    r = (yt - box_wing_light_curve(p, S, V, vis, **kw)) / sg
    p = p.numpy()
    return p, {"loss": best[0], "rms_over_noise": float(torch.sqrt((r**2).mean())),
               "params": dict(zip(names, map(float, p)))}
