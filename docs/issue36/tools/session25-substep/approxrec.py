"""Temporary pytest plugin: record, per test, the worst |actual-expected|/tolerance of every
scalar pytest.approx comparison (not committed)."""
import json
import os

import pytest
from _pytest import approx as python_api

_OUT = os.environ.get("APPROXREC_OUT", "/tmp/substep/approx")
_orig_eq = python_api.ApproxScalar.__eq__
_worst = {}


def _eq(self, actual):
    res = _orig_eq(self, actual)
    try:
        tol = self.tolerance
        err = abs(actual - self.expected)
        ratio = float(err / tol) if tol > 0 else (0.0 if err == 0 else float("inf"))
        node = os.environ.get("PYTEST_CURRENT_TEST", "?").rsplit(" (", 1)[0]
        w = _worst.get(node)
        if w is None or ratio > w[0]:
            _worst[node] = (ratio, float(err), float(tol), repr(self.expected), repr(actual))
    except Exception:
        pass
    return res


python_api.ApproxScalar.__eq__ = _eq


def pytest_sessionfinish(session):
    wid = os.environ.get("PYTEST_XDIST_WORKER", "main")
    with open(f"{_OUT}-{wid}.json", "w") as f:
        json.dump(_worst, f)


# the default impact_substep under test (before sim.scenario / sim.params read the defaults)
_V = os.environ.get("IMPACT_SUBSTEP")
if _V:
    from touchdown.sim import settings as _st
    object.__setattr__(_st.BY_KEY["sim.impact_substep"], "default", float(_V))
    import sys as _sys
    assert "touchdown.sim.scenario" not in _sys.modules and "touchdown.sim.params" not in _sys.modules
_M = os.environ.get("MAX_SUBSTEP")
if _M:
    from touchdown.sim import settings as _st2
    object.__setattr__(_st2.BY_KEY["sim.max_substep"], "default", float(_M))
