"""Physics off the well-walked paths, scene by scene, each against an independent reference or
a law: a slide on a turning body (a solve_ivp with Coriolis and centrifugal terms), a ship held on
one, a spin about the long axis in contact, a frictionless hill (energy), a start on a slope, an
impossible start, a liftoff where the body's spin lightens the ship, a ship on one point, and the
critical tilt toward an edge. The numbers in the docstrings are what 0.2.0 did
(``touchdown bench physics`` measures both)."""
import math

import numpy as np
import pytest
from click.testing import CliRunner

from touchdown.bench.reference import rotating_slide
from touchdown.cli import main
from scenes import events, long_axis, records, scene, series, tilt_deg, topics
from touchdown.sim.enums import SurfaceState
from touchdown.sim.measure import site_frame
from touchdown.sim.scenario import ScenarioError

SPINNER = {"name": "Spinner", "radius": 200000.0, "surface_gravity": 1.0,
           "rotation_period": 3600.0}
OMEGA = 2.0 * math.pi / 3600.0
G_EFF = 1.0 - OMEGA ** 2 * 200000.0  # 0.39 m/s^2 on spinning-moon's equator
MOON_G = 1.6248


def footprint_site(scn, rec, com_height):
    """(east, north) of the feet's centre in the landing-site frame."""
    centre = rec.state.pos_m - com_height * long_axis(rec.state.quat)
    pos, _ = site_frame(scn.params, centre, rec.state.vel_mps, rec.tick * scn.params.sim.dt_s)
    return pos[0, :2]


@pytest.mark.parametrize("heading", [90.0, 270.0, 0.0])
def test_a_slide_on_a_turning_body_stops_where_the_rotating_frame_says(heading):
    """A squat ship (centre of mass 0.5 m up: friction hardly rocks it) sliding at 4 m/s on
    spinning-moon, 20 km north of the equator: the Coriolis force lightens it heading east and
    presses it heading west (2 Omega v is 7% of g_eff there) and turns its path, the frame's
    centrifugal pull draws it toward the equator. Where its feet stop, against
    bench.reference.rotating_slide (a point on the turning sphere, DOP853): within 5 cm over
    30-45 m. (In 0.2.0 friction's lever arm mixed two instants 8 m apart on this body.)"""
    h = 0.5
    scn = scene({"state": "contact", "altitude": -G_EFF / 100.0, "north": 20000.0,
                 "horizontal_speed": 4.0, "heading_deg": heading}, ship={"com_height": h},
                body=SPINNER, contact={"settle_linear_vel": 1e-3}, duration=40.0)
    recs = records(scn)
    p0 = recs[0].state.pos_m[0]
    v0 = recs[0].state.vel_mps[0] - OMEGA * np.array([-p0[1], p0[0], 0.0])
    end, t_stop = rotating_slide(1.0 * 200000.0 ** 2, float(np.linalg.norm(p0)), OMEGA, p0, v0,
                                 0.5)
    assert 15.0 < t_stop < 30.0
    expected = np.array([end[1], end[2]]) * (200000.0 / np.linalg.norm(end))  # feet under it
    start = footprint_site(scn, recs[0], h)
    assert 30.0 < np.linalg.norm(expected - start) < 45.0
    assert np.linalg.norm(footprint_site(scn, recs[-1], h) - expected) < 0.05


@pytest.mark.parametrize("north", [0.0, 20000.0])
def test_a_ship_held_on_a_turning_body_does_not_creep(north):
    """Static friction holds a ship on spinning-moon (at 20 km from the equator against the
    frame's centrifugal pull along the ground, 6% of g): over a minute its feet move along the
    ground by less than a micrometre. (0.2.0: 2.5 mm an hour at the equator.)"""
    scn = scene({"state": "contact", "altitude": -G_EFF / 100.0, "north": north},
                body=SPINNER, contact={"settle_time": 1e4}, duration=60.0)
    recs = records(scn)
    a = footprint_site(scn, recs[10], 3.0)
    b = footprint_site(scn, recs[-1], 3.0)
    assert np.linalg.norm(b - a) < 1e-6
    assert not recs[-1].state.sliding[0].any()


def test_four_feet_stop_a_spin_about_the_long_axis():
    """A spin in contact (in 0.2.0 a 0.05 rad/s one lasted for ever: friction acted at one point).
    Four feet at leg_radius a, each mu_k m g / 4 against its slip, brake it at mu_k m g a / I_z:
    linearly to zero, and then the ship lands."""
    scn = scene({"state": "contact", "altitude": -MOON_G / 100.0,
                 "angular_velocity": [0.0, 0.0, 0.5]}, duration=3.0)
    recs = records(scn)
    i_z = scn.params.ships.inertia0_kgm2[0][2]
    g = 4.9048695e12 / float(np.linalg.norm(recs[0].state.pos_m[0])) ** 2
    decel = 0.5 * 10000.0 * g * 2.26 / i_z  # 0.72 rad/s^2
    spin = np.array([r.state.omega_body_radps[0][2] for r in recs])
    t_stop = 0.5 / decel
    for k in range(1, int(t_stop / 0.05)):  # while the feet slide
        assert spin[k] == pytest.approx(0.5 - decel * k * 0.05, rel=0.01, abs=1e-3)
    assert np.all(np.abs(spin[int(math.ceil(t_stop / 0.05)) + 1:]) < 1e-9)
    assert "ship.landed" in topics(recs)
    slow = records(scene({"state": "contact", "altitude": -MOON_G / 100.0,
                          "angular_velocity": [0.0, 0.0, 0.05]}, duration=2.0))
    assert "ship.landed" in topics(slow)


