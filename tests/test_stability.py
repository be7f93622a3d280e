"""Stability of each method on the contact (SEED-NOTES 8): the theoretical bound, the simulation
failing just past it and holding just inside it (with the growth per step it shows equal to the
theory's spectral radius), the exact method holding the bounce at any step, and the guard that
sub-steps or refuses an unstable scene. Scenes: bench/stability.py."""
import math

import numpy as np
import pytest

from touchdown.bench.stability import (NUDGE_MPS, OMEGA, SAG_M, ZETA, bounce_ringing, grows,
                             identified_map, rocking, rocking_mode, theory)
from scenes import records, scene, series
from touchdown.sim.scenario import ScenarioError
from touchdown.sim.stability import amplification, largest_stable_wh, spectral_radius


def eigen(zeta):
    """The oscillator's eigenvalues for w = 1: -zeta +- i sqrt(1 - zeta^2)."""
    return complex(-zeta, math.sqrt(1 - zeta * zeta))


def test_bounds_agree_with_closed_forms():
    # explicit Euler: |1 + z| <= 1 on z = h lambda  <=>  w h <= 2 zeta
    assert largest_stable_wh("explicit_euler", ZETA) == pytest.approx(2 * ZETA, rel=1e-9)
    # semi-implicit Euler: Jury's test on tr = 2 - h^2 - 2 zeta h, det = 1 - 2 zeta h
    assert largest_stable_wh("semi_implicit_euler", ZETA) == pytest.approx(
        2 * (math.sqrt(ZETA ** 2 + 1) - ZETA), rel=1e-9)
    # undamped: the familiar w h < 2 for the symplectic methods, 2 sqrt 2 for RK4
    assert largest_stable_wh("semi_implicit_euler", 0.0) == pytest.approx(2.0, rel=1e-9)
    assert largest_stable_wh("velocity_verlet", 0.0) == pytest.approx(2.0, rel=1e-9)
    assert largest_stable_wh("rk4", 0.0) == pytest.approx(2 * math.sqrt(2), rel=1e-9)
    assert largest_stable_wh("explicit_euler", 0.0) < 1e-5  # unstable at any practical step
    assert largest_stable_wh("exponential", ZETA) == math.inf


@pytest.mark.parametrize("wh", [0.5, 3.0, 10.0, 50.0])
def test_the_exact_flow_amplifies_by_exp_minus_zeta_w_h(wh):
    """exp(A h) has eigenvalues e^{(-zeta +- i sqrt(1 - zeta^2)) w h}: modulus e^{-zeta w h}."""
    assert spectral_radius(amplification("exponential", wh, ZETA)) == pytest.approx(
        math.exp(-ZETA * wh), rel=1e-9)


def test_rk4_bound_against_its_stability_polynomial():
    b = largest_stable_wh("rk4", ZETA)
    r = lambda z: 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24  # noqa: E731
    lam = eigen(ZETA)
    assert abs(r(b * 0.99 * lam)) < 1.0 < abs(r(b * 1.01 * lam))


CASES = [("explicit_euler", "bounce"), ("semi_implicit_euler", "bounce"),
         ("velocity_verlet", "bounce"), ("rk4", "bounce"), ("exponential", "rocking")]


@pytest.mark.parametrize("method,mode", CASES)
@pytest.mark.parametrize("factor", [0.95, 1.05])
def test_each_method_holds_inside_its_bound_and_fails_past_it(method, mode, factor):
    """The one-step map the simulation applies to the mode, identified from its output, is the
    theory's amplification matrix (trace and determinant to 1e-3): inside the bound it decays,
    just past it, it grows. The exponential method's limit is its kicks' on the rocking mode."""
    wh = factor * theory(method, mode)
    recs = bounce_ringing(method, wh, 200) if mode == "bounce" else rocking(method, wh, 200)
    tr, det = identified_map(recs, mode)
    limiting = {"exponential": "velocity_verlet"}.get(method, method)
    zeta = ZETA if mode == "bounce" else rocking_mode()[1]
    m = amplification(limiting, wh, zeta)
    assert tr == pytest.approx(m[0, 0] + m[1, 1], abs=1e-3)
    assert det == pytest.approx(m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0], abs=1e-3)
    assert grows(method, wh, mode) == (factor > 1.0)


