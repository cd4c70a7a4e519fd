"""Fits whose answers do not depend on the thread count (cssat._threads): the pool keeps the
order and raises the calls' errors, runs its calls at once, and the parametric stage and
``fit_parts`` give the serial loop's numbers, bit for bit, at one and two threads."""

import math
import threading

import numpy as np
import pytest


def _unit(rng, n):
    x = rng.normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1)[:, None]


def test_thread_map_keeps_the_order_runs_at_once_and_raises_the_calls_error():
    from cssat._threads import one_thread, thread_map

    assert thread_map(lambda x: x * x, range(7), 3) == [x * x for x in range(7)]
    assert thread_map(lambda x: x, [], 4) == []
    barrier = threading.Barrier(2, timeout=20)  # two calls that each wait for the other: serial calls would time out
    assert thread_map(lambda x: (barrier.wait(), x)[1], ["a", "b"], 2) == ["a", "b"]
    with pytest.raises(ZeroDivisionError):
        thread_map(lambda x: 1 / x, [1, 0, 2], 2)
    import torch

    before = torch.get_num_threads()
    with one_thread() as found:
        assert found == before and torch.get_num_threads() == 1
        assert thread_map(lambda _: torch.get_num_threads(), range(2), 2) == [1, 1]  # the workers' torch too
    assert torch.get_num_threads() == before


def _scene(seed=4, n=100):
    import torch

    from cssat.inversion.parametric import box_wing_light_curve, box_wing_visibility

    truth = np.r_[1.0, 0.9, 1.2, 4.0, 1.5, math.radians(25.0), 0.6, 0.3, 0.2, 0.0, 0.0, 1.2, 0.0, 0.0, 0.8, 0.25, 0.6]
    kw = dict(panels=2, divisions=1, dish_rings=2, dish_segments=6, dishes=1)
    rng = np.random.default_rng(seed)
    S, V = _unit(rng, n), _unit(rng, n)
    clean = box_wing_light_curve(torch.as_tensor(truth), S, V, box_wing_visibility(truth, S, V, **kw),
                                 range_km=1e-3, irradiance=1.0, **kw).numpy()
    sigma = 0.02 * clean + 0.002 * float(np.median(clean))
    return truth, kw, S, V, clean + sigma * rng.normal(size=n), sigma


def test_fit_parts_gives_the_serial_answer_with_workers():
    from cssat._threads import one_thread
    from cssat.inversion.parametric_parts import fit_parts

    truth, kw, S, V, y, sigma = _scene()
    p9 = truth[:9] * np.r_[1.1, 0.9, 1.05, 0.8, 1.2, 1.0, 1.0, 1.0, 1.0]
    with one_thread():
        out = [fit_parts(y, S, V, p9, dict(dishes=1), sigma=sigma, keep=2, workers=w, divisions=1, dish_rings=2,
                         dish_segments=6, outer=1, inner=8) for w in (1, 2)]
    np.testing.assert_array_equal(out[0][0], out[1][0])
    assert out[0][1]["briefs"] == out[1][1]["briefs"] and out[0][1]["fulls"] == out[1][1]["fulls"]
    with pytest.raises(ValueError, match="workers"):
        fit_parts(y, S, V, p9, dict(dishes=1), workers=0)


def test_the_parametric_stage_gives_the_same_numbers_at_one_and_two_threads():
    """The stage with a plain multi-start and both parts' bases (the pool's work), soft shadows, at
    torch's thread count 1 and 2: every metric and the model equal to the bit, the count put back
    (with torch's own threads the two differed, by ~1e-13 of the flux on this scene)."""
    from types import SimpleNamespace

    import torch

    from cssat.experiments.forward.egi_parametric import solve_parametric
    from cssat.inversion.egi import egi
    from cssat.inversion.parametric import box_wing_mesh
    from cssat.models.egi.config import ParametricConfig

    truth, kw, S, V, y, sigma = _scene(seed=5)
    N, A = egi(box_wing_mesh(truth, **kw))
    fit = np.arange(100) < 70
    before = torch.get_num_threads()
    out = []
    try:
        for threads in (1, 2):
            torch.set_num_threads(threads)
            m = SimpleNamespace(fit=fit, held=~fit, sigma=sigma, y=y, night=(~fit).astype(int))
            a = SimpleNamespace(sun_b=S, obs_b=V, metrics={"spin": "known"})
            sol = SimpleNamespace(res=SimpleNamespace(normals=N, areas=A), model_unit=np.zeros(100), metrics={})
            solve_parametric(ParametricConfig(visibility="soft", divisions=1, outer=1, inner=8, dishes=1, dish_rings=2,
                                              dish_segments=6, aspects=[2, 4], plain_keep=2), m, a, sol)
            assert torch.get_num_threads() == threads
            out.append(sol)
    finally:
        torch.set_num_threads(before)
    np.testing.assert_array_equal(out[0].model_unit, out[1].model_unit)
    assert out[0].metrics == out[1].metrics