def hill_slide(normal: str, guard: bool = True):
    bump = {"terrain": {"bumps": [{"east": 20.0, "north": 0.0, "radius": 15.0, "height": 2.0}]}}
    scn = scene({"state": "contact", "altitude": -MOON_G / 100.0, "horizontal_speed": 5.0,
                 "heading_deg": 90.0}, body=bump,
                contact={"friction_static": 0.0, "friction_kinetic": 0.0, "surface_normal": normal},
                sim={"energy_guard": guard}, duration=8.0)
    recs = records(scn)
    top = min(recs, key=lambda r: abs(footprint_site(scn, r, 3.0)[0] - 20.0))
    return scn, recs, top


def test_a_frictionless_ship_slows_over_a_hill_as_energy_says():
    """The ground pushes each foot along the terrain's normal: climbing ~1.9 m, a frictionless
    5 m/s slide is at sqrt(v0^2 - 2 g H) = 4.3 m/s at the top (less the dampers' small share),
    and the passivity guard takes less than 1e-3 of its kinetic energy. The seed's radial normal (contact.surface_normal
    = "radial", with sim.energy_guard = false) cannot slow it: it crosses the top at 5.0 m/s,
    tens of kJ richer, as 0.2.0 did; with the guard on, the guard takes that energy back out
    and says so in energy_guard_j."""
    scn, recs, top = hill_slide("terrain")
    assert sum(float(r.outputs.energy_guard_j[0]) for r in recs) < 1e-3 * 0.5 * 1e4 * 25.0
    v_top = float(np.linalg.norm(top.state.vel_mps[0]))
    rise = float(np.linalg.norm(top.state.pos_m[0]) - np.linalg.norm(recs[0].state.pos_m[0]))
    assert 1.85 < rise < 2.0  # the feet straddle the top, 2.26 m from it
    v_energy = math.sqrt(25.0 - 2.0 * MOON_G * rise)
    assert v_energy * 0.99 < v_top <= v_energy * 1.001
    _, seed_recs, top_seed = hill_slide("radial", guard=False)
    assert float(np.linalg.norm(top_seed.state.vel_mps[0])) == pytest.approx(5.0, rel=0.01)
    _, guarded, _ = hill_slide("radial")
    assert sum(float(r.outputs.energy_guard_j[0]) for r in guarded) > 2e4


@pytest.mark.parametrize("tilt,heading", [(0.0, 0.0), (20.0, 90.0), (20.0, 270.0), (10.0, 45.0)])
def test_a_ship_placed_on_a_slope_stands_on_its_lowest_foot(tilt, heading):
    """SPEC.md: altitude is the lowest foot's height above the terrain under it. On a 2 m bump's
    side, 7 m from its top (slope 18 degrees), tilted or not: the lowest foot starts exactly at
    the altitude asked, no foot below the ground. (0.2.0 measured under the centre of mass: the
    uphill foot started 2.6 m inside the hill and was thrown out.)"""
    bump = {"terrain": {"bumps": [{"east": 0.0, "north": 0.0, "radius": 15.0, "height": 2.0}]}}
    for state, altitude in (("flying", 0.5), ("contact", -0.01)):
        scn = scene({"state": state, "altitude": altitude, "east": 7.0, "tilt_deg": tilt,
                     "heading_deg": heading}, body=bump, duration=0.05)
        rec = records(scn)[0]
        assert rec.outputs.altitude_m[0] == pytest.approx(altitude, abs=1e-9)


@pytest.mark.parametrize("sets,key", [
    (["ships[0].initial.altitude=-20"], "ships[0].initial.altitude"),
    (["ships[0].initial.state='contact'", "ships[0].initial.altitude=-20"],
     "ships[0].initial.altitude"),
    (["ships[0].initial.state='landed'", "ships[0].initial.altitude=5"],
     "ships[0].initial.altitude"),
    (["ships[0].initial.state='landed'", "ships[0].initial.altitude=0",
      "ships[0].initial.vertical_speed=0", "ships[0].initial.angular_velocity=[0, 1, 0]"],
     "ships[0].initial.angular_velocity"),
    (["body.rotation_period=600"], "body.rotation_period"),
])
def test_impossible_starts_are_refused_naming_the_key(tmp_path, sets, key):
    """A start physics cannot be in is refused, exit 2, one line naming the key (0.2.0 launched
    a ship at altitude -20 at 134 m/s and let a landed ship hover at +5 m); a body spinning so
    fast that its equator flings ships off is refused too."""
    args = ["record", "bounce", "-o", str(tmp_path / "x.mcap")]
    for s in sets:
        args += ["--set", s]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, r.output
    assert key in r.output and r.output.count("\n") == 1
    assert not list(tmp_path.iterdir())


