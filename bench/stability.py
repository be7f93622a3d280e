"""Stability benchmark: ``touchdown bench stability [--quick]``.

For each method, the largest stable step on the contact, measured in the simulation by bisection
and printed against the theoretical bound of ``sim/stability.py`` (SEED-NOTES 8: with damping the
undamped w h < 2 does not hold). Two modes of the contact, each set up so that it is a linear
oscillator exactly:

* bounce: a ship resting in an absorbed (bilateral) contact with zeta = 0.3, nudged at 0.05 mm/s so
  that it rings within its static sag: x'' = -w^2 x - 2 zeta w x', w = sqrt(k/m) = 10 rad/s.
* rocking: the same ship on frictionless feet, nudged to turn at 1e-5 rad/s about a transverse
  axis: I theta'' = -(k a^2/2 - m g h) theta - (c a^2/2) theta' (two feet off the axis, each k/4
  and c/4 at lever arm a; the load m g on feet that shift by h theta gives the - m g h theta).
  The exponential method solves the bounce exactly, so this mode, carried by its velocity-Verlet
  kicks, is the one that limits it.

The scene builders are shared with ``tests/test_stability.py``.
"""
from __future__ import annotations

import math

import numpy as np

from touchdown.sim.enums import SurfaceState
from touchdown.sim.run import run
from touchdown.sim.scenario import parse
from touchdown.sim.stability import KICKS, largest_stable_wh

ZETA = 0.3
OMEGA = 10.0  # sqrt(k/m), rad/s
NUDGE_MPS = 5e-5  # rings within 5 um of a 16 mm sag: linear through a 100-fold growth
NUDGE_RADPS = 1e-5  # the feet stay pressed (linear) through a 100-fold growth
MASS, H_COM, A_LEG = 10000.0, 3.0, 2.26
I_T = MASS * (3 * A_LEG * A_LEG + (2 * H_COM) ** 2) / 12.0  # default inertia: uniform cylinder
MOON_G = 4.9048695e12 / 1737400.0 ** 2
SAG_M = MOON_G / OMEGA ** 2


def rocking_mode() -> tuple[float, float]:
    """(w_r, zeta_r) of the rocking oscillator described in the module docstring."""
    k, c = OMEGA * OMEGA * MASS, 2.0 * ZETA * OMEGA * MASS
    w2 = (0.5 * k * A_LEG ** 2 - MASS * MOON_G * H_COM) / I_T
    w = math.sqrt(w2)
    return w, 0.5 * c * A_LEG ** 2 / I_T / (2.0 * w)


def _records(initial: dict, method: str, dt: float, duration: float, contact: dict,
             ship: dict | None = None) -> list:
    doc = {"name": "stability", "duration": duration,
           "sim": {"integrator": method, "dt": dt, "max_substep": 0.0, "on_unstable": "allow",
                   "energy_guard": False},
           "contact": {"damping_ratio": ZETA, "absorb_damping_ratio": ZETA,
                       "settle_linear_vel": 1e-12, **contact},
           "ships": [{"id": "s", **(ship or {}), "initial": initial}]}
    return list(run(parse(doc, "stability")))


#: Ticks a mode is watched for (the fit needs a few; a slowly growing mode needs more to get
#: larger than its nudge)
STEPS = 200


def bounce_ringing(method: str, wh: float, steps: int = STEPS) -> list:
    """The bounce mode stepped once per tick of w h (landing switched off, to watch it ring).
    The ship's inertia is made huge, so that it has no rocking mode: rounding would otherwise
    seed one, and at a step past the rocking bound that, not the bounce, would grow."""
    dt = wh / OMEGA
    return _records({"state": "contact", "altitude": -SAG_M, "vertical_speed": -NUDGE_MPS},
                    method, dt, steps * dt, {}, ship={"inertia": [1e12, 1e12, 1e12]})


def rocking(method: str, wh: float, steps: int = STEPS) -> list:
    """The rocking mode stepped once per tick of w_r h (frictionless feet, landing switched off)."""
    w_r, _ = rocking_mode()
    dt = wh / w_r
    return _records({"state": "contact", "altitude": -SAG_M,
                     "angular_velocity": [NUDGE_RADPS, 0.0, 0.0]},
                    method, dt, steps * dt,
                    {"friction_static": 0.0, "friction_kinetic": 0.0, "settle_angular_vel": 1e-12})


def signal(recs: list, mode: str) -> np.ndarray:
    """The mode's coordinate per tick, signed: v_radial (bounce) or the body-x rate (rocking);
    inf once the ship has left the mode (tipped, crashed) or the numbers overflowed."""
    if mode == "bounce":
        x = np.array([r.outputs.v_radial_mps[0] for r in recs])
    else:
        x = np.array([r.state.omega_body_radps[0][0] for r in recs])
    left = np.array([int(r.state.surface_state[0]) not in (SurfaceState.CONTACT,
                                                            SurfaceState.FLYING) for r in recs])
    return np.where(np.isfinite(x) & ~left, x, np.inf)


