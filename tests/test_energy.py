"""Energy as a test (MODEL-NOTES 28): with no thrust and no RCS a ship's energy_j never rises by
more than rounding, in every state and through every transition, whatever the tilt, spin, speed,
heading, body rotation, terrain and tick; the telemetry's energy_j agrees with an independent
bookkeeping; and the passivity guard that catches integration error takes little.

energy_j is the rotating frame's Jacobi integral (sim.energy). Per tick it may rise by at most
ROUNDOFF: 1e-13 of the ship's gravitational energy scale m GM / R, the energy of lifting the ship
by 1e-13 of the body's radius (0.17 micrometres on the Moon): positions a planet's radius from
its centre are known to ~2e-10 m, and a pinned ship's pose is mapped into the turning frame
afresh each tick.

Hypothesis runs derandomized and without shrinking, so that CI runs the same examples in bounded
time."""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, example, given, settings
from hypothesis import strategies as st

from touchdown import scenarios
from touchdown.bench import physics as audit
from scenes import records, scene, tilt_deg
from touchdown.sim import measure
from touchdown.sim.dynamics import Motion
from touchdown.sim.enums import TRANSITION_EVENTS, SurfaceState
from touchdown.sim.run import run
from touchdown.sim.scenario import parse_text

ROUNDOFF_OF_GRAVITY = 1e-13


def energies(scn, recs) -> np.ndarray:
    """energy_j of every ship at every tick (ticks x ships), as export reports it."""
    p = scn.params
    ships = np.arange(scn.initial.n)
    return np.array([measure.energy(p, ships, r.tick * p.sim.dt_s,
                                    Motion(r.state.pos_m, r.state.vel_mps, r.state.quat,
                                           r.state.omega_body_radps),
                                    r.state.mass_kg)["total_j"]
                     for r in recs])


def roundoff_j(scn) -> np.ndarray:
    p = scn.params
    return ROUNDOFF_OF_GRAVITY * p.ships.mass0_kg * p.body.gm_m3ps2 / p.body.radius_m


@settings(max_examples=36, deadline=None, derandomize=True, database=None,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.too_slow])
@given(state=st.sampled_from(["flying", "contact"]), height=st.floats(0.0, 3.0),
       down=st.floats(0.0, 56.0), side=st.floats(0.0, 8.0), heading=st.floats(0.0, 360.0),
       yaw=st.floats(0.0, 90.0), tilt=st.floats(0.0, 100.0),
       spin=st.tuples(*[st.floats(-1.0, 1.0)] * 3), align=st.booleans(),
       rotation=st.sampled_from([0.0, 2360592.0, 7200.0]),
       bump=st.one_of(st.none(), st.tuples(st.floats(-2.0, 2.0), st.floats(10.0, 30.0),
                                           st.floats(-10.0, 10.0))),
       dt=st.sampled_from([0.02, 0.05, 0.1]))
# where the explicit kicks' error raised energy by up to 2.5e-4 of it in a tick (guard off):
# hard, tilted, spinning, sliding impacts that rock and topple, on a turning body over a bump
@example(state="flying", height=0.3, down=12.7, side=5.5, heading=79.5, yaw=0.0, tilt=51.4,
         spin=(-0.33, 0.42, -0.34), align=False, rotation=2360592.0, bump=(1.7, 15.0, -1.4),
         dt=0.02)
@example(state="flying", height=0.3, down=20.0, side=3.0, heading=10.0, yaw=30.0, tilt=35.0,
         spin=(0.4, -0.3, 0.5), align=False, rotation=0.0, bump=None, dt=0.05)
@example(state="contact", height=1.0, down=8.0, side=6.0, heading=200.0, yaw=45.0, tilt=30.0,
         spin=(0.5, 0.5, -0.8), align=False, rotation=7200.0, bump=(-1.5, 12.0, 3.0), dt=0.1)
def test_a_passive_ship_never_gains_energy(state, height, down, side, heading, yaw, tilt, spin,
                                           align, rotation, bump, dt):
    if state == "contact":
        tilt = min(tilt, 79.0)
    initial = {"state": state, "altitude": height if state == "flying" else -0.02 * height,
               "vertical_speed": -down, "horizontal_speed": side, "heading_deg": heading,
               "yaw_deg": yaw, "tilt_deg": tilt, "angular_velocity": list(spin)}
    body = {"rotation_period": rotation}
    if bump is not None:
        body["terrain"] = {"bumps": [{"east": bump[2], "north": 0.0, "radius": bump[1],
                                      "height": bump[0]}]}
    scn = scene(initial, body=body, contact={"align_on_touchdown": align}, sim={"dt": dt},
                duration=4.0)
    recs = records(scn)
    e = energies(scn, recs)[:, 0]
    allowed = {int(s) for s in SurfaceState}
    for rec in recs:
        assert np.isfinite(rec.state.pos_m).all() and np.isfinite(rec.state.vel_mps).all()
        assert np.isfinite(rec.state.quat).all() and int(rec.state.surface_state[0]) in allowed
        for ev in rec.events:
            assert (SurfaceState(ev.from_state), SurfaceState(ev.to_state)) in TRANSITION_EVENTS
    rise = np.diff(e)
    k = int(np.argmax(rise))
    assert rise[k] <= roundoff_j(scn)[0], (
        f"energy rose {rise[k]:.3g} J at tick {k + 1} ({SurfaceState(int(recs[k].state.surface_state[0])).label}"
        f" -> {SurfaceState(int(recs[k + 1].state.surface_state[0])).label})")


