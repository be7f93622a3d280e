"""Small helpers to build scenarios in tests, straight from dicts (the TOML structure)."""
from __future__ import annotations

import copy

import numpy as np

from touchdown.sim.enums import EventKind, SurfaceState
from touchdown.sim.run import run
from touchdown.sim.scenario import Scenario, parse


def scene(initial: dict | None = None, *, ship: dict | None = None, contact: dict | None = None,
          body: dict | None = None, sim: dict | None = None, inputs: list | None = None,
          duration: float = 10.0, ships: list | None = None) -> Scenario:
    doc = {"name": "test", "duration": duration, "sim": sim or {}, "contact": contact or {},
           "body": body or {}}
    if ships is None:
        ships = [{"id": "s", **(ship or {}), "initial": initial or {}, "inputs": inputs or []}]
    doc["ships"] = copy.deepcopy(ships)
    return parse(doc, "test")


def records(scn: Scenario, **kw) -> list:
    return list(run(scn, **kw))


def events(recs, ship: int = 0) -> list[tuple[int, str, float]]:
    """[(tick, 'ship.contact', v_radial), ...] for one ship."""
    return [(r.tick, EventKind(e.kind).topic, e.v_radial_mps) for r in recs for e in r.events
            if e.ship == ship]


def topics(recs, ship: int = 0) -> list[str]:
    return [t for _, t, _ in events(recs, ship)]


def final_state(recs, ship: int = 0) -> SurfaceState:
    return SurfaceState(int(recs[-1].state.surface_state[ship]))


def series(recs, name: str, ship: int = 0) -> np.ndarray:
    return np.array([getattr(r.outputs, name)[ship] for r in recs])


def tilt_deg(recs, ship: int = 0) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(series(recs, "cos_tilt", ship), -1.0, 1.0)))


def long_axis(quat: np.ndarray) -> np.ndarray:
    """The body z axis (N,3) of attitudes (N,4)."""
    w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
    return np.stack([2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)], 1)


def one_ship(params, state, inputs=None, i: int = 0):
    """What the compiled phases (sim.phases) take for ship ``i``: (the scene and this ship, a
    sim.ship.Here with the body at angle 0 at both ends of the tick; its state as a
    sim.ship.Ship; its commands' record)."""
    from touchdown.sim.state import Inputs
    from touchdown.sim.ship import Here, Turn, load
    inputs = Inputs.zeros(state.n) if inputs is None else inputs
    here = Here(params.scene[0], params.terrain[0], params.ships.rows[i],
                Turn(1.0, 0.0, 1.0, 0.0))
    return here, load(state.rows[i]), inputs.rows[i]


def footprint_centre(scn: Scenario, rec, i: int = 0) -> np.ndarray:
    """The mean of ship i's four feet at a record, inertial, m."""
    from touchdown.sim.contact import foot_offsets_w
    sp = scn.params.ships
    p = rec.state.pos_m[i]
    offs = foot_offsets_w(tuple(map(float, rec.state.quat[i])), float(sp.leg_radius_m[i]),
                          float(sp.com_height_m[i]))
    return p + np.mean(np.array(offs), axis=0)
