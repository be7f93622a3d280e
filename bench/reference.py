"""Independent references for the physics tests and the accuracy benchmark. Nothing here imports
the simulation.

* The vertical bounce of an upright lander: x = penetration (+ down), v = x' (+ down),
      x'' = g(r) - max(0, w^2 x + 2 zeta w v)   while x > 0,   x'' = g(r) otherwise,
  with w = sqrt(k/m) = 10 rad/s (seed: k = 100 m). Two solutions are built:
  ``bounce_closed_form`` (uniform g: ballistic parabola, then the damped oscillator
  x(t) = x_eq + e^{-zeta w t}(A cos w_d t + B sin w_d t) until the force reaches zero, found by
  brentq, then ballistic again) and ``bounce_ode`` (scipy solve_ivp, DOP853 at rtol 1e-11, with
  events at x = 0 and at the clamp, and point-mass gravity GM / r^2).
  Gravity acts at the centre of mass, ``com_height`` above the feet: g = GM / (R + h - x)^2.
* The settling of a vertical touchdown (``settle_time``): impacts at or above ``bounce_speed`` on
  the clamped zeta = 0.3 spring, slower ones on the bilateral absorber (zeta = 1), ballistic
  flights between, and the landed rule in continuous time: the first t at which |v| < v_settle has
  held for all of [t - settle_time, t] (Touchdown's reading of the seed, SEED-NOTES 1 and 3).
* The pivot topple of a rigid lander on its rim foot:
      I_p theta'' = m g L sin(theta - theta_c),  L = sqrt(h^2 + a^2), theta_c = atan(a / h),
  I_p = I_transverse + m L^2 (parallel axis), solved by solve_ivp with an event at the tipped angle;
  with an RCS torque tau against it, the righting of a tipped lander (``righting_time``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

OMEGA = 10.0  # sqrt(k/m), rad/s, from the seed's k = 100 m


@dataclass(frozen=True)
class Bounce:
    impact_speed_mps: float
    max_penetration_m: float
    separation_speed_mps: float
    apex_m: float  # height of the feet above the surface at the first apex
    contact_duration_s: float


def bounce_closed_form(g: float, v_impact: float, zeta: float = 0.3, w: float = OMEGA) -> Bounce:
    """First bounce under uniform gravity, starting at x = 0 with speed v_impact downward."""
    wd = w * math.sqrt(1.0 - zeta * zeta)
    x_eq = g / (w * w)
    a0 = -x_eq  # x(0) - x_eq
    b0 = (v_impact + zeta * w * a0) / wd  # from x'(0) = v_impact

    def x(t):
        return x_eq + math.exp(-zeta * w * t) * (a0 * math.cos(wd * t) + b0 * math.sin(wd * t))

    def v(t):
        e = math.exp(-zeta * w * t)
        return e * ((-zeta * w * a0 + wd * b0) * math.cos(wd * t)
                    + (-zeta * w * b0 - wd * a0) * math.sin(wd * t))

    def force(t):
        return w * w * x(t) + 2.0 * zeta * w * v(t)

    # maximum compression: first zero of v
    t_grid = np.linspace(1e-6, math.pi / wd, 2000)
    vs = np.array([v(t) for t in t_grid])
    k = int(np.argmax(vs < 0.0))
    t_max = brentq(v, t_grid[k - 1], t_grid[k], xtol=1e-15)
    # the clamp: first zero of the force after maximum compression
    t_grid = np.linspace(t_max, t_max + 2 * math.pi / wd, 4000)
    fs = np.array([force(t) for t in t_grid])
    k = int(np.argmax(fs < 0.0))
    t_sep = brentq(force, t_grid[k - 1], t_grid[k], xtol=1e-15)
    # ballistic from (x(t_sep), v(t_sep)) up to x = 0, decelerated by g: v0^2 = v^2 - 2 g x
    xs, vsep = x(t_sep), v(t_sep)
    v_out = math.sqrt(vsep * vsep - 2.0 * g * xs)  # speed when the feet leave, upward
    t_up = (-vsep - v_out) / g
    return Bounce(v_impact, x(t_max), v_out, v_out * v_out / (2.0 * g), t_sep + t_up)


def bounce_ode(gm: float, radius_m: float, v_impact: float, zeta: float = 0.3,
               w: float = OMEGA, x0: float = 0.0, com_height_m: float = 0.0) -> Bounce:
    """First bounce with point-mass gravity at the centre of mass, com_height_m above the feet;
    x = radius - r (feet), from x0 with v_impact down."""

    def g(x):
        r = radius_m + com_height_m - x
        return gm / (r * r)

    def force(y):
        return w * w * y[0] + 2.0 * zeta * w * y[1]

    def rhs_contact(t, y):
        return [y[1], g(y[0]) - force(y)]

    def rhs_free(t, y):
        return [y[1], g(y[0])]

    opts = dict(method="DOP853", rtol=1e-11, atol=1e-12)
    # compression until the force clamps (and the maximum on the way)
    clamp = lambda t, y: force(y)
    clamp.terminal, clamp.direction = True, -1
    vmax = lambda t, y: y[1]
    vmax.direction = -1
    sol = solve_ivp(rhs_contact, (0.0, 10.0), [x0, v_impact], events=[clamp, vmax], **opts)
    x_max = float(sol.y_events[1][0][0])
    t1, y1 = sol.t[-1], sol.y[:, -1]
    # ballistic with the feet still below ground, up to x = 0
    surface = lambda t, y: y[0]
    surface.terminal, surface.direction = True, -1
    sol2 = solve_ivp(rhs_free, (t1, t1 + 10.0), y1, events=[surface], **opts)
    t2, y2 = sol2.t[-1], sol2.y[:, -1]
    v_out = -float(y2[1])
    # apex: v = 0
    top = lambda t, y: y[1]
    top.terminal, top.direction = True, 1
    sol3 = solve_ivp(rhs_free, (t2, t2 + 1000.0), y2, events=[top], **opts)
    apex = -float(sol3.y[0, -1])
    return Bounce(v_impact, x_max, v_out, apex, t2)


def critical_angle_rad(com_height_m: float, leg_radius_m: float) -> float:
    """Tilt toward a foot at which the centre of mass is over it: atan(a / h) (seed, Topple
    Dynamics). Toward the edge between two of the four feet it is atan(a / (sqrt(2) h))."""
    return math.atan2(leg_radius_m, com_height_m)


def topple_time(g: float, mass_kg: float, i_transverse_kgm2: float, com_height_m: float,
                leg_radius_m: float, theta0_rad: float, theta_end_rad: float,
                about_pivot: bool = True) -> float:
    """Time for a lander at rest at theta0 (past critical) to reach theta_end, pivoting on its rim
    foot. ``about_pivot=False`` uses the seed's inertia about the centre of mass instead."""
    h, a = com_height_m, leg_radius_m
    big_l = math.hypot(h, a)
    tc = critical_angle_rad(h, a)
    i_p = i_transverse_kgm2 + (mass_kg * big_l * big_l if about_pivot else 0.0)

    def rhs(t, y):
        return [y[1], mass_kg * g * big_l * math.sin(y[0] - tc) / i_p]

    reach = lambda t, y: y[0] - theta_end_rad
    reach.terminal, reach.direction = True, 1
    sol = solve_ivp(rhs, (0.0, 1e4), [theta0_rad, 0.0], events=[reach], method="DOP853",
                    rtol=1e-11, atol=1e-12)
    return float(sol.t_events[0][0])