PASSIVE = ["bounce", "crash", "double-bounce", "earth", "slide", "soft-touchdown", "spinning-moon",
           "tilt-recover", "topple", "trip", "tumble-crash", "hills"]


@pytest.mark.parametrize("name", PASSIVE)
def test_the_passive_builtins_never_gain_energy_and_the_guard_takes_little(name):
    """The guard (sim.flight.passivity_guard) projects out integration error that would raise a
    passive ship's energy; over each built-in it takes less than 1e-3 of what the dampers, friction
    and transitions dissipate (the measured worst, tilt-recover, is 5e-4)."""
    scn = parse_text(scenarios.text(name), name)
    recs = list(run(scn))
    e = energies(scn, recs)
    assert np.max(np.diff(e, axis=0) - roundoff_j(scn)[None, :]) <= 0.0
    taken = np.sum([r.outputs.energy_guard_j for r in recs], axis=0)
    lost = e[0] - e[-1]
    assert np.all(taken <= 1e-3 * lost + roundoff_j(scn))


@pytest.mark.parametrize("name,ticks", [("topple", (60, 120, 160)), ("bounce", (5, 10, 300)),
                                        ("spinning-moon", (5, 40, 400)), ("hills", (20, 80))])
def test_energy_j_agrees_with_an_independent_bookkeeping(name, ticks):
    """bench.physics.energy computes the same definition its own way (a tipped ship's kinetic
    energy as I_p theta'^2 / 2 about the pivot, where sim.energy reads the velocities the
    telemetry reports): they agree, so a tipped ship's telemetry shows its real motion."""
    scn = parse_text(scenarios.text(name), name)
    recs = list(run(scn))
    e = energies(scn, recs)[:, 0]
    scale = abs(scn.params.body.gm_m3ps2 * scn.params.ships.mass0_kg[0] / scn.params.body.radius_m)
    for k in ticks:
        assert e[k] == pytest.approx(audit.energy(scn, recs[k]), abs=1e-12 * scale)
    if name == "topple":
        falling = [r for r in recs if r.state.surface_state[0] == SurfaceState.TIPPED
                   and np.linalg.norm(r.state.omega_body_radps[0]) > 0.1]
        assert falling and all(np.linalg.norm(r.state.vel_mps[0]) > 0.1 for r in falling)


@pytest.mark.parametrize("model", ["full", "pivot"])
def test_a_fall_onto_the_side_keeps_at_most_the_energy_it_had(model):
    """MODEL-NOTES 29: handed to the pivot model, a ship keeps of its motion the turn about the
    pivot (angular momentum about the foot conserved, the rest lost as in an impact). A
    frictionless 45 degree, 5 m/s touchdown had 15.8 kJ before and 36.9 kJ after in 0.2.0. The
    full model (MODEL-NOTES 48) hands nothing over: the same motion goes on."""
    for tilt, speed in ((45.0, 5.0), (30.0, 30.0), (60.0, 1.0)):
        scn = scene({"altitude": 1e-4, "vertical_speed": -speed, "tilt_deg": tilt},
                    contact={"align_on_touchdown": False, "friction_static": 0.0,
                             "friction_kinetic": 0.0, "tipped_model": model}, duration=6.0)
        recs = records(scn)
        k = next(i for i, r in enumerate(recs)
                 if any(e.to_state == SurfaceState.TIPPED for e in r.events))
        before = sum(audit.kinetic(scn, recs[k - 1].state))
        after = sum(audit.kinetic(scn, recs[k].state))
        if model == "pivot":  # the hand-over is an impact at the foot
            assert 0.0 < after <= before, (tilt, speed, before, after)
        e = energies(scn, recs)[:, 0]
        assert np.max(np.diff(e)) <= roundoff_j(scn)[0]


def test_the_pivot_model_conserves_energy_to_rounding():
    """A tipped ship falling from rest at 81 degrees and a righting-free fall: the discrete
    gradient keeps I_p theta'^2 / 2 + U exactly until the hull takes it (0.7's pivot model,
    ``contact.tipped_model = "pivot"``)."""
    scn = scene({"state": "tipped", "tilt_deg": 81.0, "heading_deg": 30.0},
                contact={"tipped_model": "pivot"}, duration=4.0)
    recs = records(scn)
    e = energies(scn, recs)[:, 0]
    resting = next(i for i, r in enumerate(recs) if r.state.pivot_rate_radps[0] == 0.0 and i > 0)
    assert resting > 5
    assert np.max(np.abs(e[:resting] - e[0])) <= 2 * roundoff_j(scn)[0]
    assert e[resting] < e[0] - 1000.0  # the hull's impact took the fall's kinetic energy


