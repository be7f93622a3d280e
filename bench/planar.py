"""A planar rigid lander on four feet, with a spring-damper and a Coulomb law at each foot: the
independent reference for Touchdown's tilted, sideways and sloped touchdowns. Nothing here imports
the simulation.

The scene is planar when the lander moves in the plane of two opposite feet (a tilt, sideways speed
or slope toward a foot): the two side feet stay on the centre line, with the same slip. Ground
frame: X along the ground (downhill +, on a slope of angle alpha), Z along its normal; gravity
(g sin alpha, -g cos alpha). The lander: centre of mass (x, z), tilt theta of its long axis from the
ground's normal (+ toward +X), rate omega; transverse moment I. A foot at body (b, -h) (b = a, 0, -a:
the fore foot, the two side feet, the aft foot) sits at

    r(theta) = (b cos theta - h sin theta, -b sin theta - h cos theta)

from the centre of mass, moves at (vx + omega r_z, vz - omega r_x), and presses when its depth
along the normal d = -(z + r_z) > 0. Its penetration is measured vertically, as the seed and
Touchdown measure it (MODEL-NOTES 22; bench.reference3d likewise): x = d sec(alpha), x' = d' sec(alpha),
and the ground pushes along -grad x, sec(alpha) long, so that the normal force is

    N = s (k x + c x') sec(alpha) = s (k d + c d') sec^2(alpha),
    clamped at 0 unless the contact is absorbed (then bilateral while d > 0),

s its share (1/4; 1/2 for the pair of side feet), k = m w^2, c = 2 zeta w m, as Touchdown reads the
seed (SEED-NOTES 1: an impact slower than bounce_speed is taken by the absorbers, zeta_absorb and
bilateral; the choice is made when a foot first touches, from the centre of mass's speed along the
local vertical, and holds until every foot has left the ground with the centre of mass rising from
it along the normal). (Until 0.9 the spring was s (k d + c d') and the choice was taken on the
normal: on an 18.9 degree slope 12% softer than Touchdown's and the 3-D reference's.) Friction at
each pressing foot opposes its own slip u:

    F = -mu N tanh(u / eps),  mu = mu_s while |u| < stick_speed, mu_k above it,

Coulomb's law per foot with a stick width: a foot slipping slower than it is held by static
friction, up to mu_s N, creeping at a slip of order eps; one that the load drives faster slides at
mu_k N until its slip falls back under it. The width must go to zero with eps, more slowly than eps
(issue 35, item 9): it is sqrt(eps 1e-2) by default (3.2e-5 m/s at eps = 1e-7), as in the 3-D
reference (bench.reference3d). Until 0.8 it was the seed's 0.01 m/s, fixed: the law then reached
mu_s, but converged to Touchdown's old stick-speed law (a foot slipping slower than 1 cm/s kept
mu_s), not to Coulomb's: a 10 degree, 20 m/s touchdown with 2 m/s sideways pitched to 37.64
degrees at 2 s with it, 37.77 with a width of 1e-5 m/s (the 3-D reference: 37.77). (A foot of a
rocking ship slips by its rate times its height over the others'; micrometres a second do not
break static friction at these widths.) As eps goes to zero this is the law exactly (the tests
check the answer no longer moves when it shrinks tenfold).

The ODE is integrated by scipy's DOP853 (or Radau: the regularised friction is stiff) with events
where a foot first touches, where the last foot leaves, and at the tipped angle.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.integrate import Radau, solve_ivp
from scipy.linalg import LinAlgWarning, lu_factor, lu_solve
from scipy.linalg.lapack import get_lapack_funcs
from scipy.sparse import issparse


@dataclass(frozen=True)
class Lander:
    """The lander and the ground: SI units, angles in radians."""

    mass_kg: float = 1e4
    i_transverse_kgm2: float = 42768.15  # a uniform cylinder, radius a, length 2 h
    com_height_m: float = 3.0
    leg_radius_m: float = 2.26
    omega_radps: float = 10.0  # sqrt(k / m)
    zeta: float = 0.3
    zeta_absorb: float = 1.0
    bounce_speed_mps: float = 10.0
    mu_s: float = 0.8
    mu_k: float = 0.5
    g_mps2: float = 1.62
    slope_rad: float = 0.0
    thrust_n: float = 0.0  # along the long axis
    eps_mps: float = 1e-6  # friction's regularisation: the slip below which it is viscous
    #: a foot slipping slower is held by static friction (mu_s); None: sqrt(eps 1e-2)
    stick_speed_mps: float | None = None

    @property
    def stick_width_mps(self) -> float:
        return (self.stick_speed_mps if self.stick_speed_mps is not None
                else math.sqrt(self.eps_mps * 1e-2))


@dataclass(frozen=True)
class Start:
    """The lander at t = 0: centre of mass (x, z), tilt, velocities, and whether it is already in
    contact (and if so, absorbed)."""

    x_m: float = 0.0
    z_m: float = 10.0
    theta_rad: float = 0.0
    vx_mps: float = 0.0
    vz_mps: float = 0.0
    omega_radps: float = 0.0
    in_contact: bool = False
    absorbing: bool = False


@dataclass
class Path:
    """The solution: samples, and the instants of its transitions."""

    t: np.ndarray
    y: np.ndarray  # rows: x, z, theta, vx, vz, omega
    events: list = field(default_factory=list)  # (t, "contact" | "liftoff" | "tipped", state y)
    tipped_t_s: float | None = None

    def at(self, t: float) -> np.ndarray:
        k = int(np.searchsorted(self.t, t))
        k = min(max(k, 1), len(self.t) - 1)
        f = (t - self.t[k - 1]) / (self.t[k] - self.t[k - 1])
        return (1 - f) * self.y[:, k - 1] + f * self.y[:, k]

    def contacts(self) -> list:
        return [e for e in self.events if e[1] == "contact"]

    def liftoffs(self) -> list:
        return [e for e in self.events if e[1] == "liftoff"]


FEET = ((1.0, 0.25), (0.0, 0.5), (-1.0, 0.25))  # (b / a, share of k and c)


def foot_offsets(ld: Lander, theta: float):
    s, c = math.sin(theta), math.cos(theta)
    h = ld.com_height_m
    return [((f * ld.leg_radius_m) * c - h * s, -(f * ld.leg_radius_m) * s - h * c, share)
            for f, share in FEET]


def lowest_foot_height(ld: Lander, y) -> float:
    return min(y[1] + rz for _, rz, _ in foot_offsets(ld, y[2]))


def forces(ld: Lander, y, absorbing: bool, sliding=(False, False, False)):
    """(Fx, Fz, torque, each foot's normal force) of the ground on the lander; ``sliding``: each
    foot's friction regime (kinetic mu_k, or static up to mu_s)."""
    _, z, th, vx, vz, om = y
    m, w = ld.mass_kg, ld.omega_radps
    k = m * w * w
    c = 2.0 * (ld.zeta_absorb if absorbing else ld.zeta) * w * m
    sec2 = 1.0 / math.cos(ld.slope_rad) ** 2  # (vertical penetration, pushed along -grad x)
    fx = fz = tq = 0.0
    normals = []
    for (rx, rz, share), slides in zip(foot_offsets(ld, th), sliding):
        pen = -(z + rz)
        if pen <= 0.0:
            normals.append(0.0)
            continue
        ux, uz = vx + om * rz, vz - om * rx
        n = share * (k * pen - c * uz) * sec2
        if not absorbing:
            n = max(n, 0.0)
        mu = ld.mu_k if slides else ld.mu_s
        f = -max(n, 0.0) * mu * math.tanh(ux / ld.eps_mps)
        fx, fz = fx + f, fz + n
        tq += rz * f - rx * n
        normals.append(n)
    return fx, fz, tq, normals


def v_up(ld: Lander, y) -> float:
    """The centre of mass's speed along the local vertical (X runs downhill, Z along the normal)."""
    return y[4] * math.cos(ld.slope_rad) - y[3] * math.sin(ld.slope_rad)


def foot_slips(ld: Lander, y):
    """Each foot's slip along the ground, m/s."""
    return [y[3] + y[5] * rz for _, rz, _ in foot_offsets(ld, y[2])]


@njit(cache=True)
def _rhs_compiled(y, par, sliding, absorbing, in_contact):
    """:func:`forces` and the equations of motion, the same operations in the same order (no
    fastmath: the same bits as the Python below), compiled: the integrator calls it ~10^4 times a
    solve. ``par``: mass, I, com height, leg radius, omega, zeta, zeta_absorb, mu_s, mu_k, g,
    slope, thrust, eps (:func:`_params`)."""
    m, i_t, h, a, w = par[0], par[1], par[2], par[3], par[4]
    g, alpha, thrust, eps = par[9], par[10], par[11], par[12]
    fx = fz = tq = 0.0
    th = y[2]
    if in_contact:
        z, vx, vz, om = y[1], y[3], y[4], y[5]
        k = m * w * w
        c = 2.0 * (par[6] if absorbing else par[5]) * w * m
        sec2 = 1.0 / math.cos(alpha) ** 2
        s, co = math.sin(th), math.cos(th)
        for i in range(3):
            f_b = 1.0 - i  # FEET: b / a = 1, 0, -1; shares 1/4, 1/2, 1/4
            share = 0.5 if i == 1 else 0.25
            rx = (f_b * a) * co - h * s
            rz = -(f_b * a) * s - h * co
            pen = -(z + rz)
            if pen <= 0.0:
                continue
            ux, uz = vx + om * rz, vz - om * rx
            n = share * (k * pen - c * uz) * sec2
            if not absorbing:
                n = 0.0 if 0.0 > n else n  # max(n, 0.0), Python's
            mu = par[8] if sliding[i] else par[7]
            f = -(0.0 if 0.0 > n else n) * mu * math.tanh(ux / eps)
            fx, fz = fx + f, fz + n
            tq += rz * f - rx * n
    tx, tz = thrust * math.sin(th), thrust * math.cos(th)
    out = np.empty(6)
    out[0], out[1], out[2] = y[3], y[4], y[5]
    out[3] = (fx + tx) / m + g * math.sin(alpha)
    out[4] = (fz + tz) / m - g * math.cos(alpha)
    out[5] = tq / i_t
    return out


def _params(ld: Lander) -> np.ndarray:
    return np.array([ld.mass_kg, ld.i_transverse_kgm2, ld.com_height_m, ld.leg_radius_m,
                     ld.omega_radps, ld.zeta, ld.zeta_absorb, ld.mu_s, ld.mu_k, ld.g_mps2,
                     ld.slope_rad, ld.thrust_n, ld.eps_mps], float)


def rhs(ld: Lander, absorbing: bool, in_contact: bool, sliding):
    """The right-hand side for solve_ivp: :func:`forces` (compiled, :func:`_rhs_compiled`)."""
    par, slides = _params(ld), np.array(sliding, np.bool_)
    absorbing, in_contact = bool(absorbing), bool(in_contact)

    def f(t, y):
        return _rhs_compiled(y, par, slides, absorbing, in_contact)
    return f


def rhs_python(ld: Lander, absorbing: bool, in_contact: bool, sliding):
    """:func:`rhs` in Python, through :func:`forces` (the compiled one is checked against it,
    bit for bit: tests/test_edges.py, ``solve(..., plain=True)``)."""
    sa, ca = math.sin(ld.slope_rad), math.cos(ld.slope_rad)
    m, i_t = ld.mass_kg, ld.i_transverse_kgm2

    def f(t, y):
        fx, fz, tq = (forces(ld, y, absorbing, sliding)[:3] if in_contact else (0.0, 0.0, 0.0))
        th = y[2]
        tx, tz = ld.thrust_n * math.sin(th), ld.thrust_n * math.cos(th)
        return [y[3], y[4], y[5], (fx + tx) / m + ld.g_mps2 * sa,
                (fz + tz) / m - ld.g_mps2 * ca, tq / i_t]
    return f


_GETRF_GETRS = {k: get_lapack_funcs(("getrf", "getrs"), (np.zeros((1, 1), k),))
                for k in (np.float64, np.complex128)}


class RadauLapack(Radau):
    """scipy's Radau, its LU factorisations and solves calling LAPACK's getrf and getrs straight,
    as scipy.linalg.lu_factor and lu_solve do after their checks (kept: a matrix or right-hand
    side that is not finite raises as there, a singular one warns): the same routines on the same
    arrays, the same bits (checked, tests/test_edges.py), without the wrappers' overhead
    (60% of a stiff solve's time went to them: scipy 1.17's batch wrapper and array-API
    checks). A dtype it does not expect goes to scipy's functions."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if issparse(self.J):
            return

        def lu(a):
            self.nlu += 1
            funcs = _GETRF_GETRS.get(a.dtype.type)
            if funcs is None or a.ndim != 2 or a.size == 0:
                return lu_factor(a, overwrite_a=True)
            if not np.isfinite(a).all():
                raise ValueError("array must not contain infs or NaNs")
            lu_, piv, info = funcs[0](a, overwrite_a=True)
            if info < 0:
                raise ValueError(f"illegal value in {-info}th argument of internal getrf "
                                 "(lu_factor)")
            if info > 0:
                warnings.warn(f"Diagonal number {info} is exactly zero. Singular matrix.",
                              LinAlgWarning, stacklevel=2)
            return lu_, piv

        def solve_lu(lu_piv, b):
            lu_, piv = lu_piv
            funcs = _GETRF_GETRS.get(lu_.dtype.type)
            if (funcs is None or b.dtype != lu_.dtype or b.ndim != 1 or b.size == 0
                    or lu_.shape[0] != b.shape[0]):
                return lu_solve(lu_piv, b, overwrite_b=True)
            if not np.isfinite(b).all():
                raise ValueError("array must not contain infs or NaNs")
            x, info = funcs[1](lu_, piv, b, trans=0, overwrite_b=True)
            if info == 0:
                return x
            raise ValueError(f"illegal value in {-info}th argument of internal gesv|posv")

        self.lu, self.solve_lu = lu, solve_lu


def solve(ld: Lander, start: Start, t_end_s: float, tipped_rad: float = math.radians(80.0),
          method: str = "Radau", rtol: float = 1e-10, atol: float = 1e-12,
          max_step_s: float = 0.01, max_phases: int = 2000, plain: bool = False) -> Path:
    """The lander from ``start`` until ``t_end_s`` or until it tips (tilt past ``tipped_rad``).
    Phases (flight, contact, each foot's friction regime) are joined at located events; at most
    ``max_phases`` of them. ``plain``: the right-hand side in Python and scipy's own Radau (the
    same bits, slower: the check of :func:`_rhs_compiled` and :class:`RadauLapack`)."""
    t, y = 0.0, np.array([start.x_m, start.z_m, start.theta_rad, start.vx_mps, start.vz_mps,
                          start.omega_radps], float)
    in_contact, absorbing = start.in_contact, start.absorbing
    ts, ys, events = [np.array([t])], [y[:, None]], []
    tipped_t = None
    opts = dict(method=RadauLapack if method == "Radau" and not plain else method, rtol=rtol,
                atol=atol, max_step=max_step_s)
    make_rhs = rhs_python if plain else rhs

    def regimes(y_):
        return tuple(abs(u) > ld.stick_width_mps for u in foot_slips(ld, y_))

    sliding = regimes(y)
    tip = lambda t_, y_: abs(y_[2]) - tipped_rad  # noqa: E731
    tip.terminal, tip.direction = True, 1
    for _ in range(max_phases):
        if t >= t_end_s:
            break
        ground = lambda t_, y_: lowest_foot_height(ld, y_)  # noqa: E731
        ground.terminal, ground.direction = True, (1 if in_contact else -1)
        evs = [ground, tip]
        for i in range(3):
            width = ld.stick_width_mps
            ev = (lambda i_, w_: (lambda t_, y_: abs(foot_slips(ld, y_)[i_]) - w_))(i, width)
            ev.terminal, ev.direction = True, (-1 if sliding[i] else 1)
            evs.append(ev)
        with np.errstate(over="ignore"):
            sol = solve_ivp(make_rhs(ld, absorbing, in_contact, sliding), (t, t_end_s), y,
                            events=evs, **opts)
        ts.append(sol.t[1:])
        ys.append(sol.y[:, 1:])
        t, y = float(sol.t[-1]), sol.y[:, -1].copy()
        if sol.status != 1:
            break
        if sol.t_events[1].size:
            tipped_t = float(sol.t_events[1][0])
            events.append((tipped_t, "tipped", y.copy()))
            break
        if sol.t_events[0].size:
            if in_contact:
                # a foot can leave and come back within one contact; it ends only when the lander
                # rises clear (the centre of mass moving away from the ground)
                if y[4] > 0.0:
                    events.append((t, "liftoff", y.copy()))
                    in_contact = False
                else:
                    y[1] += 1e-12  # past the grazing point; the contact goes on
            else:
                events.append((t, "contact", y.copy()))
                in_contact = True
                absorbing = -v_up(ld, y) < ld.bounce_speed_mps
        else:
            hit = [i for i in range(3) if sol.t_events[2 + i].size]
            sliding = tuple((not s) if i in hit else s for i, s in enumerate(sliding))
    return Path(np.concatenate(ts), np.concatenate(ys, axis=1), events, tipped_t)


def energy_j(ld: Lander, y, absorbing: bool = False) -> float:
    """Kinetic + gravitational (uniform g, along the slope's frame) + the springs' k x^2 / 2."""
    m = ld.mass_kg
    sa, ca = math.sin(ld.slope_rad), math.cos(ld.slope_rad)
    kin = 0.5 * m * (y[3] ** 2 + y[4] ** 2) + 0.5 * ld.i_transverse_kgm2 * y[5] ** 2
    pot = m * ld.g_mps2 * (y[1] * ca - y[0] * sa)
    k = m * ld.omega_radps ** 2
    sec = 1.0 / ca  # the penetration is vertical: x = d sec(alpha)
    spring = sum(0.5 * share * k * (max(-(y[1] + rz), 0.0) * sec) ** 2
                 for _, rz, share in foot_offsets(ld, y[2]))
    return kin + pot + spring


def resting_height(ld: Lander, theta: float = 0.0) -> float:
    """Centre-of-mass height at which an upright lander's four feet carry its weight's normal
    component statically: k d sec^2(alpha) = m g cos(alpha), d = g cos^3(alpha) / w^2."""
    return ld.com_height_m - ld.g_mps2 * math.cos(ld.slope_rad) ** 3 / ld.omega_radps ** 2