def settle_time(gm: float, radius_m: float, v_impact: float, com_height_m: float = 0.0,
                zeta: float = 0.3, zeta_absorb: float = 1.0, bounce_speed: float = 10.0,
                settle_speed: float = 0.5, settle_time_s: float = 0.5, w: float = OMEGA,
                max_contacts: int = 20) -> tuple[float, int]:
    """(time from the first impact until landed, number of contacts) for an upright lander
    arriving at v_impact (down) on level ground. x = penetration of the feet (+ down), v = x'."""

    def g(x):
        r = radius_m + com_height_m - x
        return gm / (r * r)

    opts = dict(method="DOP853", rtol=1e-11, atol=1e-12)

    def until(rhs, t0, y0, event, direction, span):
        event.terminal, event.direction = True, direction
        sol = solve_ivp(rhs, (t0, t0 + span), y0, events=[event], **opts)
        return float(sol.t[-1]), sol.y[:, -1]

    def free(t_, y):
        return [y[1], g(y[0])]

    t, v_in = 0.0, v_impact
    for contact in range(1, max_contacts + 1):
        if v_in >= bounce_speed:
            # the clamped spring until its force reaches zero, then ballistic: the feet rise out
            # of the ground (x falls to 0), fly, and come back down to x = 0
            def spring(t_, y):
                return [y[1], g(y[0]) - (w * w * y[0] + 2.0 * zeta * w * y[1])]

            t, y = until(spring, t, [0.0, v_in],
                         lambda t_, y: w * w * y[0] + 2.0 * zeta * w * y[1], -1, 10.0)
            t, y = until(free, t, y, lambda t_, y: y[0], -1, 10.0)
            t, y = until(free, t, [-1e-12, y[1]], lambda t_, y: y[0], 1, 1e4)
            v_in = float(y[1])
            continue

        # the absorber: bilateral and critically damped; on level ground it never lets go
        def absorber(t_, y):
            return [y[1], g(y[0]) - w * w * y[0] - 2.0 * zeta_absorb * w * y[1]]

        crossings = []
        for sign in (1.0, -1.0):
            ev = (lambda s_: (lambda t_, y: y[1] - s_ * settle_speed))(sign)
            crossings.append(ev)
        sol = solve_ivp(absorber, (t, t + 60.0), [0.0, v_in], events=crossings,
                        dense_output=True, **opts)
        # |v| < settle_speed between consecutive crossings; the first such interval that lasts
        # settle_time (the last one is open-ended) is where the ship lands
        edges = [t] + sorted(float(x) for ev_t in sol.t_events for x in ev_t) + [t + 60.0]
        for a, b in zip(edges, edges[1:]):
            if abs(float(sol.sol(0.5 * (a + b))[1])) < settle_speed and b - a >= settle_time_s:
                return a + settle_time_s, contact
        break
    raise RuntimeError("did not settle")