def test_a_tipped_ship_falls_onto_its_hull_by_the_full_model_and_rests_there():
    """The full model (MODEL-NOTES 48): a tipped ship at rest at 81 degrees falls on its feet as any
    ship in contact, its energy never rising, until its hull meets the ground at tipped_rest
    (90 degrees), where it rests, pinned, its motion that of the ground; no event (it was tipped
    all along)."""
    scn = scene({"state": "tipped", "tilt_deg": 81.0, "heading_deg": 30.0}, duration=4.0)
    recs = records(scn)
    assert not [e for r in recs for e in r.events]
    e = energies(scn, recs)[:, 0]
    assert np.max(np.diff(e)) <= roundoff_j(scn)[0]
    tilts = tilt_deg(recs)
    resting = next(i for i, r in enumerate(recs) if i > 0
                   and np.linalg.norm(r.state.omega_body_radps[0]) == 0.0)
    assert 5 < resting < len(recs) - 5
    assert tilts[resting] == pytest.approx(90.0, abs=1.0)
    assert np.all(tilts[resting:] == tilts[resting])
    assert e[resting] < e[0] - 1000.0  # the hull's impact took the fall's kinetic energy


def test_export_energy_on_a_spinning_body_includes_its_frame():
    """On spinning-moon the landed ship is carried round at 350 m/s; its energy_j (relative to
    the turning frame, with the frame's centrifugal potential) stays constant."""
    scn = parse_text(scenarios.text("spinning-moon"), "spinning-moon")
    recs = list(run(scn))
    e = energies(scn, recs)[:, 0]
    landed = [i for i, r in enumerate(recs) if r.state.surface_state[0] == SurfaceState.LANDED]
    assert landed and np.max(np.abs(e[landed] - e[landed[0]])) <= roundoff_j(scn)[0]
    assert math.isclose(np.linalg.norm(recs[-1].state.vel_mps[0]),
                        2 * math.pi / 3600.0 * np.hypot(*recs[-1].state.pos_m[0][:2]), rel_tol=1e-9)


def test_a_wide_ship_rights_itself_without_gaining_energy():
    """MODEL-NOTES 13: past tipped_angle (80) but short of its own critical tilt (84.3 degrees), a
    squat, wide ship rights itself with no RCS: contact -> tipped -> contact, energy never rising
    through either hand-over."""
    scn = scene({"altitude": 0.01, "vertical_speed": -0.5, "tilt_deg": 81.0},
                contact={"align_on_touchdown": False}, ship={"com_height": 1.0, "leg_radius": 10.0},
                duration=20.0)
    recs = records(scn)
    names = [e.kind for r in recs for e in r.events]
    from touchdown.sim.enums import EventKind
    assert EventKind.TIPPED in names and EventKind.RIGHTED in names
    assert np.max(np.diff(energies(scn, recs)[:, 0])) <= roundoff_j(scn)[0]


def test_the_hand_over_to_the_pivot_keeps_the_turn_about_it_and_loses_the_rest():
    """sim.pivot.rate_from_momentum: a motion that is already a turn about the pivot's axis
    keeps its rate; any other loses exactly its part orthogonal to that turn in the kinetic-energy
    metric (KE = KE(kept) + KE(lost)), as an inelastic impact at the foot does."""
    from scipy.spatial.transform import Rotation

    from touchdown.sim.pivot import pivot_axis, rate_from_momentum
    scn = scene({"state": "contact", "altitude": -0.01, "tilt_deg": 60.0, "heading_deg": 20.0})
    st, par = scn.initial, scn.params
    m, i_b = st.mass_kg, par.ships.inertia0_kgm2
    p, q = st.pos_m, st.quat
    pivot = st.pin_pivot_bf_m
    a = np.array([pivot_axis(tuple(p[0]), tuple(q[0]))])
    d = p - pivot
    rot = Rotation.from_quat(np.roll(q[0], -1))

    def kinetic(v, w_w):
        w_b = rot.inv().apply(w_w)
        return 0.5 * m[0] * float(v @ v) + 0.5 * float(w_b @ (i_b[0] * w_b))

    def rate_of(v, w_w):
        motion = Motion(tuple(p[0]), tuple(v), tuple(q[0]), tuple(rot.inv().apply(w_w)))
        return rate_from_momentum(par.body.omega_radps, float(m[0]), tuple(i_b[0]), motion,
                                  tuple(pivot[0]))

    w_turn = 0.37 * a[0]
    v_turn = np.cross(w_turn, d[0])
    rate = rate_of(v_turn, w_turn)
    assert rate == pytest.approx(0.37, rel=1e-12)
    rng = np.random.default_rng(7)
    for _ in range(5):
        v, w_w = rng.normal(size=3), 0.3 * rng.normal(size=3)
        rate = float(rate_of(v, w_w))
        kept_w = rate * a[0]
        kept_v = np.cross(kept_w, d[0])
        before, kept = kinetic(v, w_w), kinetic(kept_v, kept_w)
        lost = kinetic(v - kept_v, w_w - kept_w)
        assert kept <= before and kept + lost == pytest.approx(before, rel=1e-12)
