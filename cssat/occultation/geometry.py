"""The occultation's geometry and the occulter's silhouette (issue 25, point 1).

The *fundamental plane* (the occultation convention of Bessel, used by SORA and pyote for
asteroids) is the plane through the observer perpendicular to the star's direction ``d``; the
occulter's shadow moves across it. The satellite's shadow centre, relative to the observer, is
``s(t) = P (r_sat(t) − r_obs(t))`` with ``P = I − d dᵀ``; its velocity ``ṡ`` (km/s) sets the
shadow's speed and direction over the ground (≈ 2.6 km/s for a GEO satellite: the star drifts
at the sidereal rate behind a nearly fixed satellite; on the ground itself the shadow is longer
by ``1/cos`` of the star's zenith angle along the star's azimuth; the experiment stands its
telescopes on level ground and projects them into the plane along the starlight;
:func:`ground_to_plane` and :func:`plane_to_ground` convert positions). Assumptions: a star at infinity (parallel light), the satellite's positions of the
scenario (SGP4), the star's catalogue direction (no aberration or proper motion: the shadow
track is shifted, not changed, by them).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cssat._checks import FieldError, float_param, int_param
from cssat.scene import as_mesh

__all__ = ["bar_target", "star_direction", "plane_basis", "shadow_track", "silhouette", "ground_to_plane", "plane_to_ground"]


def star_direction(ra_deg: float, dec_deg: float) -> np.ndarray:
    """The unit vector ``(3,)`` (GCRS) of a star at right ascension / declination (ICRS, deg)."""
    ra = np.radians(float_param(ra_deg, "star.ra_deg", -360.0, 360.0))
    dec = np.radians(float_param(dec_deg, "star.dec_deg", -90.0, 90.0))
    return np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])


def plane_basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``(e_east, e_north)`` spanning the fundamental plane ⟂ ``d``: ``e_north``
    towards the celestial north pole's projection, ``e_east = e_north × d`` (east on the sky as
    seen from the ground)."""
    d = np.asarray(d, dtype=np.float64)
    d = d / np.linalg.norm(d)
    z = np.array([0.0, 0.0, 1.0])
    n = z - d * (z @ d)
    if np.linalg.norm(n) < 1e-12:  # a star at the pole: any north
        n = np.array([1.0, 0.0, 0.0]) - d * d[0]
    n /= np.linalg.norm(n)
    return np.cross(n, d), n


