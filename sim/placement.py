"""Where a scenario's ships start (SPEC.md section 3): each ship's pose and motion from its
``initial`` table, its lowest foot at the given altitude over the terrain, compiled (sim.compiled).

Apart from :mod:`sim.scenario`, which checks and resolves a document in plain Python: a tool that
only reads a scenario's parameters (``touchdown export`` of a log's numbers) needs no compiled
code, and loads none (numba's import and its kernels' loading, half a second).
"""
from __future__ import annotations

import math

import numpy as np

from touchdown.sim import trig, vec
from touchdown.sim.compiled import entry, kernel, separate
from touchdown.sim.contact import Ground, lowest_foot, lowest_foot_penetration
from touchdown.sim.enums import SurfaceState
from touchdown.sim.params import Params
from touchdown.sim.settings import SurfaceNormal
from touchdown.sim.state import State


@kernel
def quat_from_axes(ex, ey, ez):
    """The unit quaternion (w, x, y, z) of the rotation whose matrix has columns ex, ey, ez
    (Shepperd's method: the largest of the four candidates' diagonals, for accuracy)."""
    m00, m10, m20 = ex
    m01, m11, m21 = ey
    m02, m12, m22 = ez
    tr = m00 + m11 + m22
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2
        q = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2
        q = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2
        q = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    return vec.quat_normalize(q)


#: Iterations placing a ship by its lowest foot (each moves it by the remaining error; the feet's
#: site coordinates shift by a fraction of the move, so a few reach rounding on any slope).
MAX_PLACEMENT_ITERATIONS = 50

#: Columns of the table of starts _place_ships reads, one row per ship.
(_EAST, _NORTH, _ALT, _COS_HD, _SIN_HD, _COS_TH, _SIN_TH, _COS_YAW, _SIN_YAW, _LEG, _COM, _V_UP,
 _V_FWD, _W_X, _W_Y, _W_Z) = range(16)


@separate
def _place(ground, r_hat, quat, leg_radius_m, com_height_m, altitude_m):
    """The centre of mass on the ray r_hat such that the lowest foot is ``altitude_m`` above the
    terrain under it (SPEC.md section 3), whatever the tilt and the slope."""
    rho = ground.radius_m + altitude_m + com_height_m
    for _ in range(MAX_PLACEMENT_ITERATIONS):
        alt = -lowest_foot_penetration(ground, vec.scale(r_hat, rho), quat, leg_radius_m,
                                       com_height_m)
        move = altitude_m - alt
        rho = rho + move
        if abs(move) <= 4.0 * 2.220446049250313e-16 * rho:
            break
    return vec.scale(r_hat, rho)


@entry
def _place_ships(terrain, radius_m, omega_radps, radial, starts, rows):
    """Every ship's pose and motion from its row of ``starts``: the landing-site directions at
    (east, north), the long axis tilted toward the heading and turned by yaw about itself, the
    lowest foot at the altitude, velocities along local up and the heading (relative to the
    surface), the body's spin added to the angular velocity. Written into ``rows`` (states)."""
    ground = Ground(radius_m, terrain[0], 1.0, 0.0, omega_radps, radial)
    for i in range(starts.shape[0]):
        st = starts[i]
        r_hat = vec.unit((radius_m, st[_EAST], st[_NORTH]))
        east = vec.unit(vec.cross((0.0, 0.0, 1.0), r_hat))
        north = vec.cross(r_hat, east)
        fwd = vec.add(vec.scale(north, st[_COS_HD]), vec.scale(east, st[_SIN_HD]))
        ez = vec.add(vec.scale(r_hat, st[_COS_TH]), vec.scale(fwd, st[_SIN_TH]))
        ex = vec.sub(vec.scale(fwd, st[_COS_TH]), vec.scale(r_hat, st[_SIN_TH]))
        ey = vec.cross(ez, ex)
        ex, ey = (vec.add(vec.scale(ex, st[_COS_YAW]), vec.scale(ey, st[_SIN_YAW])),
                  vec.sub(vec.scale(ey, st[_COS_YAW]), vec.scale(ex, st[_SIN_YAW])))
        quat = quat_from_axes(ex, ey, ez)
        pos = _place(ground, r_hat, quat, st[_LEG], st[_COM], st[_ALT])
        surf_v = (omega_radps * -pos[1], omega_radps * pos[0], 0.0)
        vel = vec.add(vec.add(surf_v, vec.scale(r_hat, st[_V_UP])), vec.scale(fwd, st[_V_FWD]))
        omega = vec.add((st[_W_X], st[_W_Y], st[_W_Z]),
                        vec.quat_rotate_inv(quat, (0.0, 0.0, omega_radps)))
        lowest = lowest_foot(ground, pos, quat, st[_LEG], st[_COM])[1]
        r = rows[i]
        for k in range(3):
            r.pos_m[k] = pos[k]
            r.vel_mps[k] = vel[k]
            r.omega_body_radps[k] = omega[k]
            r.pin_pos_bf_m[k] = pos[k]
            r.pin_pivot_bf_m[k] = lowest[k]
        for k in range(4):
            r.quat[k] = quat[k]
            r.pin_quat_bf[k] = quat[k]


def initial_state(params: Params, ships: list[dict]) -> State:
    """Every ship where its ``initial`` table puts it (:func:`_place_ships`; the angles' cosines
    and sines from sim.trig here, once). sim.vec keeps even the set-up elementwise IEEE
    arithmetic: a replay on another CPU rebuilds this state bit for bit."""
    sh = params.ships
    starts = np.empty((len(ships), 16))
    for i, s in enumerate(ships):
        ini = s["initial"]
        hd, th, yaw = (math.radians(ini[k]) for k in ("heading_deg", "tilt_deg", "yaw_deg"))
        starts[i] = (ini["east"], ini["north"], ini["altitude"], *trig.cos_sin(hd),
                     *trig.cos_sin(th), *trig.cos_sin(yaw),
                     sh.leg_radius_m[i], sh.com_height_m[i], ini["vertical_speed"],
                     ini["horizontal_speed"], *ini["angular_velocity"])
    st = State.zeros(len(ships))
    _place_ships(params.terrain, params.body.radius_m, params.body.omega_radps,
                 params.contact.surface_normal == SurfaceNormal.RADIAL, starts, st.rows)
    rows = st.rows
    rows["surface_state"] = [SurfaceState.from_label(s["initial"]["state"]) for s in ships]
    rows["mass_kg"], rows["fuel_kg"] = sh.mass0_kg, sh.fuel0_kg
    rows["absorbing"] = [s["initial"]["state"] != "flying"
                         and abs(s["initial"]["vertical_speed"]) < params.contact.bounce_speed_mps
                         for s in ships]
    return st


__all__ = ["initial_state", "quat_from_axes"]