def righting_time(g: float, mass_kg: float, i_transverse_kgm2: float, com_height_m: float,
                  leg_radius_m: float, torque_nm: float, theta0_rad: float,
                  theta_end_rad: float) -> float:
    """Time for a tipped lander at rest at theta0 to be turned back to theta_end by an RCS torque
    about its pivot foot: I_p theta'' = m g L sin(theta - theta_c) - tau."""
    h, a = com_height_m, leg_radius_m
    big_l = math.hypot(h, a)
    tc = critical_angle_rad(h, a)
    i_p = i_transverse_kgm2 + mass_kg * big_l * big_l

    def rhs(t, y):
        return [y[1], (mass_kg * g * big_l * math.sin(y[0] - tc) - torque_nm) / i_p]

    reach = lambda t, y: y[0] - theta_end_rad  # noqa: E731
    reach.terminal, reach.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 1e4), [theta0_rad, 0.0], events=[reach], method="DOP853",
                    rtol=1e-11, atol=1e-12)
    return float(sol.t_events[0][0])


def planar_touchdown(v_side_mps: float, v_down_mps: float, g: float, mass_kg: float = 1e4,
                     i_transverse_kgm2: float = 42768.15, com_height_m: float = 3.0,
                     leg_radius_m: float = 2.26, omega: float = OMEGA, zeta: float = 0.3,
                     zeta_absorb: float = 1.0, bounce_speed: float = 10.0, mu: float = 0.5,
                     slip_scale_mps: float = 1e-4, t_end_s: float = 10.0,
                     tipped_deg: float = 80.0):
    """An upright lander touching down with a sideways speed along one of its feet, in the plane of
    that motion (exactly planar: the two side feet project onto the centre line), as a rigid body
    on level ground: x horizontal, z up, theta its tilt toward the motion (+ = forward).

    Four feet, k/4 and c/4 each (k = m w^2, c = 2 zeta w m; the absorber's zeta, bilateral while a
    foot is compressed, for an impact slower than bounce_speed), feet at (+-a, -h) and two at
    (0, -h); Coulomb friction mu N at each pressing foot against its slip, regularised as
    mu N tanh(slip / slip_scale) (no separate static coefficient: compare with mu_s = mu_k).
    Uniform gravity g. Time from the touchdown. Radau at rtol 1e-9, an event at ``tipped_deg``.
    Returns (time the tilt reaches tipped_deg or None, the largest tilt in degrees, the feet's
    centre's travel in m)."""
    k = mass_kg * omega * omega
    absorbing = v_down_mps < bounce_speed
    c = 2.0 * (zeta_absorb if absorbing else zeta) * omega * mass_kg
    feet = ((leg_radius_m, 0.25), (0.0, 0.5), (-leg_radius_m, 0.25))
    h = com_height_m

    def rhs(t, y):
        _, z, th, vx, vz, om = y
        s, co = math.sin(th), math.cos(th)
        fx = fz = tq = 0.0
        for bx, share in feet:
            rx, rz = bx * co - h * s, -bx * s - h * co
            pen = -(z + rz)
            if pen <= 0.0:
                continue
            ux, uz = vx + om * rz, vz - om * rx
            f = share * (k * pen - c * uz)
            if not absorbing:
                f = max(f, 0.0)
            ff = -mu * max(f, 0.0) * math.tanh(ux / slip_scale_mps)
            fx, fz = fx + ff, fz + f
            tq += rz * ff - rx * f
        return [vx, vz, om, fx / mass_kg, fz / mass_kg - g, tq / i_transverse_kgm2]

    tipped = lambda t, y: y[2] - math.radians(tipped_deg)  # noqa: E731
    tipped.terminal, tipped.direction = True, 1
    with np.errstate(over="ignore"):  # Radau's finite-difference Jacobian probes far steps
        sol = solve_ivp(rhs, (0.0, t_end_s), [0.0, h, 0.0, v_side_mps, -v_down_mps, 0.0],
                        method="Radau", rtol=1e-9, atol=1e-11, events=[tipped], max_step=0.01)
    t_tip = float(sol.t_events[0][0]) if sol.t_events[0].size else None
    feet_x = sol.y[0] - h * np.sin(sol.y[2])
    return t_tip, math.degrees(float(np.max(sol.y[2]))), float(feet_x[-1] - feet_x[0])


