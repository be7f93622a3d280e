"""Coulomb friction at the centre of pressure, applied as an impulse after each (sub)step.

Touchdown's law (``friction_model = "coulomb"``, SEED-NOTES 4): let s be the slip speed of the
contact point relative to the surface and J_stop = s / (1/m + (r x t)^T I^-1 (r x t)) the impulse
that brings it exactly to rest (t: slip direction, r: contact point from the centre of mass).
With N the mean normal force over the step of length h:

    sliding:  J = min(J_stop, mu_k N h)               (decelerates, never overshoots zero)
    sticking: J = J_stop if J_stop <= mu_s N h         (holds exactly, whatever pushes sideways)
              J = mu_k N h otherwise                   (breaks away)

A slide on level ground therefore decelerates at mu_k g and stops at v0^2 / (2 mu_k g). The
impulse stands for a force that acted throughout the step, so the step's drift is corrected for it
(:func:`spread_over_step`): without that, the drift uses the speed from before the impulse, a
slide overshoots by mu_k g h T / 2 (first order in the step h) and a ship held on a slope creeps
by a h^2 / 2 a step.

The seed's law (``"seed"``): kinetic above 0.01 m/s with no stopping test, else reset the centre of
mass's tangential velocity, falling back to kinetic friction beyond mu_s N; it acts at the centre
of mass (no moment). Kept reachable for comparison; it 2-cycles and creeps as SEED-NOTES 4 shows.
"""
from __future__ import annotations

import numpy as np

from sim import vec
from sim.constants import STICK_SPEED_MPS


def spread_over_step(pos_m: np.ndarray, quat: np.ndarray, vel_before: np.ndarray,
                     vel_after: np.ndarray, omega_before: np.ndarray, omega_after: np.ndarray,
                     h: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position and attitude as if the friction impulse had acted evenly over the step of length
    h: a velocity change dv spread over the step changes its drift by h dv / 2 (dv opposes the
    slip, so the ship ends short of where its speed before the impulse took it), and likewise
    for the turn. Exact for a constant friction force; a ship held at rest by static friction
    then stays exactly where it is."""
    h_col = h if np.ndim(h) == 0 else np.asarray(h)[:, None]
    pos = pos_m + 0.5 * h_col * (vel_after - vel_before)
    return pos, vec.quat_integrate(quat, omega_after - omega_before, 0.5 * np.asarray(h))


def apply(model: str, mu_s: float, mu_k: float, h: float, body_omega_radps: float,
          mass_kg: np.ndarray, inertia_kgm2: np.ndarray, pos_m: np.ndarray, vel_mps: np.ndarray,
          quat: np.ndarray, omega_b: np.ndarray, normal_n: np.ndarray, cop_w: np.ndarray,
          sliding: np.ndarray):
    """Returns (vel, omega_b, sliding, friction force magnitude N)."""
    seed = model == "seed"
    point = pos_m if seed else cop_w
    n_hat = vec.unit(point)
    r = point - pos_m
    omega_w = vec.quat_rotate(quat, omega_b)
    v_point = vel_mps if seed else vel_mps + vec.cross(omega_w, r)
    # velocity of the surface under the point: Omega z x point
    v_surf = np.zeros_like(point)
    v_surf[:, 0] = -body_omega_radps * point[:, 1]
    v_surf[:, 1] = body_omega_radps * point[:, 0]
    v_rel = v_point - v_surf
    v_t = v_rel - vec.scale(n_hat, vec.dot(v_rel, n_hat))
    s = vec.norm(v_t)
    moving = s > 0.0
    t_hat = v_t / np.where(moving, s, 1.0)[:, None]
    n_pos = np.maximum(normal_n, 0.0)
    lim_s = mu_s * n_pos * h
    lim_k = mu_k * n_pos * h
    if seed:
        j_stop = mass_kg * s
        j = np.where(s > STICK_SPEED_MPS, lim_k, np.where(j_stop <= lim_s, j_stop, lim_k))
        u_b_over_i = np.zeros_like(omega_b)
    else:
        u_b = vec.quat_rotate_inv(quat, vec.cross(r, t_hat))
        u_b_over_i = u_b / inertia_kgm2
        inv_m_eff = 1.0 / mass_kg + vec.dot(u_b, u_b_over_i)
        j_stop = s / inv_m_eff
        j = np.where(sliding, np.minimum(j_stop, lim_k), np.where(j_stop <= lim_s, j_stop, lim_k))
    j = np.where(moving & (n_pos > 0.0), j, 0.0)
    vel = vel_mps - vec.scale(t_hat, j / mass_kg)
    omega = omega_b - vec.scale(u_b_over_i, j)
    still_sliding = j < j_stop if not seed else s - j / mass_kg > STICK_SPEED_MPS
    return vel, omega, still_sliding & moving, j / h