def _topocentric(alt_deg: float, az_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The star's direction ``s`` and the plane's basis ``(u, w)`` in local east–north–up: ``u``
    horizontal, to the right of the star's azimuth seen from the ground; ``w = u × s``, the
    zenith's projection (up the sky)."""
    alt = np.radians(float_param(alt_deg, "star_alt_deg", 0.0, 90.0, open_lo=True))
    az = np.radians(float_param(az_deg, "star_az_deg", -360.0, 360.0))
    s = np.array([np.cos(alt) * np.sin(az), np.cos(alt) * np.cos(az), np.sin(alt)])
    u = np.array([np.cos(az), -np.sin(az), 0.0])
    return s, u, np.cross(u, s)


def ground_to_plane(enu_m: Any, star_alt_deg: float, star_az_deg: float) -> np.ndarray:
    """Telescope offsets on the ground ``enu_m (N, 2)`` (east, north) or ``(N, 3)`` (+ up), m, as
    fundamental-plane coordinates ``(N, 2)`` (across: horizontal, right of the star's azimuth;
    up-sky: the zenith's projection), for a star at altitude ``star_alt_deg`` > 0 and azimuth
    ``star_az_deg`` (from north through east): the projection along the star's light,
    ``p = g − (g·s) s``, whose coordinates on the plane's basis ``u, w ⟂ s`` are ``g·u, g·w``. A ground offset towards the star's azimuth shrinks by ``sin(alt)`` in
    the plane, one across it not at all: telescopes 25 m apart in the plane along the up-sky axis
    stand ``25/sin(alt)`` m apart on the ground (49 m at 31°)."""
    g = np.asarray(enu_m, dtype=np.float64)
    if g.ndim != 2 or g.shape[1] not in (2, 3):
        raise FieldError("enu_m", f"expected ground offsets of shape (N, 2) or (N, 3), got {g.shape}")
    if g.shape[1] == 2:
        g = np.concatenate([g, np.zeros((len(g), 1))], 1)
    _, u, w = _topocentric(star_alt_deg, star_az_deg)
    return np.stack([g @ u, g @ w], 1)


def plane_to_ground(plane_m: Any, star_alt_deg: float, star_az_deg: float) -> np.ndarray:
    """Where the star's rays through fundamental-plane points ``plane_m (N, 2)`` (across, up-sky;
    m) meet level ground: east–north offsets ``(N, 2)``, m — the inverse of
    :func:`ground_to_plane` on flat ground (``g = p + λ s`` with ``g_up = 0``)."""
    q = np.asarray(plane_m, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 2:
        raise FieldError("plane_m", f"expected plane coordinates of shape (N, 2), got {q.shape}")
    s, u, w = _topocentric(star_alt_deg, star_az_deg)
    p = q[:, :1] * u + q[:, 1:] * w
    g = p - (p[:, 2] / s[2])[:, None] * s
    return g[:, :2]


def shadow_track(scenario: Any, d: np.ndarray) -> dict[str, np.ndarray]:
    """The shadow centre in the fundamental plane over the ``scenario``'s times: ``xy_km (T, 2)``
    (east, north of the observer), ``velocity_km_s (T, 2)`` (central differences), ``speed_km_s
    (T,)``, ``distance_km (T,)`` (the satellite's distance along ``d``: the propagation distance)
    and ``miss_km (T,)`` (the shadow centre's distance from the observer)."""
    if len(scenario) < 2:
        raise FieldError("scenario.n_steps", "the shadow's velocity needs at least 2 times")
    e, n = plane_basis(d)
    rel = scenario.r_sat - scenario.r_obs
    xy = np.stack([rel @ e, rel @ n], 1)
    t = (scenario.times - scenario.times[0]) / np.timedelta64(1, "s")
    v = np.gradient(xy, t, axis=0)
    return {"xy_km": xy, "velocity_km_s": v, "speed_km_s": np.linalg.norm(v, axis=1), "distance_km": rel @ d,
            "miss_km": np.linalg.norm(xy, axis=1)}


def silhouette(mesh: Any, view_body: Any, pixel_m: float, size: int, *, supersample: int = 4,
               center: Any = None) -> np.ndarray:
    """The occulter mask ``(size, size)`` in [0, 1] (1 = opaque: the fraction of each pixel the
    mesh covers, from ``supersample``² samples a pixel) of ``mesh`` projected along the
    body-frame unit vector ``view_body`` (from the star through the satellite to the observer,
    or its opposite: a projection), on a grid of ``pixel_m`` centred on ``center`` (body frame,
    m; default the mesh's bounding-box centre). Rows run along the plane's ``e_north`` of
    :func:`plane_basis` (of ``view_body``), columns along ``e_east``."""
    from skimage.draw import polygon  # heavy: scikit-image, only for silhouette()

    m = as_mesh(mesh)
    size = int_param(size, "size", 1, 1 << 14)
    ss = int_param(supersample, "supersample", 1, 64)
    pixel_m = float_param(pixel_m, "pixel_m", 0.0, open_lo=True)
    v = np.asarray(view_body, dtype=np.float64).reshape(3)
    if not np.isfinite(v).all() or np.linalg.norm(v) == 0:
        raise FieldError("view_body", f"expected a direction (3,), got {view_body!r}")
    e, n = plane_basis(v)
    verts = np.asarray(m.vertices, dtype=np.float64)
    c = (verts.min(0) + verts.max(0)) / 2 if center is None else np.asarray(center, dtype=np.float64)
    p = verts - c
    fine = size * ss
    step = pixel_m / ss
    # fine-grid coordinates: pixel centres of the fine grid at (k + 0.5) step − size·pixel/2
    col = (p @ e) / step + fine / 2 - 0.5
    row = (p @ n) / step + fine / 2 - 0.5
    out = np.zeros((fine, fine), bool)
    tri = np.asarray(m.faces)
    for f in tri:
        rr, cc = polygon(row[f], col[f], shape=out.shape)
        out[rr, cc] = True
    return out.reshape(size, ss, size, ss).mean((1, 3))


def bar_target(size: int, pixel_m: float, bar_m: float = 0.5, *, n_bars: int = 4, length_m: float = 4.0) -> np.ndarray:
    """A resolution target ``(size, size)`` in [0, 1] (pixel-area fractions, 1 = opaque): a 2 m
    square "bus" at the centre and two groups of ``n_bars`` bars ``bar_m`` wide and ``length_m``
    long separated by gaps of ``bar_m`` — north of the bus the bars run east–west (their gaps
    resolved across the array's line), south of it north–south (their gaps resolved along the
    shadow's motion, by time). Whether the gaps come back (:func:`~cssat.occultation.feature_contrast`)
    says whether ``bar_m`` features are resolved."""
    size = int_param(size, "size", 8, 1 << 14)
    px = float_param(pixel_m, "pixel_m", 0.0, open_lo=True)
    bar = float_param(bar_m, "bar_m", 0.0, open_lo=True)
    n = int_param(n_bars, "n_bars", 1, 1000)
    ss = 8
    c = (np.arange(size * ss) + 0.5) / ss * px - size * px / 2  # fine-grid centres, m
    X, Y = np.meshgrid(c, c)  # columns east, rows north
    out = (np.abs(X) <= 1.0) & (np.abs(Y) <= 1.0)
    group = (2 * n - 1) * bar  # the bars and gaps across the group
    for k in range(n):
        lo = -group / 2 + 2 * k * bar
        out |= (Y >= 1.5 + lo + group / 2) & (Y < 1.5 + lo + group / 2 + bar) & (np.abs(X) <= length_m / 2)
        out |= (X >= lo) & (X < lo + bar) & (Y <= -1.5) & (Y >= -1.5 - length_m)
    if (np.abs(Y[out]).max() if out.any() else 0) > size * px / 2 - px:
        raise FieldError("size", f"the bar target does not fit a {size} × {size} grid of {px:g} m pixels")
    return out.reshape(size, ss, size, ss).mean((1, 3))
