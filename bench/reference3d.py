"""A rigid lander on four feet in three dimensions, with a spring-damper and a regularised Coulomb
law at each foot: the independent reference for Touchdown's contact at the edges (issue 35).
Nothing here imports the simulation; the scene conventions (the site, the start's tilt, heading
and yaw, the slope's azimuth) are SPEC.md's, written out again here.

The body: a point mass GM at the origin, radius R, not turning. The landing site is the point
(R, 0, 0); east is +y, north +z. The terrain is the height field h(e, n) = s_e e + s_n n over
(e, n) = (y, z) with (s_e, s_n) = -tan(slope) (sin az, cos az): the ground slopes down toward the
azimuth az, from north toward east.

The lander: mass m, principal inertia I (body frame, z the long axis), four feet at body
(+-a, 0, -h) and (0, +-a, -h) (a = leg_radius, h = com_height). Its state is the centre of mass
relative to the site d (so that millimetres a body's radius from its centre are resolved), its
velocity v, attitude q (body -> inertial) and body-frame angular velocity w:

    d' = v,   m v' = -m GM p / |p|^3 + T e_z + sum_i F_i,   p = (R, 0, 0) + d
    q' = q (x) (0, w) / 2,   I w' = tau_rcs + R^T sum_i r_i x F_i - w x I w

Each foot i, at P_i = p + r_i, has penetration x_i = R + h(P_i) - |P_i| (along the local radial,
as Touchdown and the seed measure it) and is pushed along g_i = -grad x_i = P_i / |P_i| -
grad h (length sec(slope)) by

    F_i = k_i x_i + c_i x_i',   x_i' = -g_i . u_i,   u_i = v + omega x r_i,

k_i = k / 4 = stiffness_per_kg m / 4, c_i = 2 zeta sqrt(k m) / 4, clamped at zero unless the
contact is absorbed (SEED-NOTES 1: a touchdown slower than bounce_speed along the local radial is
taken by the critically damped absorbers, bilateral while a foot is compressed; the choice is made
where the first foot touches and holds until every foot is clear and the ship rises); zero where
x_i <= 0. The normal force is N_i = F_i |g_i|.

Friction at each pressing foot acts in the terrain's tangent plane there, taken on the centre of
mass's local vertical (normal n_i = unit(p / |p| - grad h): the sphere's own curvature across the
footprint, a / R ~ 1e-6 rad, left out), against the foot's slip s_i (u_i less its part along n_i):

    f_i = -mu(|s_i|) max(N_i, 0) tanh(|s_i| / eps) s_i / |s_i|,
    mu(s) = mu_k + (mu_s - mu_k) exp(-(s / v_s)^2),

a regularised Coulomb law with a Stribeck drop from mu_s to mu_k over the width v_s. Both widths go
to zero for Coulomb's law, and v_s must go more slowly than eps: a foot that sticks slips at a few
eps, where the law must have reached mu_s, so v_s / eps must grow without bound (issue 35, item 9:
with v_s = 10 eps the law never exceeds 0.77 and the sticking answers are 2-4% off). Here
v_s = sqrt(eps * STRIBECK_SCALE_MPS) by default (1e-4 m/s at eps = 1e-6: 100 eps); the answers
are checked to stop moving as eps shrinks tenfold (tests/test_reference3d.py).

Integration: scipy's solve_ivp (Radau by default, LSODA and DOP853 to cross-check; the friction is
stiff while a foot sticks: mu N / (m eps) ~ 1e5 1/s) at rtol 1e-9, with the right-hand side and a
finite-difference Jacobian compiled by numba (a tool, not the simulation's code). Events end a
segment wherever the law has a kink or a jump: each foot's penetration crossing zero (the damper's
force jumps there), the liftoff (every foot clear and the centre of mass rising from the ground
along its normal: :func:`v_rise`; until 0.9 along the local vertical), the tilt from
local vertical crossing the tipped angle (either way), and the end of an RCS burn.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

#: v_s = sqrt(eps * STRIBECK_SCALE_MPS): the Stribeck width shrinks as the root of the smoothing
STRIBECK_SCALE_MPS = 1e-2

MOON_GM = 4.9048695e12
MOON_R = 1737400.0

# -- the parameters as the compiled kernels read them (one float array) --------------------------
(P_R, P_GM, P_SE, P_SN, P_M, P_IX, P_IY, P_IZ, P_A, P_H, P_K, P_C, P_CA, P_MUS, P_MUK, P_EPS,
 P_VS, P_T, P_TX, P_TY, P_TZ, P_ABS, P_RCS) = range(23)
N_PAR = 23


@dataclass(frozen=True)
class Lander3:
    """The lander, SI units. ``inertia_kgm2`` None: a uniform solid cylinder of radius
    max(leg_radius, 0.5) and length 2 com_height (SPEC.md's default)."""

    mass_kg: float = 1e4
    com_height_m: float = 3.0
    leg_radius_m: float = 2.26
    inertia_kgm2: tuple | None = None
    stiffness_per_kg: float = 100.0
    zeta: float = 0.3
    zeta_absorb: float = 1.0
    bounce_speed_mps: float = 10.0
    mu_s: float = 0.8
    mu_k: float = 0.5
    thrust_n: float = 0.0  # along body +z, throughout
    rcs_torque_body_nm: tuple = (0.0, 0.0, 0.0)
    rcs_until_s: float = math.inf  # the RCS torque acts from 0 until then

    @property
    def inertia(self) -> tuple:
        if self.inertia_kgm2 is not None:
            return tuple(self.inertia_kgm2)
        r, length, m = max(self.leg_radius_m, 0.5), 2.0 * self.com_height_m, self.mass_kg
        ixx = m * (3.0 * r * r + length * length) / 12.0
        return (ixx, ixx, 0.5 * m * r * r)


@dataclass(frozen=True)
class Ground3:
    gm_m3ps2: float = MOON_GM
    radius_m: float = MOON_R
    slope_deg: float = 0.0
    slope_azimuth_deg: float = 0.0  # the downhill direction, from north toward east

    @property
    def gradient(self) -> tuple[float, float]:
        if self.slope_deg == 0.0:
            return 0.0, 0.0
        t = math.tan(math.radians(self.slope_deg))
        az = math.radians(self.slope_azimuth_deg)
        return -t * math.sin(az), -t * math.cos(az)


@dataclass(frozen=True)
class Law:
    """The friction law's regularisation: eps (tanh's width) and v_s (the Stribeck width; None:
    sqrt(eps STRIBECK_SCALE_MPS))."""

    eps_mps: float = 1e-6
    stribeck_mps: float | None = None

    @property
    def v_s(self) -> float:
        return (self.stribeck_mps if self.stribeck_mps is not None
                else math.sqrt(self.eps_mps * STRIBECK_SCALE_MPS))


@dataclass(frozen=True)
class Start3:
    """Where the lander starts (SPEC.md's ``ships.initial``): the lowest foot ``altitude_m`` above
    the terrain under it (negative: pressed in), the long axis tilted toward the heading and the
    ship turned by yaw about it (yaw 0: foot 0 toward the heading), velocities along local up and
    the heading, angular velocity in the body frame. ``state``: "flying" or in contact
    ("contact", "landed", "tipped": all the same here), absorbed as the scenario does it (a start
    on the ground slower than bounce_speed)."""

    altitude_m: float = 10.0
    tilt_deg: float = 0.0
    heading_deg: float = 0.0
    yaw_deg: float = 0.0
    vertical_speed_mps: float = 0.0
    horizontal_speed_mps: float = 0.0
    angular_velocity_body: tuple = (0.0, 0.0, 0.0)
    east_m: float = 0.0
    north_m: float = 0.0
    state: str = "flying"


def params_array(ld: Lander3, gr: Ground3, law: Law, absorbing: bool, rcs_on: bool) -> np.ndarray:
    par = np.zeros(N_PAR)
    s_e, s_n = gr.gradient
    m = ld.mass_kg
    k = ld.stiffness_per_kg * m
    w = math.sqrt(ld.stiffness_per_kg)
    ix, iy, iz = ld.inertia
    par[P_R], par[P_GM], par[P_SE], par[P_SN] = gr.radius_m, gr.gm_m3ps2, s_e, s_n
    par[P_M], par[P_IX], par[P_IY], par[P_IZ] = m, ix, iy, iz
    par[P_A], par[P_H], par[P_K] = ld.leg_radius_m, ld.com_height_m, k
    par[P_C], par[P_CA] = 2.0 * ld.zeta * w * m, 2.0 * ld.zeta_absorb * w * m
    par[P_MUS], par[P_MUK], par[P_EPS], par[P_VS] = ld.mu_s, ld.mu_k, law.eps_mps, law.v_s
    par[P_T] = ld.thrust_n
    par[P_TX], par[P_TY], par[P_TZ] = ld.rcs_torque_body_nm
    par[P_ABS] = 1.0 if absorbing else 0.0
    par[P_RCS] = 1.0 if rcs_on else 0.0
    return par


# -- the compiled right-hand side ------------------------------------------------------------------
@njit(cache=True)
def _rot(q, v):
    """q v q*: body -> inertial."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    return np.array([v[0] + w * tx + (y * tz - z * ty), v[1] + w * ty + (z * tx - x * tz),
                     v[2] + w * tz + (x * ty - y * tx)])


@njit(cache=True)
def _rot_inv(q, v):
    return _rot(np.array([q[0], -q[1], -q[2], -q[3]]), v)


@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def _foot_body(i, a, h):
    if i == 0:
        return np.array([a, 0.0, -h])
    if i == 1:
        return np.array([0.0, a, -h])
    if i == 2:
        return np.array([-a, 0.0, -h])
    return np.array([0.0, -a, -h])


@njit(cache=True)
def feet_state(y, par):
    """Per foot: penetration x, its rate x', the force F (as the law clamps it), the normal force
    N = F |g|, and the slip speed |s| (rows 0..4 of a 5 x 4 array)."""
    out = np.zeros((5, 4))
    _contact(y, par, out)
    return out


@njit(cache=True)
def _contact(y, par, out):
    """(force, torque about the centre of mass) of the ground, inertial; fills ``out`` (5 x 4)
    with each foot's x, x', F, N, |slip|."""
    big_r = par[P_R]
    d = y[0:3]
    v = y[3:6]
    qn = np.sqrt(y[6] ** 2 + y[7] ** 2 + y[8] ** 2 + y[9] ** 2)
    q = y[6:10] / qn
    w_b = y[10:13]
    w_w = _rot(q, w_b)
    s_e, s_n = par[P_SE], par[P_SN]
    grad_h = np.array([0.0, s_e, s_n])
    p = np.array([big_r + d[0], d[1], d[2]])
    p_hat = p / np.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
    n_f = p_hat - grad_h
    n_f = n_f / np.sqrt(n_f[0] ** 2 + n_f[1] ** 2 + n_f[2] ** 2)
    k_i, c_i = 0.25 * par[P_K], 0.25 * (par[P_CA] if par[P_ABS] > 0.5 else par[P_C])
    absorbing = par[P_ABS] > 0.5
    mu_s, mu_k, eps, v_s = par[P_MUS], par[P_MUK], par[P_EPS], par[P_VS]
    force = np.zeros(3)
    torque = np.zeros(3)
    for i in range(4):
        r = _rot(q, _foot_body(i, par[P_A], par[P_H]))
        xx = d + r  # the foot relative to the site
        r2 = big_r * big_r + 2.0 * big_r * xx[0] + xx[0] * xx[0] + xx[1] * xx[1] + xx[2] * xx[2]
        rr = np.sqrt(r2)
        above = (2.0 * big_r * xx[0] + xx[0] * xx[0] + xx[1] * xx[1] + xx[2] * xx[2]) / (rr + big_r)
        foot = np.array([big_r + xx[0], xx[1], xx[2]])
        hgt = s_e * foot[1] + s_n * foot[2]
        pen = hgt - above
        g = foot / rr - grad_h
        u = v + _cross(w_w, r)
        rate = -(g[0] * u[0] + g[1] * u[1] + g[2] * u[2])
        f = k_i * pen + c_i * rate
        if not absorbing and f < 0.0:
            f = 0.0
        if pen <= 0.0:
            f = 0.0
        g_norm = np.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
        nrm = f * g_norm
        un = u[0] * n_f[0] + u[1] * n_f[1] + u[2] * n_f[2]
        slip = u - un * n_f
        s = np.sqrt(slip[0] ** 2 + slip[1] ** 2 + slip[2] ** 2)
        fv = f * g
        if nrm > 0.0 and s > 0.0:
            z = s / v_s
            mu = mu_k + (mu_s - mu_k) * np.exp(-z * z)
            fv = fv - slip * (mu * nrm * np.tanh(s / eps) / s)
        force += fv
        torque += _cross(r, fv)
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i] = pen, rate, f, nrm, s
    return force, torque


@njit(cache=True)
def rhs(t, y, par):
    out = np.zeros((5, 4))
    force, torque = _contact(y, par, out)
    big_r = par[P_R]
    p = np.array([big_r + y[0], y[1], y[2]])
    r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
    r3 = r2 * np.sqrt(r2)
    m = par[P_M]
    qn = np.sqrt(y[6] ** 2 + y[7] ** 2 + y[8] ** 2 + y[9] ** 2)
    q = y[6:10] / qn
    ez = _rot(q, np.array([0.0, 0.0, 1.0]))
    acc = -par[P_GM] * p / r3 + (force + par[P_T] * ez) / m
    w = y[10:13]
    tau = _rot_inv(q, torque)
    if par[P_RCS] > 0.5:
        tau = tau + np.array([par[P_TX], par[P_TY], par[P_TZ]])
    inertia = np.array([par[P_IX], par[P_IY], par[P_IZ]])
    lw = inertia * w
    alpha = (tau - _cross(w, lw)) / inertia
    dq = 0.5 * np.array([-q[1] * w[0] - q[2] * w[1] - q[3] * w[2],
                         q[0] * w[0] + q[2] * w[2] - q[3] * w[1],
                         q[0] * w[1] + q[3] * w[0] - q[1] * w[2],
                         q[0] * w[2] + q[1] * w[1] - q[2] * w[0]])
    out_d = np.empty(13)
    out_d[0:3] = y[3:6]
    out_d[3:6] = acc
    out_d[6:10] = dq
    out_d[10:13] = alpha
    return out_d


@njit(cache=True)
def jac(t, y, par):
    """Forward differences, each step scaled to its variable (slips resolved far below eps)."""
    f0 = rhs(t, y, par)
    out = np.empty((13, 13))
    for j in range(13):
        typ = 1e-3 if j < 3 else (1e-4 if j < 6 else (1e-6 if j < 10 else 1e-5))
        hj = 1e-8 * max(abs(y[j]), typ)
        yj = y.copy()
        yj[j] += hj
        out[:, j] = (rhs(t, yj, par) - f0) / hj
    return out


# -- the scene ------------------------------------------------------------------------------------
def _unit(v):
    return v / np.linalg.norm(v)


def quat_from_axes(ex, ey, ez) -> np.ndarray:
    """The attitude whose body axes are ex, ey, ez (a rotation matrix's columns)."""
    m = np.column_stack([ex, ey, ez])
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        return np.array([0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s,
                         (m[1, 0] - m[0, 1]) / s])
    i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
    q = np.zeros(4)
    q[0] = (m[k, j] - m[j, k]) / s
    q[1 + i] = 0.25 * s
    q[1 + j] = (m[j, i] + m[i, j]) / s
    q[1 + k] = (m[k, i] + m[i, k]) / s
    return q if q[0] >= 0 else -q


def initial_state(ld: Lander3, gr: Ground3, st: Start3) -> np.ndarray:
    """The state vector of a start (SPEC.md section 3's placement, by the lowest foot)."""
    big_r = gr.radius_m
    site = np.array([big_r, st.east_m, st.north_m])
    r_hat = _unit(site)
    east = _unit(np.cross([0.0, 0.0, 1.0], r_hat))
    north = np.cross(r_hat, east)
    hd, th, yw = (math.radians(x) for x in (st.heading_deg, st.tilt_deg, st.yaw_deg))
    fwd = north * math.cos(hd) + east * math.sin(hd)
    ez = r_hat * math.cos(th) + fwd * math.sin(th)
    ex = fwd * math.cos(th) - r_hat * math.sin(th)
    ey = np.cross(ez, ex)
    ex, ey = ex * math.cos(yw) + ey * math.sin(yw), ey * math.cos(yw) - ex * math.sin(yw)
    q = quat_from_axes(ex, ey, ez)
    par = params_array(ld, gr, Law(), False, False)
    y = np.zeros(13)
    y[6:10] = q
    # the lowest foot at the altitude: move along r_hat (the feet's height is linear in the move
    # to within the curvature; a few passes reach rounding)
    rho = big_r + st.altitude_m + ld.com_height_m
    for _ in range(60):
        y[0:3] = r_hat * rho - np.array([big_r, 0.0, 0.0])
        alt = -feet_state(y, par)[0].max()
        move = st.altitude_m - alt
        rho += move
        if abs(move) < 1e-13:
            break
    y[0:3] = r_hat * rho - np.array([big_r, 0.0, 0.0])
    y[3:6] = r_hat * st.vertical_speed_mps + fwd * st.horizontal_speed_mps
    y[10:13] = st.angular_velocity_body
    return y


@dataclass
class Event3:
    t_s: float
    kind: str  # "contact", "liftoff", "tipped", "righted"
    v_radial_mps: float


@dataclass
class Path3:
    """The solution: segments of dense output, the events, and the scene."""

    lander: Lander3
    ground: Ground3
    law: Law
    segments: list = field(default_factory=list)  # (t0, t1, OdeSolution, absorbing, rcs_on)
    events: list = field(default_factory=list)
    t_end_s: float = 0.0
    status: str = ""  # "", "tipped" (stopped at the tipped angle)
    n_rhs: int = 0

    def y(self, t: float) -> np.ndarray:
        for t0, t1, sol, _, _ in self.segments:
            if t <= t1 or (t0, t1) == self.segments[-1][:2]:
                out = sol(min(max(t, t0), t1))
                out[6:10] /= np.linalg.norm(out[6:10])
                return out
        raise ValueError(t)

    def par_at(self, t: float) -> np.ndarray:
        for t0, t1, _, absorbing, rcs_on in self.segments:
            if t <= t1:
                return params_array(self.lander, self.ground, self.law, absorbing, rcs_on)
        _, _, _, absorbing, rcs_on = self.segments[-1]
        return params_array(self.lander, self.ground, self.law, absorbing, rcs_on)

    def first(self, kind: str) -> Event3 | None:
        for e in self.events:
            if e.kind == kind:
                return e
        return None

    # -- what a user checks, as functions of time ---------------------------------------------
    def sample(self, ts) -> np.ndarray:
        return np.array([self.y(float(t)) for t in ts])


def _ez(y):
    return _rot(y[6:10] / np.linalg.norm(y[6:10]), np.array([0.0, 0.0, 1.0]))


def p_of(gr: Ground3, y) -> np.ndarray:
    return np.array([gr.radius_m + y[0], y[1], y[2]])


def cos_tilt(gr: Ground3, y) -> float:
    """Cosine of the long axis' angle from local vertical."""
    return float(_ez(y) @ _unit(p_of(gr, y)))


def tilt_deg(gr: Ground3, y) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, cos_tilt(gr, y)))))


