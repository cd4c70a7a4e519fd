"""A direction's error ellipse (cssat.inversion.ellipse): the tangent plane against spherical
trigonometry, the ellipse against a known spread, and the regions' levels against a Monte
Carlo written here (Gaussian draws, the covariance known or estimated from replicates)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cssat._checks import FieldError


def _from_offset(center, east, north):
    """The direction ``(lon, lat)`` at ``(east, north)`` degrees from ``center`` along the great
    circle (spherical trigonometry, independent of the module's projection)."""
    lon0, lat0 = (math.radians(v) for v in center)
    d, b = math.radians(math.hypot(east, north)), math.atan2(east, north)
    lat = math.asin(math.sin(lat0) * math.cos(d) + math.cos(lat0) * math.sin(d) * math.cos(b))
    lon = lon0 + math.atan2(math.sin(b) * math.sin(d) * math.cos(lat0), math.cos(d) - math.sin(lat0) * math.sin(lat))
    return math.degrees(lon), math.degrees(lat)


@pytest.mark.parametrize("center", [(10.0, 20.0), (200.0, -75.0), (0.0, 89.5)])
def test_the_tangent_offset_inverts_the_great_circle_step(center):
    from cssat.inversion.ellipse import tangent_offset
    from cssat.inversion.spin_errors import separation_deg

    for east, north in [(0.7, 0.0), (0.0, -1.3), (2.0, 1.5), (-0.01, 0.02)]:
        point = _from_offset(center, east, north)
        got = tangent_offset(center, point)
        assert got == pytest.approx([east, north], abs=1e-9)
        assert float(np.hypot(*got)) == pytest.approx(separation_deg(center, point), abs=1e-7)
    assert tangent_offset(center, center) == pytest.approx([0.0, 0.0], abs=1e-12)


def test_the_ellipse_of_a_known_spread():
    """Offsets ±a along the position angle and ±b across it (four of them): second moments a²/2,
    b²/2 — semi-axes a/√2, b/√2."""
    from cssat.inversion.ellipse import ellipse_of_cov, error_ellipse

    a, b, pa = 0.8, 0.3, 120.0
    u = np.array([math.sin(math.radians(pa)), math.cos(math.radians(pa))])  # (east, north) along pa
    v = np.array([u[1], -u[0]])
    major, minor, got_pa = error_ellipse([a * u, -a * u, b * v, -b * v])
    assert (major, minor, got_pa) == pytest.approx((a / math.sqrt(2), b / math.sqrt(2), pa))
    assert ellipse_of_cov(np.diag([0.04, 0.09])) == pytest.approx((0.3, 0.2, 0.0))  # north the longer axis
    assert ellipse_of_cov(np.diag([0.09, 0.04])) == pytest.approx((0.3, 0.2, 90.0))


@pytest.mark.parametrize("dof", [0, 20])
def test_the_regions_hold_their_levels_in_a_monte_carlo(dof):
    """Gaussian offsets of a tilted 3:1 spread: with the covariance known (``dof`` 0) each
    draw's level against the true ellipse; with ``dof = 20`` the ellipse estimated from 20 other
    draws each time (Hotelling). The fraction at or below 0.6827 / 0.9545 matches within 3.5
    binomial σ; the Gaussian levels with an estimated covariance under-cover (the reason for
    Hotelling's)."""
    from cssat.inversion.ellipse import ellipse_level, ellipse_of_cov, error_ellipse

    rng = np.random.default_rng(3)
    A = np.array([[0.5, 0.0], [0.35, 0.17]])  # offsets = A @ z: covariance A Aᵀ
    center, n = (33.0, -12.0), 3000
    true = ellipse_of_cov(A @ A.T)
    levels, naive = [], []
    for _ in range(n):
        east, north = A @ rng.standard_normal(2)
        point = _from_offset(center, east, north)
        ell = error_ellipse(rng.standard_normal((dof, 2)) @ A.T) if dof else true
        levels.append(ellipse_level(center, point, *ell, dof=dof))
        naive.append(ellipse_level(center, point, *ell))
    levels, naive = np.array(levels), np.array(naive)
    for q in (0.6827, 0.9545):
        assert abs(np.mean(levels <= q) - q) < 3.5 * math.sqrt(q * (1 - q) / n), (q, np.mean(levels <= q))
    if dof:
        assert np.mean(naive <= 0.9545) < 0.9545 - 3.5 * math.sqrt(0.9545 * 0.0455 / n)


def test_a_flat_ellipse_and_bad_input():
    from cssat.inversion.ellipse import ellipse_level, ellipse_of_cov, error_ellipse, errors_level

    c = (10.0, 0.0)
    assert ellipse_level(c, _from_offset(c, 0.0, 0.3), 0.3, 0.0, 0.0) == pytest.approx(1 - math.exp(-0.5))
    assert ellipse_level(c, _from_offset(c, 0.01, 0.3), 0.3, 0.0, 0.0) == 1.0  # off the line
    with pytest.raises(FieldError, match="minor_deg.*0 ≤ minor ≤ major"):
        ellipse_level(c, c, 0.1, 0.2, 0.0)
    with pytest.raises(FieldError, match="dof.*replicate count ≥ 3"):
        ellipse_level(c, c, 0.2, 0.1, 0.0, dof=2)
    with pytest.raises(FieldError, match="cov.*a \\(2, 2\\) covariance"):
        ellipse_of_cov(np.eye(3))
    with pytest.raises(FieldError, match="cov.*no negative variance"):  # was (1, 0, 90): not a covariance
        ellipse_of_cov([[1.0, 0.0], [0.0, -1.0]])
    with pytest.raises(FieldError, match="cov.*finite values"):
        ellipse_of_cov([[math.nan, 0.0], [0.0, 1.0]])
    assert ellipse_of_cov([[1.0, 1.0], [1.0, 1.0]])[1] == pytest.approx(0.0, abs=1e-7)  # singular: a flat ellipse
    with pytest.raises(FieldError, match="offsets.*at least one"):
        error_ellipse(np.zeros((0, 2)))
    with pytest.raises(FieldError, match="errors.*missing L_dof"):
        errors_level({"L_major_deg": 1.0, "L_minor_deg": 0.5, "L_pa_deg": 0.0}, "L", c, c)
    nan = dict(L_major_deg=math.nan, L_minor_deg=math.nan, L_pa_deg=math.nan, L_dof=math.nan)
    assert math.isnan(errors_level(nan, "L", c, c))  # an unreliable verdict's withheld 1σ


def test_a_tumbling_solution_reads_its_level_from_its_ellipse():
    from cssat.inversion import TumblingSolution, TumblingState
    from cssat.inversion.ellipse import ellipse_level

    state = TumblingState(0.6, 0.8, 0.3, 1e-3, 2e-3, 0.0, 40.0, 30.0, 0.0, 0.0, "equatorial")
    e = dict(L_err_deg=0.5, L_major_deg=0.45, L_minor_deg=0.2, L_pa_deg=30.0, L_dof=20.0)
    sol = TumblingSolution(state=state, errors=e)
    point = _from_offset((40.0, 30.0), 0.3, 0.4)
    assert sol.L_level(*point) == pytest.approx(ellipse_level((40.0, 30.0), point, 0.45, 0.2, 30.0, dof=20))
    # along the major axis a point is nearer, in level, than the same distance across it
    r = 0.35
    along, across = _from_offset((40.0, 30.0), r / 2, r * math.sqrt(3) / 2), _from_offset((40.0, 30.0), r * math.sqrt(3) / 2, -r / 2)
    assert sol.L_level(*along) < 0.6827 < sol.L_level(*across)
    withheld = TumblingSolution(state=state, errors={k: math.nan for k in e})
    assert math.isnan(withheld.L_level(*point))
