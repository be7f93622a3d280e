"""sim.state.event_of, the step's fast way to build an Event, builds the dataclass's object."""
import dataclasses
import pickle

import numpy as np

from touchdown.sim.state import TRANSITION_DTYPE, Event, event_of
from touchdown.sim.step import transitions


ARGS = (17, 3, 2, 1, 2, -1.25, "lander-4", 0.8375)
NAMED = {"ship_id": ARGS[6], "t_event_s": ARGS[7]}


def test_event_of_is_the_dataclass_field_for_field():
    built, fast = Event(*ARGS), event_of(*ARGS[:6], **NAMED)
    # every field set, none more (a field added to Event and not to event_of fails here)
    assert vars(fast) == vars(built) == dict(zip((f.name for f in dataclasses.fields(Event)), ARGS))
    assert type(fast) is Event and fast == built and hash(fast) == hash(built)
    assert repr(fast) == repr(built) and pickle.loads(pickle.dumps(fast)) == built
    try:
        fast.tick = 0
    except dataclasses.FrozenInstanceError:
        pass
    else:
        raise AssertionError("an event must stay frozen")


def test_transitions_names_each_event_at_its_instant():
    # the step into tick 4 (dt 0.05) of ship 1: a contact at 0.02 s into it, then a liftoff
    rows = np.array([(1, 0, 1, -2.5, 0.02), (1, 1, 0, 0.75, 0.05)], dtype=TRANSITION_DTYPE)
    evs = transitions(rows, np.array([4, 4]), 0.05, ("a", "b"))
    assert [(e.tick, e.ship, e.from_state, e.to_state, e.ship_id) for e in evs] == [
        (4, 1, 0, 1, "b"), (4, 1, 1, 0, "b")]
    assert evs[0].t_event_s == 4 * 0.05 - (0.05 - 0.02) and evs[1].t_event_s == 4 * 0.05
    assert evs[0] == Event(4, 1, evs[0].kind, 0, 1, -2.5, "b", 4 * 0.05 - (0.05 - 0.02))