def v_radial(gr: Ground3, y) -> float:
    return float(y[3:6] @ _unit(p_of(gr, y)))


def v_rise(gr: Ground3, y) -> float:
    """How fast the centre of mass rises from the ground: g . v, g = p / |p| - grad h (its gap's
    rate; on level ground the radial speed). A ship hopping off a slope's downhill feet rises
    from the ground while it descends."""
    s_e, s_n = gr.gradient
    return float(y[3:6] @ (_unit(p_of(gr, y)) - np.array([0.0, s_e, s_n])))


def ground_normal(gr: Ground3, y) -> np.ndarray:
    s_e, s_n = gr.gradient
    return _unit(_unit(p_of(gr, y)) - np.array([0.0, s_e, s_n]))


def solve3(ld: Lander3, gr: Ground3, st: Start3, t_end_s: float, law: Law = Law(),
           method: str = "Radau", rtol: float = 1e-9, atol: float | None = None,
           tipped_deg: float = 80.0, stop_at_tipped: bool = True, max_segments: int = 4000,
           max_step_s: float = 0.05, y0: np.ndarray | None = None) -> Path3:
    """The lander from ``start`` until ``t_end_s`` (or until it tips past ``tipped_deg`` when
    ``stop_at_tipped``). Segments are joined at the events of the module docstring."""
    y = initial_state(ld, gr, st) if y0 is None else np.array(y0, float)
    t = 0.0
    on_ground = st.state != "flying"
    absorbing = on_ground and abs(st.vertical_speed_mps) < ld.bounce_speed_mps
    rcs_on = ld.rcs_until_s > 0.0 and any(x != 0.0 for x in ld.rcs_torque_body_nm)
    path = Path3(ld, gr, law)
    if atol is None:
        atol = np.array([1e-10] * 3 + [1e-10] * 3 + [1e-12] * 4 + [1e-11] * 3)
    cos_tip = math.cos(math.radians(tipped_deg))
    in_contact = on_ground
    fs = feet_state(y, params_array(ld, gr, law, absorbing, rcs_on))
    lowest = int(np.argmax(fs[0]))
    if not on_ground and fs[0, lowest] > -1e-12 and fs[1, lowest] > 0.0:
        # a flying start with a foot at the ground and going in: the touchdown is now
        in_contact = True
        absorbing = -v_radial(gr, y) < ld.bounce_speed_mps
        path.events.append(Event3(0.0, "contact", v_radial(gr, y)))
    for _ in range(max_segments):
        if t >= t_end_s:
            break
        par = params_array(ld, gr, law, absorbing, rcs_on)

        def foot_event(i):
            def ev(t_, y_):
                return feet_state(y_, par)[0, i]
            ev.terminal, ev.direction = True, 0
            return ev

        def clamp_event(i):
            k_i, c_i = 0.25 * par[P_K], 0.25 * par[P_C]

            def ev(t_, y_):
                fs = feet_state(y_, par)
                return k_i * fs[0, i] + c_i * fs[1, i]
            ev.terminal, ev.direction = True, 0
            return ev

        evs = [foot_event(i) for i in range(4)]
        tip = lambda t_, y_: cos_tilt(gr, y_) - cos_tip  # noqa: E731
        tip.terminal, tip.direction = True, 0
        evs.append(tip)
        if not absorbing:  # the clamp: a kink in the force where a pressing foot lets go
            evs += [clamp_event(i) for i in range(4)]
        t_stop = t_end_s
        if rcs_on and ld.rcs_until_s < t_end_s:
            t_stop = min(t_stop, ld.rcs_until_s)
        f = lambda t_, y_: rhs(t_, y_, par)  # noqa: E731
        jf = lambda t_, y_: jac(t_, y_, par)  # noqa: E731
        kw = dict(method=method, rtol=rtol, atol=atol, events=evs, dense_output=True,
                  max_step=max_step_s)
        if method in ("Radau", "BDF", "LSODA"):
            kw["jac"] = jf
        sol = solve_ivp(f, (t, t_stop), y, **kw)
        path.n_rhs += sol.nfev
        if sol.status < 0:
            raise RuntimeError(f"reference3d: {sol.message} at t = {sol.t[-1]:.6g}")
        t_new = float(sol.t[-1])
        y_new = sol.y[:, -1].copy()
        y_new[6:10] /= np.linalg.norm(y_new[6:10])
        path.segments.append((t, t_new, sol.sol, absorbing, rcs_on))
        t, y = t_new, y_new
        if sol.status == 0:  # reached t_stop
            if rcs_on and t >= ld.rcs_until_s - 1e-15 and t < t_end_s:
                rcs_on = False
                continue
            break
        hit = [k for k in range(len(evs)) if sol.t_events[k].size]
        if 4 in hit:
            # which way the tilt goes: d(cos tilt)/dt from the attitude's rate
            ez_rate = _cross(_rot(y[6:10], y[10:13]), _ez(y))
            going = float(ez_rate @ _unit(p_of(gr, y)))
            kind = "tipped" if going < 0 else "righted"
            if in_contact:  # a ship tumbling in flight is flying (Touchdown's states)
                path.events.append(Event3(t, kind, v_radial(gr, y)))
            if kind == "tipped" and stop_at_tipped and in_contact:
                path.status = "tipped"
                break
            # step off the crossing so that the event is not found again at once
            t, y = _nudge(par, t, y, t_stop)
            continue
        # a foot crossed the ground or its force the clamp: the contact's bookkeeping, then on
        # from a state nudged past the crossing (the crossing itself would be found again at once)
        t2, y2 = _nudge(par, t, y, t_stop)
        pen2 = feet_state(y2, par)[0]
        if not in_contact and pen2.max() > 0.0:
            in_contact = True
            v_imp = -v_radial(gr, y)
            absorbing = v_imp < ld.bounce_speed_mps
            path.events.append(Event3(t, "contact", -v_imp))
            if cos_tilt(gr, y) < cos_tip:  # touching down lying down: on its side at once
                path.events.append(Event3(t, "tipped", -v_imp))
                if stop_at_tipped:
                    path.status = "tipped"
                    t, y = t2, y2
                    break
        elif in_contact and pen2.max() <= 0.0 and v_rise(gr, y) > 0.0:
            in_contact = False
            absorbing = False
            path.events.append(Event3(t, "liftoff", v_radial(gr, y)))
        t, y = t2, y2
    path.t_end_s = t
    return path


def _nudge(par, t, y, t_stop):
    """A state a hair past an event: 1e-9 s on by the midpoint rule (the event's own state would
    trigger it again at once)."""
    dt = min(1e-9, max(t_stop - t, 0.0))
    k1 = rhs(t, y, par)
    y2 = y + dt * rhs(t + 0.5 * dt, y + 0.5 * dt * k1, par)
    y2[6:10] /= np.linalg.norm(y2[6:10])
    return t + dt, y2