@pytest.mark.parametrize("wh", [3.0, 10.0])
def test_the_exponential_method_holds_the_bounce_at_any_step_and_is_exact_there(wh):
    """Far past every explicit method's bound, the exact flow rings down as the damped oscillator
    does, y'(t) = e^{-zeta w t} (y0' cos w_d t - (w^2 y0 + zeta w y0') / w_d sin w_d t), tick by
    tick from the recorded start (y: penetration's offset from the static sag)."""
    recs = bounce_ringing("exponential", wh, steps=12)
    v = series(recs, "v_radial_mps")
    pen = series(recs, "penetration_m")
    dt = wh / OMEGA
    # the closed form in x = penetration (+ down), x' = -v_radial; equilibrium x_eq at the sag
    r0 = float(np.linalg.norm(recs[0].state.pos_m[0]))
    g = 4.9048695e12 / (r0 * r0)
    x_eq = g / OMEGA ** 2
    y0, yd0 = pen[0] - x_eq, -v[0]
    wd = OMEGA * math.sqrt(1 - ZETA * ZETA)
    t = np.arange(len(recs)) * dt
    decay = np.exp(-ZETA * OMEGA * t)
    yd = decay * (yd0 * np.cos(wd * t) - (OMEGA ** 2 * y0 + ZETA * OMEGA * yd0) / wd
                  * np.sin(wd * t))
    assert abs(v[0]) == pytest.approx(NUDGE_MPS, rel=0.1)
    # positions a Moon's radius out are held to ulp(|p|) = 2.3e-10 m, which the spring turns into
    # w^2 ulp h / 2 ~ 2e-9 m/s: the floor of any method here
    assert np.max(np.abs(-v - yd)) < 1e-8
    assert abs(pen[0] - SAG_M) < 1e-4
    assert not grows("exponential", wh, "bounce")


def test_an_unstable_scene_is_refused_when_asked():
    with pytest.raises(ScenarioError) as err:
        scene({"altitude": 1.0}, sim={"integrator": "rk4", "dt": 0.5, "max_substep": 0.0,
                                      "on_unstable": "error"})
    assert "sim.dt" in str(err.value) and "unstable" in str(err.value)


def test_an_unstable_scene_is_sub_stepped_by_default():
    scn = scene({"altitude": 0.5, "vertical_speed": -20.0},
                sim={"integrator": "explicit_euler", "dt": 0.1, "max_substep": 0.0}, duration=30.0)
    h = scn.params.sim.dt_s / scn.params.ships.n_substeps[0]
    assert OMEGA * h < largest_stable_wh("explicit_euler", ZETA)
    assert scn.resolved["sim"]["max_substep"] == 0.0  # the scene's setting; the ship's own need
    recs = records(scn)
    assert np.isfinite(series(recs, "altitude_m")).all()
    # bounded: no energy from nowhere (stable is not accurate: near its bound explicit Euler
    # cancels most of the physical damping, so this bounce comes back nearly as high as it fell)
    g = scn.params.body.surface_gravity_mps2
    assert series(recs, "altitude_m").max() <= (20.0 ** 2 + 2 * g * 0.5) / (2 * g)


def test_the_exponential_method_is_sub_stepped_for_its_rocking_mode_only():
    """At a 0.08 s tick the bounce (w h = 0.8) needs nothing and the rocking mode (w_r h = 0.62
    for the default ship, within half of velocity Verlet's 1.34 on the critically damped
    absorber) needs nothing either; at 0.5 s the rocking mode needs sub-steps, and `error`
    refuses instead."""
    plain = scene({"altitude": 1.0}, sim={"integrator": "exponential", "dt": 0.08,
                                          "max_substep": 0.0, "on_unstable": "error"})
    assert plain.params.ships.n_substeps[0] == 1
    big = scene({"altitude": 1.0}, sim={"integrator": "exponential", "dt": 0.5, "max_substep": 0.0})
    h = big.params.sim.dt_s / big.params.ships.n_substeps[0]
    w_rock_bound = math.sqrt(100.0 * 2.26 ** 2 / 2 / ((3 * 2.26 ** 2 + 36.0) / 12.0))
    assert 1 < big.params.ships.n_substeps[0]
    assert w_rock_bound * h < 0.5 * min(largest_stable_wh("velocity_verlet", z) for z in (ZETA, 1.0))
    with pytest.raises(ScenarioError):
        scene({"altitude": 1.0}, sim={"integrator": "exponential", "dt": 0.5, "max_substep": 0.0,
                                      "on_unstable": "error"})
