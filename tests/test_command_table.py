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


def test_the_inputs_are_declared_once_and_everything_else_follows_the_table():
    """sim.fields.INPUTS is the one declaration of the inputs; the recorded command, the step's
    records, the scenario's settings and the service's commands are derived from it."""
    import dataclasses

    from touchdown.sim import fields
    from touchdown.sim.settings import in_table
    from touchdown.sim.state import COMMAND_DTYPE, INPUTS_DTYPE
    names = tuple(f.name for f in fields.INPUTS)
    assert names == INPUTS == ("throttle", "rcs", "hold")
    assert tuple(f.name for f in dataclasses.fields(Command))[2:] == names
    assert Command(0, "a").inputs == tuple(f.default for f in fields.INPUTS)
    assert INPUTS_DTYPE.names == names and COMMAND_DTYPE["inputs"] == INPUTS_DTYPE
    settings = {s.key.rpartition(".")[2]: s for s in in_table("ships.inputs")}
    assert tuple(settings) == ("t", *names)
    for f in fields.INPUTS:
        s = settings[f.name]
        if f.choices is not None:
            assert s.choices == f.labels and s.default == f.labels[0]
        else:
            assert (s.lo, s.hi) == f.limits
        kind = KINDS[f.name]
        assert tuple(x.name for x in kind.fields) == f.wire and kind.parts == {f.name}


def test_the_logs_command_message_has_the_tables_inputs():
    """The proto cannot be derived (it is the log's schema, written schema-first): each input is
    a field of its Command message, by name, a double per number (repeated for a vector), a
    choice as the enum whose values are the choices'."""
    from google.protobuf.descriptor import FieldDescriptor as FD

    from touchdown.proto import touchdown_pb2 as pb
    from touchdown.sim import fields
    msg = pb.Command.DESCRIPTOR
    assert [f.name for f in msg.fields] == ["tick", "ship_id", *INPUTS]
    for f in fields.INPUTS:
        d = msg.fields_by_name[f.name]
        repeated = d.is_repeated
        assert repeated is (f.per_ship > 1)
        if f.choices is not None:
            assert d.type == FD.TYPE_ENUM
            assert {v.number for v in d.enum_type.values} == {int(m) for m in f.choices}
        else:
            assert d.type == FD.TYPE_DOUBLE
    assert [f.name for f in pb.CommandBatch.DESCRIPTOR.fields] == ["tick", "commands"]


def test_world_command_takes_the_inputs_by_name_or_in_order():
    world = World.of(parse({"name": "t", "duration": 1.0,
                            "ships": [{"id": "a", "player_id": "p"}]}, "t"))
    assert world.command("a", 0.5, (0.0, 0.2, 0.0), 1).inputs == (0.5, (0.0, 0.2, 0.0), 1)
    assert world.command("a", hold=2).inputs == (0.0, (0.0, 0.0, 0.0), 2)
    for bad in (lambda: world.command("a", thrust=1.0), lambda: world.command("a", 0.1, throttle=0.2),
                lambda: world.command("a", 0.1, (0, 0, 0), 0, 9)):
        with pytest.raises(TypeError):
            bad()


def test_the_docstring_list_of_commands_is_the_table():
    """service/commands.py's docstring lists each command and its fields by hand (what a gateway
    author reads first): held to KINDS here, so a new command cannot miss it."""
    import re
    listed = {}
    for line in commands.__doc__.splitlines():
        m = re.match(r"^    (\w+) +(\(nothing\)|\w+(?:, \w+)*)(?: {2,}\S|\s*$)", line)
        if m:
            listed[m.group(1)] = () if m.group(2) == "(nothing)" else tuple(
                x.strip() for x in m.group(2).split(","))
    assert listed == {name: tuple(f.name for f in kind.fields) for name, kind in KINDS.items()}
