"""Linear stability of each stepping method on the contact's damped oscillator.

While a foot is compressed, the ground is the linear oscillator x'' = -w^2 x - 2 zeta w x'
(w = sqrt(k/m) = 10 rad/s for the seed's k = 100 m). One step of a method maps (x, x') by a 2x2
amplification matrix M(w h, zeta); the step is stable when M's spectral radius is at most one.
The largest stable w h is found by bisection (a fixed 80 halvings) on that radius. SEED-NOTES 8:
with damping the undamped bound w h < 2 no longer holds (explicit Euler is stable only for
w h below about 0.6 at zeta = 0.3, and not at all without damping).

``exponential`` solves the spring-damper exactly: its amplification on the bounce is the exact
flow's, with spectral radius e^{-zeta w h} < 1 at every step, so the bounce never limits its
step. What it integrates explicitly are the velocity-Verlet kicks that carry rotation, so its limit
is velocity Verlet's bound applied to the rocking modes (:data:`KICKS`).

Used when a scenario is loaded (not inside the step): a method and sub-step that would be unstable
for the scene's contact are sub-stepped further or refused, as ``sim.on_unstable`` says.
"""
from __future__ import annotations

import functools
import math

import numpy as np

#: Methods that solve the spring-damper exactly, and the explicit scheme their kicks use: that
#: scheme's bound applies to the modes the kicks carry (rocking on the feet), not to the bounce.
KICKS: dict[str, str] = {"exponential": "velocity_verlet"}

_HALVINGS = 80
_SEARCH_MAX = 16.0  # w h beyond any method here


def _mul(*ms: np.ndarray) -> np.ndarray:
    """The product of 2x2 matrices, left to right, each entry a0 b0 + a1 b1 in that order: numpy's
    ``@`` hands even a 2x2 product to the host's BLAS, whose kernel OpenBLAS picks by CPU (fused
    multiply-adds on AVX2 and AVX-512, not on older ones), so the last bits, and the bisection's
    edge below, would differ between machines."""
    out = ms[0]
    for b in ms[1:]:
        a = out
        out = np.array([[a[i, 0] * b[0, j] + a[i, 1] * b[1, j] for j in (0, 1)] for i in (0, 1)])
    return out


def amplification(method: str, wh: float, zeta: float) -> np.ndarray:
    """One step of ``method`` on x'' = -x - 2 zeta x' in units where w = 1, step wh."""
    a = np.array([[0.0, 1.0], [-1.0, -2.0 * zeta]])
    eye = np.eye(2)
    h = wh
    if method == "explicit_euler":
        return eye + h * a
    if method == "semi_implicit_euler":
        # v1 = v + h (-x - 2 zeta v); x1 = x + h v1
        kick = np.array([[1.0, 0.0], [-h, 1.0 - 2.0 * zeta * h]])
        drift = np.array([[1.0, h], [0.0, 1.0]])
        return _mul(drift, kick)
    if method == "velocity_verlet":
        # v_half = v + h/2 a(x, v); x1 = x + h v_half; the closing kick's damper at the end's own
        # velocity, by one fixed-point pass (sim.integrators.velocity_verlet):
        # v1' = v_half + h/2 a(x1, v_half); v1 = v_half + h/2 a(x1, v1')
        half_kick = np.array([[1.0, 0.0], [-h / 2, 1.0 - zeta * h]])
        drift = np.array([[1.0, h], [0.0, 1.0]])
        closing = np.array([[1.0, 0.0],
                            [-h / 2 + zeta * h * h / 2, 1.0 - zeta * h + zeta * zeta * h * h]])
        return _mul(closing, drift, half_kick)
    if method == "rk4":
        ha = h * a
        ha2 = _mul(ha, ha)
        ha3 = _mul(ha2, ha)
        return eye + ha + ha2 / 2 + ha3 / 6 + _mul(ha3, ha) / 24
    if method == "exponential":
        # the exact flow exp(A h): its columns are the flow from (1, 0) and from (0, 1) (compiled:
        # imported here, as a scenario's checks, which use this module, run none)
        from touchdown.sim import exact
        cols = []
        for x0, v0 in ((1.0, 0.0), (0.0, 1.0)):
            x, v, _ = exact.flow_at(exact.Flow(1.0, 2.0 * zeta, 0.0, 0.0, x0, v0), float(h))
            cols.append([x, v])
        return np.array(cols).T
    raise ValueError(f"no stability analysis for method {method!r}")


def spectral_radius(m: np.ndarray) -> float:
    tr, det = m[0, 0] + m[1, 1], m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    disc = tr * tr / 4.0 - det
    if disc < 0.0:  # complex pair: |lambda|^2 = det
        return math.sqrt(max(det, 0.0))
    r = math.sqrt(disc)
    return max(abs(tr / 2.0 + r), abs(tr / 2.0 - r))


@functools.lru_cache(maxsize=1024)  # pure; a sweep and a burst of spawns parse thousands of scenes
def largest_stable_wh(method: str, zeta: float) -> float:
    """The largest w h for which ``method`` does not amplify the contact oscillator (0 if none:
    explicit Euler, zeta 0; infinity for a method that solves it exactly). A pure function of
    its two numbers, so kept once found: a live service's spawns of one ship class would each
    run the 80-step bisection again (2 ms each)."""
    if method in KICKS:
        return math.inf

    def stable(wh):
        return spectral_radius(amplification(method, wh, zeta)) <= 1.0 + 1e-12

    lo, hi = 0.0, _SEARCH_MAX
    if not stable(1e-9):
        return 0.0
    for _ in range(_HALVINGS):
        mid = 0.5 * (lo + hi)
        if stable(mid):
            lo = mid
        else:
            hi = mid
    return lo