def identified_map(recs: list, mode: str) -> tuple[float, float]:
    """(trace, determinant) of the one-step map the simulation applied to the mode, identified
    from its output: on a linear 2x2 map every sequence obeys x_{k+2} = tr x_{k+1} - det x_k
    (Cayley-Hamilton), fitted by least squares over the run's linear part (from the nudge until
    the mode has grown a hundredfold, beyond which the feet would leave the ground, or decayed
    ten-thousandfold, near the rounding floor of positions a planet's radius out)."""
    with np.errstate(all="ignore"):
        x = signal(recs, mode)
        a0 = np.abs(x[:3]).max()
        out = np.flatnonzero(~(np.abs(x) < 100.0 * a0) | (np.abs(x) < 1e-4 * a0))
        n = out[0] if out.size and out[0] >= 4 else len(x)
        x = x[:n]
        if len(x) < 4 or not np.isfinite(x).all():
            return math.inf, math.inf
        rows = np.stack([x[1:-1], -x[:-2]], axis=1)
        (tr, det), *_ = np.linalg.lstsq(rows, x[2:], rcond=None)
        return float(tr), float(det)


def amplification_per_step(recs: list, mode: str) -> float:
    """The spectral radius of the identified one-step map: the mode's growth per step."""
    tr, det = identified_map(recs, mode)
    if not (math.isfinite(tr) and math.isfinite(det)):
        return math.inf
    disc = tr * tr / 4.0 - det
    if disc < 0.0:
        return math.sqrt(max(det, 0.0))
    r = math.sqrt(disc)
    return max(abs(tr / 2.0 + r), abs(tr / 2.0 - r))


def grows(method: str, wh: float, mode: str, steps: int = STEPS) -> bool:
    """True when the nudged mode grows: its identified one-step map amplifies, and the mode
    does get larger than the nudge."""
    recs = bounce_ringing(method, wh, steps) if mode == "bounce" else rocking(method, wh, steps)
    with np.errstate(all="ignore"):
        x = np.abs(signal(recs, mode))
    return amplification_per_step(recs, mode) > 1.0 and bool(
        not np.isfinite(x).all() or x.max() > 1.5 * x[:3].max())


def theory(method: str, mode: str) -> float:
    """The theoretical largest stable w h of ``method`` on ``mode``."""
    if mode == "bounce":
        return largest_stable_wh(method, ZETA)
    _, zeta_r = rocking_mode()
    return largest_stable_wh(KICKS.get(method, method), zeta_r)


def measured(method: str, mode: str, hi: float, halvings: int) -> float:
    """The largest w h (up to ``hi``) at which the nudged mode does not grow, by bisection:
    a fixed number of halvings. Returns ``hi`` when even ``hi`` is stable."""
    if not grows(method, hi, mode):
        return hi
    lo = 0.0
    for _ in range(halvings):
        mid = 0.5 * (lo + hi)
        if grows(method, mid, mode):
            hi = mid
        else:
            lo = mid
    return lo


def main(quick: bool = False) -> None:
    from touchdown.bench.speed import machine
    print(f"machine: {machine()}")
    w_r, zeta_r = rocking_mode()
    print(f"contact: w = {OMEGA:g} rad/s, zeta = {ZETA:g} (bounce); w_r = {w_r:.3f} rad/s, "
          f"zeta_r = {zeta_r:.3f} (rocking, default ship)")
    halvings = 6 if quick else 12
    print(f"{'method':<22}{'mode':<9}{'theory w h':>12}{'measured w h':>14}{'tick (s)':>10}")
    rows = [(m, "bounce") for m in ("explicit_euler", "semi_implicit_euler", "velocity_verlet",
                                    "rk4", "exponential")]
    rows += [("exponential", "rocking"), ("velocity_verlet", "rocking")]
    for method, mode in rows:
        bound = theory(method, mode)
        w = OMEGA if mode == "bounce" else w_r
        cap = 10.0 if math.isinf(bound) else 2.0 * bound
        got = measured(method, mode, cap, halvings)
        th = "none" if math.isinf(bound) else f"{bound:.3f}"
        note = f"  (stable at every step tried, up to w h = {cap:g})" if got >= cap else ""
        print(f"{method:<22}{mode:<9}{th:>12}{got:>14.3f}{got / w:>10.4f}{note}")
    print(f"measured: the largest w h at which a nudged mode does not grow: the one-step map "
          f"identified from {STEPS} simulated ticks (x[k+2] = tr x[k+1] - det x[k]) has spectral "
          f"radius <= 1; {halvings} halvings.")


if __name__ == "__main__":
    main()
