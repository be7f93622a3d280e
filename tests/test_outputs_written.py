"""Every per-tick output (sim.fields, record "outputs") is written by the step, every tick, and
means something: a new field added to the table but not computed in ``observe`` (sim/phases.py)
fails here, where every other test would pass with a column that is always 0 (README, "Where
things are": a new per-tick export field).

- Written: the step's output records are filled with a byte pattern before the step (the step
  allocates them with np.empty: an unwritten field holds whatever was there, most often zeros);
  after one tick of ships in every state, no field of any ship still holds the pattern.
- Meant: over the built-in scenarios (every state, the engine, the RCS, friction, the passivity
  guard), each output is non-zero at some tick of some ship.
"""
from __future__ import annotations

import numpy as np
import pytest

from touchdown import scenarios
from touchdown.sim import fields
from touchdown.sim import step as step_module
from touchdown.sim.run import run
from touchdown.sim.scenario import parse_text

OUTPUTS = fields.of_record("outputs")
PATTERN = 0xA5


class _FilledNumpy:
    """numpy, but ``empty`` fills what it allocates with PATTERN."""

    def __getattr__(self, name):
        return getattr(np, name)

    @staticmethod
    def empty(shape, dtype=float, **kw):
        a = np.empty(shape, dtype, **kw)
        if a.nbytes:
            a.view(np.uint8)[...] = PATTERN
        return a


def _unwritten(outputs: np.ndarray) -> list[str]:
    """The output fields of which some ship's bytes all still hold PATTERN."""
    out = []
    for f in OUTPUTS:
        raw = np.ascontiguousarray(outputs[f.name]).view(np.uint8).reshape(outputs.shape[0], -1)
        if np.any(np.all(raw == PATTERN, axis=1)):
            out.append(f.name)
    return out


def test_the_step_writes_every_output_of_every_ship_every_tick(monkeypatch):
    scn = parse_text(scenarios.text("fleet"), "fleet")
    recs = list(run(scn))
    # states along the run: flying, in contact, landed, tipped, crashed where the fleet has them
    picks = [recs[k] for k in (0, len(recs) // 4, len(recs) // 2, len(recs) - 1)]
    # compiled before numpy is patched (numba reads a module's globals when it compiles)
    step_module.step(scn.params, picks[0].state, _zeros_inputs(picks[0].state.n))
    monkeypatch.setattr(step_module, "np", _FilledNumpy())
    for rec in picks:
        _state, outputs, _events = step_module.step(scn.params, rec.state,
                                                    _zeros_inputs(rec.state.n))
        assert _unwritten(outputs.rows) == [], f"tick {rec.tick}: never written by the step"


def _zeros_inputs(n: int):
    from touchdown.sim.state import Inputs
    return Inputs.zeros(n)


def test_the_pattern_would_be_found():
    """The check above can fail: a record whose field was not written is caught."""
    a = _FilledNumpy.empty(3, fields.record_dtype("outputs"))
    assert _unwritten(a) == [f.name for f in OUTPUTS]
    a["altitude_m"] = 0.0
    assert "altitude_m" not in _unwritten(a) and "throttle" in _unwritten(a)


@pytest.fixture(scope="module")
def builtin_outputs() -> dict[str, np.ndarray]:
    """The largest |value| of each output over every tick and ship of every built-in scenario."""
    largest = {f.name: 0.0 for f in OUTPUTS}
    for name in scenarios.names():
        for rec in run(parse_text(scenarios.text(name), name)):
            for f in OUTPUTS:
                v = getattr(rec.outputs, f.name)
                if v.size:
                    largest[f.name] = max(largest[f.name], float(np.max(np.abs(v))))
    return largest


@pytest.mark.parametrize("name", [f.name for f in OUTPUTS])
def test_every_output_means_something_somewhere_in_the_builtins(builtin_outputs, name):
    assert builtin_outputs[name] > 0.0, f"{name} is 0 at every tick of every built-in scenario"
