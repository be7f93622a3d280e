"""Touchdown against the 3-D four-foot reference (bench.reference3d, checked in
tests/test_reference3d.py): issue 35's scenes, and hypothesis over 3-D starts (tilt and its azimuth
against the legs, sideways speed and its direction, yaw spin, slope and its azimuth, mass, legs,
tick). Each scene is described once (bench.edges3d.Scene) and run by both; the measures read both
runs the same way."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings, strategies as st

from touchdown.bench import edges3d as E
from touchdown.bench import starts3d as S


def _ref(sc):
    return E.run_reference(sc)


def SLOW(dt):  # noqa: N802 - the default tick (0.05 s) is the fast part's; the others the whole suite's
    return pytest.param(dt, marks=pytest.mark.slow)


@pytest.mark.parametrize("dt", [SLOW(0.1), 0.05, SLOW(0.005)])
def test_a_ship_turning_over_an_edge_is_not_pinned(dt):
    """Item 1: the default lander standing square on a 27 degree slope, an edge downhill (1.04
    degrees under the static edge limit): its soft legs load the downhill feet as it turns, it
    has no barrier left over that edge, and it tips where the reference does (11.83 s), to 0.3%
    at every tick (0.7 landed it at 1.0 s, pinned, at every tick; until its uphill feet's
    release kept their pull, MODEL-NOTES 52, it tipped at 11.72 s at dt 0.1 to 0.02)."""
    ref = _ref(E.EDGE_ON_SLOPE)
    sim = E.run_sim(E.EDGE_ON_SLOPE, dt)
    assert E.outcome(ref) == E.outcome(sim) == "tipped"
    assert sim.landed_t_s is None
    assert E.tip_instant(sim) == pytest.approx(E.tip_instant(ref), rel=0.003)


@pytest.mark.parametrize("dt", [SLOW(0.1), 0.05])
def test_a_slide_just_steeper_than_atan_mu_s_slides_as_kinetic_friction_says(dt):
    """Item 2: a squat ship on a 39.3 degree slope (atan(mu_s) = 38.66) slides the reference's
    5.536 m in 6 s, to 1% (0.7: 4.99 m, its feet keeping mu_s below 1 cm/s for 0.43 s)."""
    ref, sim = _ref(E.SLIDE_39), E.run_sim(E.SLIDE_39, dt)
    assert E.distance_m(sim) == pytest.approx(E.distance_m(ref), rel=0.01)


@pytest.mark.parametrize("scene", [E.EDGE_24, E.EDGE_27, E.SPIN_TOUCHDOWN],
                         ids=lambda sc: sc.name)
@pytest.mark.parametrize("dt", [SLOW(0.1), 0.05])
def test_the_landing_instant_is_the_references_to_0_3_percent(scene, dt):
    """Item 3: 2 m/s touchdowns tilted 24 and 27 degrees toward an edge, and one spinning at
    1 rad/s: landed where the reference's thresholds have held settle_time in continuous time, to
    0.3% (0.7 at dt 0.1: +0.3%, +0.2% and +12.6%)."""
    ref, sim = _ref(scene), E.run_sim(scene, dt)
    assert sim.landed_t_s == pytest.approx(E.landing(ref), rel=0.003)


@pytest.mark.parametrize("dt", [SLOW(0.1), 0.05])
def test_landed_is_a_state_of_rest_not_glue(dt):
    """Item 4: a ship landed on a 35 degree slope given 30% of its weight in thrust is in contact
    again and slides the reference's 7.42 m in 6 s (to 1%); one landed on level ground given 40 kN m
    about an edge tips at the reference's instant (to 1%). 0.7 kept both pinned; contact.landed =
    "attached" still does."""
    ref, sim = _ref(E.LANDED_THRUST), E.run_sim(E.LANDED_THRUST, dt)
    assert E.outcome(sim) == "contact" and sim.first("contact") == 0.0
    assert E.distance_m(sim) == pytest.approx(E.distance_m(ref), rel=0.01)
    ref, sim = _ref(E.LANDED_TORQUE), E.run_sim(E.LANDED_TORQUE, dt)
    assert E.tip_instant(sim) == pytest.approx(E.tip_instant(ref), rel=0.01)
    glued = E.run_sim(E.LANDED_TORQUE, dt, contact={"landed": "attached"})
    assert E.outcome(glued) == "landed" and E.distance_m(glued) == 0.0


@pytest.mark.parametrize("dt", [SLOW(0.1), 0.05, SLOW(0.005)])
def test_a_tipped_ship_answers_every_torque(dt):
    """Item 5: tipped at 85 degrees toward a foot, 80 kN m at (cos 30, sin 30, 0) of body (x, y)
    until 1.5 s: back under 80 degrees at the reference's instant and rate, to 1%, spinning about
    the vertical as it does, and turning as low after (to a degree); with the torque in the foot's
    plane too. (0.7's pivot model: 1.142 s against 0.9265, no spin, 68 degrees against 46.)"""
    ref, sim = _ref(E.TIPPED_RCS), E.run_sim(E.TIPPED_RCS, dt)
    (t_ref, rate_ref), (t_sim, rate_sim) = E.righting(ref), E.righting(sim)
    assert t_sim == pytest.approx(t_ref, rel=0.01)
    if dt <= 0.05:  # the rate at the instant, from the tick's state: a tick of 0.1 s is coarse
        assert rate_sim == pytest.approx(rate_ref, rel=0.01)
    spin = lambda tr: E.at(tr, E.yaw_rate_up(tr), 1.0)  # noqa: E731
    assert spin(sim) == pytest.approx(spin(ref), rel=0.01)
    assert E.lowest_after_righting(sim) == pytest.approx(E.lowest_after_righting(ref), abs=1.0)
    ref, sim = _ref(E.TIPPED_RCS_PLANE), E.run_sim(E.TIPPED_RCS_PLANE, dt)
    assert E.righting(sim)[0] == pytest.approx(E.righting(ref)[0], rel=0.01)


@pytest.mark.parametrize("dt", [SLOW(0.1), 0.05, SLOW(0.005)])
def test_sticking_transitions_are_the_references(dt):
    """Items 6 and 7: a spinning, tilted, sliding touchdown keeps the reference's spin once its
    feet stop slipping (0.2 and 1 s, to 1%; 0.7: +30%); a slow skid toward an edge rocks to the
    reference's peak tilt (to 1%; 0.7: +2.8% at dt 0.1, +5.4% at 0.05)."""
    ref, sim = _ref(E.SPIN_SLIDE), E.run_sim(E.SPIN_SLIDE, dt)
    for t in (0.2, 1.0):
        assert E.at(sim, E.yaw_rate_up(sim), t) == pytest.approx(E.at(ref, E.yaw_rate_up(ref), t),
                                                                 rel=0.01)
    ref, sim = _ref(E.SKID_EDGE), E.run_sim(E.SKID_EDGE, dt)
    assert E.peak_tilt(sim) == pytest.approx(E.peak_tilt(ref), rel=0.01)


@pytest.mark.parametrize("dt", [SLOW(0.1), 0.05, SLOW(0.005)])
def test_a_ship_that_lands_while_it_rocks_rests_where_the_rock_ends(dt):
    """Item 6's spinning slide lands at 6.59 s still rocking by 0.05 deg (its angular speed under
    the seed's 0.01 rad/s). Pinned where it settled it kept the rock's 3 mm at its centre of mass
    (east 0.1654 m at the end against the reference's 0.1691, -2.2%, at every tick) and its tilt;
    landed at the rest pose (MODEL-NOTES 55) it ends where the reference's rock ends: east to 1%,
    north and yaw to 1%, level to 0.01 deg."""
    ref, sim = _ref(E.SPIN_SLIDE), E.run_sim(E.SPIN_SLIDE, dt)
    assert sim.landed_t_s is not None
    end_ref, end_sim = E.horizontal_m(ref)[-1], E.horizontal_m(sim)[-1]
    assert end_sim[0] == pytest.approx(end_ref[0], rel=0.01)
    assert end_sim[1] == pytest.approx(end_ref[1], rel=0.01)
    assert E.yaw_deg(sim)[-1] == pytest.approx(E.yaw_deg(ref)[-1], rel=0.01)
    assert E.tilt_deg(ref)[-1] < 0.01
    assert E.tilt_deg(sim)[-1] < 0.01


@pytest.mark.parametrize("scene", [E.EDGE_20_24, E.EDGE_20_285, E.COMBINED],
                         ids=lambda sc: sc.name)
def test_fast_touchdowns_around_the_edge_limit(scene):
    """Item 8: 20 m/s touchdowns tilted 24 and 28.5 degrees toward an edge, and the 10 degree one
    with 2 m/s sideways out of the tilt plane: each bounces, tumbles in its flight and comes down
    lying on its side (tipped at its second touchdown) as the reference does; its tilt 1 s after
    the impact within 1% of the reference's, at the default tick."""
    ref, sim = _ref(scene), E.run_sim(scene, 0.05)
    assert E.outcome(sim) == E.outcome(ref) == "tipped"
    assert E.at(sim, E.tilt_deg(sim), 1.0) == pytest.approx(E.at(ref, E.tilt_deg(ref), 1.0),
                                                            rel=0.01)
    assert E.tip_instant(sim) == pytest.approx(E.tip_instant(ref), rel=0.01)


# -- hypothesis over 3-D starts ----------------------------------------------------------------
STARTS = dict(tilt=st.one_of(st.just(0.0), st.floats(0.5, 14.0)), heading=st.floats(0.0, 360.0),
              yaw=st.floats(0.0, 90.0), v_down=st.floats(1.0, 8.0), side=st.floats(0.0, 3.0),
              side_heading=st.floats(0.0, 360.0), spin=st.floats(-0.5, 0.5),
              mass=st.floats(5e3, 2e4), com=st.floats(1.5, 3.5), leg=st.floats(1.8, 3.0),
              slope=st.one_of(st.just(0.0), st.floats(0.0, 20.0)),
              azimuth=st.floats(0.0, 360.0))


@pytest.mark.slow
@settings(max_examples=8, deadline=None, derandomize=True, database=None,
          phases=[Phase.explicit, Phase.generate], suppress_health_check=[HealthCheck.too_slow])
@given(dt=st.sampled_from([0.1, 0.05, 0.02]), **STARTS)
def test_3d_touchdowns_end_as_the_reference_says_at_every_tick(dt, tilt, heading, yaw, v_down,
                                                               side, side_heading, spin, mass,
                                                               com, leg, slope, azimuth):
    """Over 3-D starts and ticks, the first 3 s end as the reference's do: tipped over or not,
    lifted off or not. (Starts whose tilt in the reference comes within 3 degrees of the edge
    limit, atan(a / (sqrt(2) h)), or that are still turning toward it at the end, are left out:
    there the outcome depends on where the ship is at 3 s, not on what it does.)"""
    sc = S.scene(tilt, heading, yaw, v_down, side, side_heading, spin, mass, com, leg, slope,
                azimuth)
    ref = _ref(sc)
    til = E.tilt_deg(ref)
    limit = S.edge_limit_deg(com, leg)
    assume(ref.first("tipped") is not None or abs(float(til.max()) - limit) > 3.0)
    assume(ref.first("tipped") is not None or til[-1] < til.max() - 0.5 or til.max() < 5.0)
    sim = E.run_sim(sc, dt)
    assert (sim.first("tipped") is not None) == (ref.first("tipped") is not None)
    assert (sim.first("liftoff") is not None) == (ref.first("liftoff") is not None)


#: A start that ends 1.7% short of the reference's slide (below).
SHORT_SLIDE_ON_13_DEG = dict(tilt=5.755882564999277, heading=0.0, yaw=48.772109190106356,
                             v_down=7.5908550034997315, side=0.4952026720146344,
                             side_heading=190.9352466715881, spin=-0.2, mass=17228.783948533557,
                             com=1.8017826459585167, leg=2.97999065875626,
                             slope=12.971227311254891, azimuth=119.07216668469069)


#: What the 3-D reference does with each of the 200 starts of bench.starts3d's sample of seed 35
#: (bench.starts3d.reference_table; written by ``python tests/test_edges3d.py``): the reference
#: takes 0.4 s a start and the simulation 0.01, so the sweep below reads it, and the test after
#: it runs the reference again on a tenth of the starts each run
REFERENCE_TABLE = Path(__file__).parent / "data" / "starts3d-seed35-reference.json"
SEED, STARTS = 35, 200


def _reference_table() -> list:
    doc = json.loads(REFERENCE_TABLE.read_text())
    assert (doc["seed"], doc["starts"]) == (SEED, STARTS)
    return [S.Reached(bool(r[0]), r[1], (r[2], r[3])) for r in doc["rows"]]


@pytest.mark.slow
def test_3d_touchdowns_follow_the_reference_at_the_default_tick():
    """Over the 142 3-D starts in the test's scope of 200 (tilt and its azimuth against the legs,
    sideways speed and its direction, yaw spin, slope and its azimuth, mass, legs; a seeded
    sample), at the default settings (tick 0.05 s, 25 ms sub-steps, 5 ms while it strikes, 1 ms
    pieces where a sliding foot's friction is stiff), a ship that stands rocks to the
    reference's largest tilt and ends where it went, to issue 35's 1% (0.1 degree, 1 cm). Until
    a stopping foot's drag turned with its slip in an impact (MODEL-NOTES 51) and an absorbed
    foot's release kept its pull (52), two of the first 24 missed 1% (impacts onto 12-14 degree
    slopes, 1.5-3% off); of the first 55 one more did: a 2.2 m/s touchdown onto 14.1 degrees slides
    2.2 cm (1.8%) further than the reference's 1.211 m, an error of the 25 ms sub-steps where
    two more feet strike the ground 0.75 s after touchdown (docs/issue35/tools/
    restart_release.py; 5 ms sub-steps end 0.1 cm off); those strikes now get the impact's
    5 ms sub-steps (MODEL-NOTES 53, the test below). Of the 142, two more missed until the
    feet at their stick/slip transition beside a stiff foot were resolved (MODEL-NOTES 58): start
    118, 0.30 m short of 1.338 m (a foot's breakaway held by a stiff foot's impulse), and 48,
    1.8 cm off of 0.805 m (a slip passing its least short of zero, dragged along where it
    slid). The reference's runs are its table's (REFERENCE_TABLE, checked below)."""
    checked, misses = 0, []
    for start, known in zip(S.sampled_starts(SEED, STARTS), _reference_table(), strict=True):
        verdict = S.follows(start, known=known)
        if verdict is None:
            continue
        checked += 1
        if verdict:
            misses.append(verdict)
    assert checked == 142
    assert not misses, "\n".join(misses)


@pytest.mark.slow
def test_the_samples_reference_table_is_what_the_reference_does_now():
    """Every tenth start of the table (twenty: 5, 15, ..., 195; 14 of them in scope) run by the
    reference as it is now: in scope or not as
    the table has it, its largest tilt and its end point to a micrometre (the table was written
    on another machine, by another scipy perhaps: LSODA's path may differ in its last bits, not
    more). A change to the reference (its law, its method, the scenes) fails here until the
    table is written again (``python tests/test_edges3d.py``)."""
    table = _reference_table()
    starts = list(S.sampled_starts(SEED, STARTS))
    for k in range(5, STARTS, 10):
        now = S.reached(starts[k], E.run_reference(S.scene(**starts[k])))
        was = table[k]
        where = f"start {k}: table {was}, reference now {now}"
        assert now.in_scope == was.in_scope, where
        assert now.peak_deg == pytest.approx(was.peak_deg, abs=1e-6), where
        assert np.subtract(now.end_m, was.end_m) == pytest.approx((0.0, 0.0), abs=1e-6), where


@pytest.mark.slow
def test_a_sliding_impact_on_a_13_degree_slope_ends_where_the_reference_does():
    """Tilted 5.8 degrees, 7.6 m/s down with 0.5 m/s sideways onto a 13 degree slope: it slides
    2.147 m in 3 s in the reference (converged in its regularisation: 2.147 to 2.148 m for eps
    1e-5 to 1e-8, LSODA and Radau agreeing), 2.148 m at the default settings. A foot coming to a
    stop under the impact's load is stepped with its drag against its slip until the last
    stretch before its stop (MODEL-NOTES 51); its drag frozen along where it slid from 5 ms
    before its stop ended 3.7 cm (1.7%) short: a foot whose slip passes zero at 19 mm/s was held,
    and at 1 ms impact sub-steps another, caught by static friction, was missed (10 cm long)."""
    assert S.follows(SHORT_SLIDE_ON_13_DEG) == ""


#: Start 64 of a wider sample (session 37's `touchdown bench starts3d` campaign), inside this
#: file's ranges: upright, 4.1 m/s down with 1.8 m/s sideways onto a 7.6 degree slope.
STOP_UNDER_A_STRIKE = dict(tilt=0.0, heading=80.94862471047296, yaw=12.530475581488423,
                           v_down=4.142875760830524, side=1.836456173881057,
                           side_heading=140.5570265276838, spin=-0.0756994452357872,
                           mass=15457.766448842965, com=1.8607617491896156,
                           leg=2.926362920572009, slope=7.5880423805746195,
                           azimuth=145.25522630480717)


@pytest.mark.parametrize("start", [STOP_UNDER_A_STRIKE, list(S.sampled_starts(105, 119))[118]],
                         ids=["wide-64", "seed105-118"])
def test_a_foot_stopping_under_a_strike_sticks_where_the_reference_holds_it(start):
    """Start 64's foot 0 strikes at 0.125 s under 299 kN while two others slide, and its slip stops
    at 0.128 s. Holding it there takes 0.83 of its static cone by the reference's own law at the
    model's state; the model's test counted the foot's kinetic drag among the other forces,
    asked 1.03, and let it slide on at mu_k against a drive near mu_s. It never stuck again and
    the ship ended 13.8 cm short of the reference's 0.663 m, landed 0.24 s early (MODEL-NOTES
    70). Now it holds, as the reference's foot does, and the ship ends within 1%. Start 118 of
    seed 105 (2 degrees tilted, 4.1 m/s down onto 8.3 degrees) was the same decision: 3.9 cm off
    of 0.427 m before, 0.6 mm now."""
    assert S.follows(start) == ""


#: Sample start 49 of S.sampled_starts(35, 200): 2.2 m/s down onto a 14.1 degree slope; it rocks
#: onto two more feet 0.75 s after its first touchdown.
ROCKING_STRIKE_ON_14_DEG = dict(tilt=6.7657194836754595, heading=47.20477970513942,
                                yaw=84.19969199500565, v_down=2.233770377107115,
                                side=0.6321545131211518, side_heading=297.2274193343547,
                                spin=-0.22816004569611448, mass=7954.4658355828005,
                                com=2.0107068680161895, leg=2.490653802397407,
                                slope=14.089317045900717, azimuth=151.55744862532794)


def test_a_rocking_ships_later_foot_strike_follows_the_reference():
    """2.2 m/s down onto a 14.1 degree slope, tilted 6.8 degrees: the ship lands on feet 0 and 3,
    rocks, and 0.75 s later feet 1 and 2 swing down onto the ground at 1.6-1.7 m/s along its
    normal (0 to 48-64 kN within 25 ms) while its centre of mass moves along local up at well
    under 1 m/s. The reference slides 1.211 m in 3 s. Those strikes are an impact
    (sim.phases.striking, MODEL-NOTES 53: a foot that meets the ground within the tick faster
    than IMPACT_SPEED_MPS): 5 ms sub-steps end 1.2108 m (-0.04%); with the centre of mass's
    radial speed alone deciding, 25 ms sub-steps stepped the strikes and the ship slid 1.2334 m
    (+1.8%; restarting the reference from the model's state, 12.7 mrad/s of error in that one
    stretch)."""
    assert list(S.sampled_starts(35, 50))[49] == ROCKING_STRIKE_ON_14_DEG
    sc = S.scene(**ROCKING_STRIKE_ON_14_DEG)
    ref = _ref(sc)
    sim = E.run_sim(sc, 0.05)
    assert E.distance_m(sim) == pytest.approx(E.distance_m(ref), rel=0.01)
    assert S.follows(ROCKING_STRIKE_ON_14_DEG) == ""


def test_an_impact_converges_with_its_sub_step():
    """Tilted 12.8 degrees, 6.8 m/s down, 2.5 m/s sideways against its tilt: the feet touch down
    sliding under the impact's load while the ship turns over one that holds, and one of them
    comes to rest under about 90 kN while the others slide and the ship turns about it. At the default
    settings it ends 1.345 m from its start in 3 s, as the reference does (1.345), to 1%: the
    stiff foot's pieces are 1 ms (sim.stiff_substep). 0.8 took that foot's friction as an
    impulse after each 5 ms sub-step, missed its stop and slid 1.535 m (+14%; sim.stiff_substep
    = 0 still does); a 1 ms impact sub-step everywhere would double a touchdown sweep's cost."""
    sc = S.scene(12.82672, 206.26773, 62.72895, 6.80023, 2.49824, 0.25, 0.033447, 1e4, 2.00001,
                2.61494, 0.0, 0.0)
    ref = _ref(sc)
    sim = E.run_sim(sc, 0.05)
    assert E.distance_m(sim) == pytest.approx(E.distance_m(ref), rel=0.01)
    seed = E.run_sim(sc, 0.05, sim={"stiff_substep": 0.0})
    assert E.distance_m(seed) > 1.1 * E.distance_m(ref)


#: Envelope case 173 of ``touchdown sweep`` (300 samples, seed 1): 3.35 m/s down and 1.29 m/s
#: downhill onto the envelope's 6 degree slope, tilted 4.8 degrees.
STIFF_STOP_BESIDE_A_HOLDING_PAIR = {
    "name": "envelope case 173", "duration": 1.5,
    "body": {"name": "Luna", "terrain": {"slope_deg": 6.0, "slope_azimuth_deg": 90.0}},
    "ships": [{"id": "case-173", "initial": {
        "altitude": 0.5, "vertical_speed": -3.352788713814329,
        "horizontal_speed": 1.2935869676664309, "heading_deg": 90.0,
        "tilt_deg": 4.8033557425369}}]}


@pytest.mark.slow
def test_a_stiff_foots_stop_beside_a_holding_pair_follows_the_reference():
    """At tick 7 of envelope case 173 foot 0 slides at 0.67 mm/s under 67 kN (its own friction
    would stop it within 55 us) while feet 1 and 3 hold at 0.7 of their cones. In the reference
    foot 0 stops, and the pair breaks away. The model restarted there and the reference from
    the same state run 0.5 s: the reference moves 437 mm, and the model ends 0.28 mm and 0.8 mm/s
    from it because it steps down to the stiff foot's stop (MODEL-NOTES 58, sim.flight.
    at_transition). Without that refinement, or with any of the narrower rules tried in
    docs/issue36/session14-fast42d.txt, the stiff foot's 1 ms pieces keep all three feet
    sliding and it ends 36.5 mm and 112 mm/s off."""
    from touchdown.bench.reference3d import Ground3, Lander3, Law, MOON_R, Start3, solve3
    from touchdown.sim.run import run
    from touchdown.sim.scenario import parse

    params = parse(STIFF_STOP_BESIDE_A_HOLDING_PAIR, "case 173")
    records = list(run(params))
    k = next(i for i, r in enumerate(records) if r.tick == 7)
    n_ticks = 10
    start, end = records[k].state.rows[0], records[k + n_ticks].state.rows[0]
    assert list(start["sliding"]) == [1, 0, 0, 0] and bool(start["absorbing"])
    centre_m = np.array([MOON_R, 0.0, 0.0])
    y0 = np.concatenate([np.array(start["pos_m"]) - centre_m, start["vel_mps"], start["quat"],
                         start["omega_body_radps"]])
    span_s = n_ticks * params.params.sim.dt_s
    ref = solve3(Lander3(), Ground3(slope_deg=6.0, slope_azimuth_deg=90.0),
                 Start3(state="contact", vertical_speed_mps=0.0), span_s, law=Law(),
                 method="LSODA", y0=y0, stop_at_tipped=False).y(span_s)
    pos_ref_m, vel_ref_mps = ref[0:3] + centre_m, ref[3:6]
    way_m = np.linalg.norm(pos_ref_m - np.array(start["pos_m"]))
    assert way_m == pytest.approx(0.437, abs=0.002)
    assert np.linalg.norm(np.array(end["pos_m"]) - pos_ref_m) < 0.01 * way_m
    assert np.linalg.norm(np.array(end["vel_mps"]) - vel_ref_mps) < 0.01


if __name__ == "__main__":  # the sample's reference table, written again (both cores, ~1 minute)
    rows = S.reference_table(SEED, STARTS)
    head = json.dumps({"seed": SEED, "starts": STARTS,
                       "what": "bench.starts3d.reference_table: in scope, largest tilt (deg), "
                               "end east and north (m), a row a start"})
    lines = [json.dumps([r.in_scope, r.peak_deg, r.end_m[0], r.end_m[1]]) for r in rows]
    REFERENCE_TABLE.write_text(head[:-1] + ', "rows": [\n' + ",\n".join(lines) + "\n]}\n")
    print(f"{REFERENCE_TABLE}: {sum(r.in_scope for r in rows)} of {len(rows)} in scope")
