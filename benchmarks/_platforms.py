"""Two box-wing-with-dishes GEO platforms built here with cssat's mesh primitives, as truths that
the parametric family (:mod:`cssat.inversion.parametric`) does not contain: each has details
the family has no parameter for (wings of separate panels with gaps between them, yoke booms,
an Earth-deck tower or module with its own small antenna, an apogee-engine cylinder, and — on
the second — two dishes that are not mirror images). Proportions are generic, in the range of
published GEO communications platforms, not any one satellite's drawings.

Body frame as :func:`cssat.scene.models.astra_like`'s: +z the Earth deck, the wings along ±y,
the east/west faces ±x. Part albedos (``materials``): bus 0.35 (MLI), wings 0.1 (cells, both
sides), dishes 0.6 (white paint), booms, tower and engine 0.35.

Each builder returns ``(mesh, nominal)``: ``nominal (17,)`` the family's parameters nearest to
the platform by construction (its bus's half-sizes, one wing's panels and gaps as one panel,
the yoke as the gap, the larger dish), the start of the benchmark's oracle rows. :data:`FINE`
holds, for the family with its finer parts (``wing_panels``, ``booms``, ``deck``, ``dish_pair``:
:mod:`cssat.inversion.parametric`), each platform's parts and parameters by construction: what
that family leaves out is the tower's small dish and the engine (b702), the omni mast (spacebus).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

BUS, WING, DISH = 0.35, 0.1, 0.6


def _wing(side: int, n: int, length: float, gap: float, width: float, hinge_deg: float, root: float) -> list:
    """``n`` two-sided panels ``length × width`` along ``side`` × y with ``gap`` between them,
    the first at ``|y| = root``, turned ``hinge_deg`` about y (the family's hinge convention)."""
    from cssat.scene.models import panel

    h = math.radians(hinge_deg)
    w = width * np.array([math.sin(h), 0.0, math.cos(h)])
    out = []
    for k in range(n):
        y0 = root + k * (length + gap)
        u = np.array([0.0, side * length, 0.0])
        origin = np.array([0.0, side * y0, 0.0]) - w / 2
        first, second = (u, w) if side > 0 else (w, u)
        out.append(panel(first, second, origin, divisions=(2, 2), cd=WING, cs=0.0))
    return out


def _dish_angles(axis: Any) -> tuple[float, float]:
    """The family's ``(dish_tilt, dish_azimuth)`` (rad) of a dish axis."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return math.acos(a[2]), math.atan2(a[1], a[0])


def b702_like() -> tuple[Any, np.ndarray]:
    """A large box-wing: a 3.2 × 3.0 × 4.2 m bus (x, y, z); each wing three 2.6 × 3.0 m panels
    with 0.12 m gaps on a 1.8 m boom, turned 20°; a mirror pair of 1.35 m reflectors on the ±x
    faces, tilted 27° towards the Earth deck; a 1.0 × 1.0 × 0.8 m tower on the Earth deck with a
    0.45 m dish on top; an apogee-engine cylinder (r 0.35 m, 0.6 m) under the bus."""
    from cssat.scene.mesh import merge
    from cssat.scene.models import box, cylinder, dish

    a, b, c, boom = 1.6, 1.5, 2.1, 1.8
    parts = [box((2 * a, 2 * b, 2 * c), divisions=4, cd=BUS, cs=0.0)]
    for side in (1, -1):
        parts.append(box((0.1, boom, 0.1), center=(0.0, side * (b + boom / 2), 0.0), cd=BUS, cs=0.0))
        parts += _wing(side, 3, 2.6, 0.12, 3.0, 20.0, b + boom)
        parts.append(dish(1.35, 0.4, center=(side * (a + 0.15), 0.0, 1.0), axis=(side * 0.5, 0.0, 1.0), rings=8,
                          segments=32, cd=DISH, cs=0.0))
    parts.append(box((1.0, 1.0, 0.8), center=(0.0, 0.0, c + 0.4), cd=BUS, cs=0.0))
    parts.append(dish(0.45, 0.12, center=(0.0, 0.0, c + 0.8), axis=(0.0, 0.0, 1.0), rings=4, segments=16, cd=DISH, cs=0.0))
    parts.append(cylinder(0.35, 0.6, center=(0.0, 0.0, -c - 0.3), axis=(0.0, 0.0, 1.0), segments=16, cd=BUS, cs=0.0))
    tilt, az = _dish_angles((0.5, 0.0, 1.0))
    nominal = np.r_[a, b, c, 3 * 2.6 + 2 * 0.12, 3.0, math.radians(20.0), boom, BUS, WING,
                    a + 0.15, 0.0, 1.0, tilt, az, 1.35, 0.4, DISH]
    return merge(parts, name="b702_like"), nominal


def fine_params(nominal: np.ndarray, parts: dict, **extra: float) -> tuple[dict, dict]:
    """``(parts, params)`` of the finer family: the plain family's ``nominal (17,)`` with ``extra``
    (the parts' own parameters, and any of the plain ones to replace), in
    :func:`~cssat.inversion.parametric.param_names`' order."""
    from cssat.inversion.parametric import param_names

    base = dict(zip(param_names(2), map(float, nominal)), **extra)
    return parts, {k: float(base[k]) for k in param_names(**parts)}


def spacebus_like() -> tuple[Any, np.ndarray]:
    """A tall box-wing with unequal dishes: a 2.2 × 2.0 × 4.6 m bus; each wing four 1.9 × 2.2 m
    panels with 0.08 m gaps on a 1.2 m boom, turned −40°; a 1.2 m reflector on the +x face tilted
    31° towards the Earth deck, a 0.9 m one low on the −x face looking out and 17° up, off the
    y = 0 plane (not the +x one's mirror image); an 0.8 × 0.6 × 0.4 m module on the Earth deck
    with a 1 m omni mast."""
    from cssat.scene.mesh import merge
    from cssat.scene.models import box, cylinder, dish

    a, b, c, boom = 1.1, 1.0, 2.3, 1.2
    parts = [box((2 * a, 2 * b, 2 * c), divisions=4, cd=BUS, cs=0.0)]
    for side in (1, -1):
        parts.append(box((0.1, boom, 0.1), center=(0.0, side * (b + boom / 2), 0.0), cd=BUS, cs=0.0))
        parts += _wing(side, 4, 1.9, 0.08, 2.2, -40.0, b + boom)
    parts.append(dish(1.2, 0.36, center=(a + 0.1, 0.3, 0.8), axis=(0.6, 0.0, 1.0), rings=8, segments=32, cd=DISH, cs=0.0))
    parts.append(dish(0.9, 0.25, center=(-a - 0.1, -0.2, -0.4), axis=(-1.0, 0.0, 0.3), rings=8, segments=32, cd=DISH,
                      cs=0.0))
    parts.append(box((0.8, 0.6, 0.4), center=(0.0, 0.0, c + 0.2), cd=BUS, cs=0.0))
    parts.append(cylinder(0.05, 1.0, center=(0.3, 0.0, c + 0.9), axis=(0.0, 0.0, 1.0), segments=8, cd=BUS, cs=0.0))
    tilt, az = _dish_angles((0.6, 0.0, 1.0))
    nominal = np.r_[a, b, c, 4 * 1.9 + 3 * 0.08, 2.2, math.radians(-40.0), boom, BUS, WING,
                    a + 0.1, 0.3, 0.8, tilt, az, 1.2, 0.36, DISH]
    return merge(parts, name="spacebus_like"), nominal


#: the finer family's parts and parameters of each platform (module docstring): ``name → (parts, params)``
FINE = {
    "b702_like": fine_params(
        np.r_[1.6, 1.5, 2.1, 2.6, 3.0, math.radians(20.0), 1.8, BUS, WING, 1.75, 0.0, 1.0, *_dish_angles((0.5, 0.0, 1.0)),
              1.35, 0.4, DISH],
        dict(dishes=2, wing_panels=3, booms=True, deck=True),
        panel_gap=0.12, boom_width=0.1, deck_a=0.5, deck_b=0.5, deck_h=0.8),
    "spacebus_like": fine_params(
        np.r_[1.1, 1.0, 2.3, 1.9, 2.2, math.radians(-40.0), 1.2, BUS, WING, 1.2, 0.3, 0.8, *_dish_angles((0.6, 0.0, 1.0)),
              1.2, 0.36, DISH],
        dict(dishes=2, dish_pair="free", wing_panels=4, booms=True, deck=True),
        dish2_x=-1.2, dish2_y=-0.2, dish2_z=-0.4, dish2_tilt=_dish_angles((-1.0, 0.0, 0.3))[0],
        dish2_azimuth=_dish_angles((-1.0, 0.0, 0.3))[1], dish2_radius=0.9, dish2_depth=0.25,
        panel_gap=0.08, boom_width=0.1, deck_a=0.4, deck_b=0.3, deck_h=0.4),
}

