"""The service's commands as one table (service.kinds, issue 26): parse and apply are read off it,
and its inputs' ranges are a recorded command's and a scenario's [[ships.inputs]]'."""
from __future__ import annotations

import pytest

from touchdown.service import commands
from touchdown.service.kinds import KINDS, apply, in_force
from touchdown.sim.scenario import INPUT, parse
from touchdown.sim.timeline import HOLD_MODES, INPUTS, RCS, THROTTLE, Command, CommandError
from touchdown.sim.world import World


def test_every_command_is_a_row_and_parse_takes_its_fields():
    assert list(commands.FIELDS) == list(KINDS) == [
        "throttle", "rcs", "hold", "spawn", "retire", "autoland"]
    assert commands.FIELDS["rcs"] == ("x", "y", "z")


@pytest.mark.parametrize("lo,hi,key", [(*THROTTLE, "throttle"), (*RCS, "rcs")])
def test_a_command_a_recorded_command_and_a_scenario_take_the_same_ranges(lo, hi, key):
    check = INPUT[key][2]
    assert check(lo) is None and check(hi) is None and check(hi + 1e-9) and check(lo - 1e-9)
    field = "value" if key == "throttle" else "x"
    for x, ok in ((lo, True), (hi, True), (hi + 0.5, False), (lo - 0.5, False)):
        entry = {"cmd": key, "ship_id": "a", "player_id": "p", "x": "0", "y": "0", "z": "0",
                 field: repr(x)}
        if key == "throttle":
            entry = {k: v for k, v in entry.items() if k not in "xyz"}
        assert isinstance(commands.parse("1-0", entry), commands.Request) is ok
        given = {"throttle": x} if key == "throttle" else {"rcs": (x, 0.0, 0.0)}
        if ok:
            Command(0, "a", **given).check()
        else:
            with pytest.raises(CommandError):
                Command(0, "a", **given).check()
    assert INPUT["hold"][2]("radial") is None and INPUT["hold"][2]("up")
    assert set(HOLD_MODES) == {"off", "kill_rotation", "radial"}


def test_an_input_command_sets_its_input_alone_and_becomes_a_recorded_command():
    world = World.of(parse({"name": "t", "duration": 1.0,
                            "ships": [{"id": "a", "player_id": "p"}]}, "t"))
    pending: dict = {}
    for fields in ({"cmd": "throttle", "value": "0.5"}, {"cmd": "hold", "mode": "radial"},
                   {"cmd": "rcs", "x": "0.1", "y": "0", "z": "-0.1"}):
        req = commands.parse("1-0", {"ship_id": "a", "player_id": "p", **fields})
        assert apply(world, req, pending, {}) is None
    assert pending == {"a": [0.5, (0.1, 0.0, -0.1), 2]}
    assert len(INPUTS) == len(in_force(world, 0)) == 3
    req = commands.parse("1-0", {"cmd": "throttle", "ship_id": "b", "player_id": "p",
                                 "value": "1"})
    assert apply(world, req, pending, {}) == "throttle: no ship 'b' in the fleet at tick 0"
    (cmd,) = world.commands((sid, *given) for sid, given in pending.items())
    assert (cmd.throttle, cmd.rcs, cmd.hold) == (0.5, (0.1, 0.0, -0.1), 2)
