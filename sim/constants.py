"""Physical and model constants, each with its source. SI units throughout."""
from __future__ import annotations

#: Standard gravity, m/s^2, for specific impulse (BIPM, CGPM 1901; exact by definition).
G0_MPS2 = 9.80665

#: Contact spring stiffness per kilogram of ship, 1/s^2: the seed's ``k_spring = ship_mass * 100.0``.
#: It makes the contact's natural frequency omega = sqrt(k/m) = 10 rad/s for every ship.
CONTACT_STIFFNESS_PER_KG = 100.0

#: Tangential speed below which the seed treats the ship as stuck (static friction), m/s: the
#: seed's own threshold between its static and kinetic branches (its law, sim.friction.seed).
SEED_STICK_SPEED_MPS = 0.01

#: A foot of Coulomb's law that slips slower than this after its friction impulse still counts as
#: sticking, m/s (``contact.stick_speed``, MODEL-NOTES 39): a tolerance for four rigid feet, which
#: under a rocking ship slip against each other by the kinematics alone (micrometres a second),
#: not a threshold of the law. A tenth of a millimetre a second, the width over which the 3-D
#: reference's friction drops from mu_s to mu_k (bench.reference3d). 0.7 used the seed's 0.01 m/s,
#: which let a foot keep mu_s while it slid (issue 35, item 2).
STICK_SPEED_MPS = 1e-4

#: A ship whose pressing feet slip faster than this is not at rest and does not land, m/s: the
#: seed's own line between moving and still (MODEL-NOTES 44, 45).
SETTLE_SLIP_MPS = 0.01

#: Landing legs per ship. Four legs at 90 degree spacing on a circle of ``leg_radius``: the body
#: coordinates are exact (a, 0), (0, a), (-a, 0), (0, -a), so an upright ship has no spurious torque.
LEG_DIRECTIONS_BODY = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))

#: Default specific impulses, s: Apollo LM descent engine 311 s (NASA SP-2010-3061 "Apollo LM
#: descent propulsion"), Apollo RCS thrusters 290 s (Marquardt R-4D data sheet).
DEFAULT_ISP_S = 311.0
DEFAULT_RCS_ISP_S = 290.0

#: Moon (IAU 2015 nominal / JPL DE440 GM): mean radius, m, and GM, m^3/s^2.
MOON_RADIUS_M = 1737400.0
MOON_GM_M3PS2 = 4.9048695e12
#: Earth (WGS 84): equatorial radius, m, and GM, m^3/s^2.
EARTH_RADIUS_M = 6378137.0
EARTH_GM_M3PS2 = 3.986004418e14

#: Most bumps a terrain may have (the compiled terrain's fixed table, sim.contact.TERRAIN_DTYPE).
MAX_BUMPS = 1000