def rotating_slide(gm: float, radius_m: float, spin_radps: float, pos_bf_m, vel_bf_mps,
                   mu: float, t_end_s: float = 600.0):
    """Where a point sliding on a turning sphere of radius ``radius_m`` (the body-fixed frame,
    spin about +z) comes to rest under Coulomb friction mu N, in that frame:

        r'' = -GM r / |r|^3 + Omega^2 (x, y, 0) - 2 Omega z x r' + N r_hat - mu N r'_hat,

    N the normal acceleration that keeps it on the sphere (r . r' = 0: N = -|r'|^2 / r -
    r_hat . (gravity + centrifugal + Coriolis)). DOP853 at rtol 1e-11 until the speed falls to
    1e-9 m/s. Returns the body-fixed position there, and the time."""
    om = np.array([0.0, 0.0, spin_radps])

    def rhs(t, y):
        r, v = y[:3], y[3:]
        rn = np.linalg.norm(r)
        r_hat = r / rn
        free = -gm * r / rn ** 3 + spin_radps ** 2 * np.array([r[0], r[1], 0.0]) \
            - 2.0 * np.cross(om, v)
        normal = -(v @ v) / rn - r_hat @ free
        speed = np.linalg.norm(v)
        fric = -mu * max(normal, 0.0) * v / speed if speed > 0.0 else 0.0
        return np.concatenate([v, free + normal * r_hat + fric])

    stop = lambda t, y: np.linalg.norm(y[3:]) - 1e-9  # noqa: E731
    stop.terminal, stop.direction = True, -1
    sol = solve_ivp(rhs, (0.0, t_end_s), np.concatenate([pos_bf_m, vel_bf_mps]), method="DOP853",
                    rtol=1e-11, atol=1e-12, events=[stop])
    return sol.y[:3, -1], float(sol.t[-1])