def test_a_start_in_the_ground_comes_out_no_faster_than_an_impact_went_in():
    """The deepest start allowed is what an impact at crash_speed can press the feet to,
    crash_speed / sqrt(stiffness_per_kg) = 5 m; from there (or from 4.9 m, upright, at rest) the
    springs give back at most crash_speed."""
    with pytest.raises(ScenarioError):
        scene({"state": "contact", "altitude": -5.01})
    recs = records(scene({"state": "contact", "altitude": -4.9}, duration=3.0))
    fastest = max(float(r.outputs.v_radial_mps[0]) for r in recs)
    assert 0.0 < fastest < 50.0


@pytest.mark.parametrize("ratio,lifts", [(0.99, False), (1.01, True)])
@pytest.mark.parametrize("state", ["landed", "contact"])
def test_liftoff_weighs_the_ship_in_the_turning_frame(ratio, lifts, state):
    """On spinning-moon's equator a 10 t ship weighs m g_eff = 3.9 kN, not m g = 10 kN: thrust
    just above that lifts it, just below does not, landed or in contact. (0.2.0 kept it landed
    at 9 kN.)"""
    thrust = ratio * 10000.0 * G_EFF
    scn = scene({"state": state, "altitude": 0.0 if state == "landed" else -G_EFF / 100.0},
                ship={"max_thrust": thrust, "fuel_mass": 100.0}, body=SPINNER,
                inputs=[{"t": 0.0, "throttle": 1.0}], duration=4.0)
    recs = records(scn)
    assert ("ship.liftoff" in topics(recs)) == lifts
    if not lifts:
        assert series(recs, "v_radial_mps").max() < 0.5


def test_a_ship_on_one_point_is_the_seeds_inverted_pendulum():
    """leg_radius = 0 puts the four feet at one point under the centre of mass: nothing is over
    the footprint, so no tilt is stable and the ship never lands; tilted 1 degree it falls over
    (0.2.0 landed it at 0.55 s). It falls as I_p theta'' = m g h sin theta says."""
    recs = records(scene({"state": "contact", "altitude": -MOON_G / 100.0, "tilt_deg": 1.0},
                         ship={"leg_radius": 0.0}, duration=20.0))
    assert "ship.landed" not in topics(recs)
    tipped = [t for t, name, _ in events(recs) if name == "ship.tipped"]
    assert tipped
    from scipy.integrate import solve_ivp
    m, h = 10000.0, 3.0
    i_t = m * (3 * 0.5 ** 2 + (2 * h) ** 2) / 12.0  # the default cylinder's radius is at least 0.5
    i_p = i_t + m * h * h

    def rhs(t, y):
        return [y[1], m * MOON_G * h * math.sin(y[0]) / i_p]

    reach = lambda t, y: y[0] - math.radians(80.0)  # noqa: E731
    reach.terminal, reach.direction = True, 1
    ref = solve_ivp(rhs, (0.0, 100.0), [math.radians(1.0), 0.0], events=[reach], method="DOP853",
                    rtol=1e-11, atol=1e-12).t_events[0][0]
    assert abs(tipped[0] * 0.05 - ref) < 0.05 + 0.02 * ref


@pytest.mark.parametrize("side,falls", [(-0.5, False), (0.5, True)])
def test_the_critical_tilt_toward_an_edge_is_atan_a_over_sqrt2_h(side, falls):
    """Toward the edge between two feet (yaw 45 degrees) the footprint's rim is a / sqrt(2) from
    its centre: the critical tilt is atan(a / (sqrt(2) h)) = 28.0 degrees for the default lander,
    not the 37.0 degrees toward a foot."""
    crit = math.degrees(math.atan2(2.26, math.sqrt(2.0) * 3.0))
    recs = records(scene({"state": "contact", "altitude": -MOON_G / 100.0,
                          "tilt_deg": crit + side, "yaw_deg": 45.0}, duration=30.0))
    assert ("ship.tipped" in topics(recs)) == falls
    if not falls:
        assert SurfaceState(int(recs[-1].state.surface_state[0])) is SurfaceState.LANDED
        assert tilt_deg(recs)[-1] < 5.0


@pytest.mark.parametrize("ratio,refused", [(0.99, False), (1.01, True)])
def test_a_body_that_spins_its_ships_off_is_refused(ratio, refused):
    """Omega^2 R against GM / R^2 at the equator: a body turning just slower than that holds a
    ship (barely: g_eff is 1% of g), just faster flings it off and is refused naming the key."""
    radius, g = 200000.0, 1.0
    period = 2.0 * math.pi / math.sqrt(ratio * g / radius)
    body = {"radius": radius, "surface_gravity": g, "rotation_period": period}
    if refused:
        with pytest.raises(ScenarioError, match="body.rotation_period"):
            scene({"state": "landed"}, body=body)
    else:
        assert scene({"state": "landed"}, body=body).params.body.rotation_period_s == period
