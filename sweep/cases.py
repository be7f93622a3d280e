"""The cases of a sweep: its axes (``--vary KEY=LO:HI:N``), the full grid or a Latin hypercube of
random samples (``--samples N --seed S``), and each case as a scenario of one ship.

A case is the base scenario's first ship with the case's values set, alone in the scene, which
carries the case's values of any scene key (contact, body, terrain slope). That scenario is what
``touchdown sweep --record CASE`` records, and what the sweep steps as one ship of its fleet.

Keys: ``ships.KEY`` (or ``ships[0].KEY``, ``ships.0.KEY``) addresses the first ship, e.g.
``ships.initial.horizontal_speed``, ``ships.mass``; ``contact.*``, ``body.*`` (with
``body.terrain.slope_deg`` and ``body.terrain.slope_azimuth_deg``) and ``controller.*`` address
the scene. The tick and the duration (``sim.dt``, ``duration``) are the sweep's, one for all cases.
"""
from __future__ import annotations

import copy
import itertools
import re
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from touchdown.sim.errors import TouchdownError
from touchdown.sim.scenario import Scenario, ScenarioError, parse

#: Keys whose value every case shares: the tick and the run's length fix the ticks the fleet is
#: stepped through together; timing keys would make a case join or leave the fleet.
FIXED = ("duration", "sim.dt", "ships.spawn_t", "ships.retire_t", "name")


class SweepError(TouchdownError, ValueError):
    """A bad sweep definition (exit 2): one line naming the option or key."""


@dataclass(frozen=True)
class Axis:
    key: str  # as the table's column names it: "ships.initial.horizontal_speed"
    lo: float
    hi: float
    n: int | None = None  # points of the grid (None: a random sampling's range)

    def grid(self) -> np.ndarray:
        if self.n == 1:
            return np.array([self.lo])
        return np.linspace(self.lo, self.hi, int(self.n))

    @property
    def spec(self) -> str:
        return f"{self.key}={self.lo!r}:{self.hi!r}" + (f":{self.n}" if self.n else "")


def normalise_key(given: str) -> str:
    key = re.sub(r"\[(\d+)\]", r".\1", given.strip())
    if key.startswith("ships.0."):
        key = "ships." + key[len("ships.0."):]
    return key


def parse_vary(items: Sequence[str], sampled: bool) -> list[Axis]:
    """``KEY=LO:HI:N`` (a grid) or, with ``sampled``, ``KEY=LO:HI``."""
    axes = []
    for item in items:
        if "=" not in item:
            raise SweepError(f"--vary {item!r}: expected KEY=LO:HI" + ("" if sampled else ":N"))
        given, rng = item.split("=", 1)
        key = normalise_key(given)
        parts = rng.split(":")
        want = 2 if sampled else 3
        if len(parts) != want and not (sampled and len(parts) == 3):
            raise SweepError(f"--vary {item!r}: expected {key}=LO:HI" + ("" if sampled else ":N"))
        try:
            lo, hi = float(parts[0]), float(parts[1])
            n = int(parts[2]) if len(parts) == 3 else None
        except ValueError:
            raise SweepError(f"--vary {item!r}: LO and HI must be numbers"
                             + ("" if sampled else ", N a whole number")) from None
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise SweepError(f"--vary {key}: LO and HI must be finite")
        if n is not None and n < 1:
            raise SweepError(f"--vary {key}: N must be at least 1")
        if sampled:
            n = None
        if key in FIXED or key.startswith(("ships.inputs", "sim.")) or key == "ships.id":
            raise SweepError(f"--vary {key}: not a key a sweep varies (the tick, the duration, the "
                             f"ship's identity, timing and commands are shared by every case)")
        if any(a.key == key for a in axes):
            raise SweepError(f"--vary {key}: given twice")
        axes.append(Axis(key, lo, hi, n))
    if not axes:
        raise SweepError("--vary: at least one KEY=LO:HI" + ("" if sampled else ":N") + " is needed")
    return axes


def latin_hypercube(n: int, dims: int, seed: int) -> np.ndarray:
    """``n`` points in [0, 1)^dims, one in each of n equal slices of every axis (McKay, Beckman
    and Conover 1979), from numpy's PCG64 seeded with ``seed``: the same points on every machine."""
    rng = np.random.Generator(np.random.PCG64(seed))
    u = np.empty((n, dims))
    for d in range(dims):
        u[:, d] = (rng.permutation(n) + rng.random(n)) / n
    return u


@dataclass(frozen=True)
class Sweep:
    """A sweep's definition: the base scenario document, its axes, and grid or samples."""

    doc: dict  # the scenario as TOML gave it (before resolution)
    source: str
    axes: tuple[Axis, ...]
    samples: int | None = None
    seed: int = 0
    values: np.ndarray = field(default=None, repr=False, compare=False)  # (cases, axes)

    @classmethod
    def of(cls, doc: dict, source: str, axes: Sequence[Axis], samples: int | None = None,
           seed: int = 0) -> "Sweep":
        if not doc.get("ships"):
            raise SweepError(f"{source}: ships: the sweep varies the scenario's first ship; "
                             "there is none")
        if samples is not None:
            if samples < 1:
                raise SweepError("--samples: at least 1")
            u = latin_hypercube(samples, len(axes), seed)
            lo = np.array([a.lo for a in axes])
            hi = np.array([a.hi for a in axes])
            values = lo + u * (hi - lo)
        else:
            grids = [a.grid() for a in axes]
            count = int(np.prod([len(g) for g in grids]))
            if count > 50_000_000:
                raise SweepError(f"--vary: {count:,} cases is more than 50,000,000")
            values = np.array(list(itertools.product(*grids)), dtype=float).reshape(count,
                                                                                  len(axes))
        sw = cls(doc, source, tuple(axes), samples, seed, values)
        sw.check()
        return sw

    @property
    def n_cases(self) -> int:
        return int(self.values.shape[0])

    @property
    def scene_axes(self) -> tuple[int, ...]:
        """The axes that set scene keys (not the ship's)."""
        return tuple(j for j, a in enumerate(self.axes) if not a.key.startswith("ships."))

    def definition(self) -> dict:
        """What the table's metadata records (enough to make the same cases again)."""
        return {"vary": [a.spec for a in self.axes], "samples": self.samples,
                "seed": self.seed if self.samples is not None else None,
                "cases": self.n_cases, "source": self.source}

    def overrides(self, case: int) -> dict[str, Any]:
        return {a.key: float(self.values[case, j]) for j, a in enumerate(self.axes)}

    def case_doc(self, case: int) -> dict:
        """Case ``case`` as a scenario document: the first ship alone, its values set."""
        return self.group_doc([case])

    def group_doc(self, cases: Sequence[int]) -> dict:
        """Cases that share their scene values as one scenario: one ship per case (``case-K``)."""
        doc = copy.deepcopy({k: v for k, v in self.doc.items() if k != "ships"})
        base_ship = self.doc["ships"][0]
        row0 = self.values[cases[0]]
        for j in self.scene_axes:
            _set(doc, self.axes[j].key.split("."), float(row0[j]))
        ships = []
        ship_axes = [(j, a.key.split(".")[1:]) for j, a in enumerate(self.axes)
                     if a.key.startswith("ships.")]
        for k in cases:
            sh = _copied(base_ship)
            sh["id"] = f"case-{k}"
            for j, path in ship_axes:
                _set(sh, path, float(self.values[k, j]))
            ships.append(sh)
        doc["ships"] = ships
        return doc

    def case_scenario(self, case: int) -> Scenario:
        return parse(self.case_doc(case), self.source)

    def groups(self, cases: Sequence[int]) -> list[list[int]]:
        """``cases`` grouped by their scene values (in order of first appearance)."""
        sa = self.scene_axes
        if not sa:
            return [list(cases)] if len(cases) else []
        by: dict[tuple, list[int]] = {}
        vals = self.values[:, sa]
        for k in cases:
            by.setdefault(tuple(vals[k].tolist()), []).append(int(k))
        return list(by.values())

    def check(self) -> None:
        """Every axis names a numeric key the scenario takes, and its ends are values it takes
        (each end parsed once, with the other axes at their lows: ScenarioError otherwise)."""
        lows = np.array([a.lo for a in self.axes])
        for j, a in enumerate(self.axes):
            for end in (a.lo, a.hi):
                vals = lows.copy()
                vals[j] = end
                probe = Sweep(self.doc, self.source, self.axes, values=vals[None, :])
                try:
                    scn = probe.case_scenario(0)
                except ScenarioError as exc:
                    raise SweepError(f"--vary {a.key}={end!r}: {exc}") from None
                node: Any = scn.resolved
                for part in a.key.split("."):
                    node = node[0] if isinstance(node, list) else node
                    node = node.get(part) if isinstance(node, dict) else None
                if isinstance(node, bool) or not isinstance(node, (int, float)):
                    raise SweepError(f"--vary {a.key}: not a numeric key of the scenario "
                                     f"(resolved value {node!r})")
        if any(s.get("spawn_t", 0.0) or s.get("retire_t") is not None
               for s in self.doc["ships"][:1]):
            raise SweepError(f"{self.source}: ships[0]: a swept ship is present from tick 0 to "
                             "the end (no spawn_t or retire_t)")


#: Values a document holds that are never changed in place (TOML's and JSON's scalars)
_IMMUTABLE = (str, int, float, bool, type(None))


def _copied(node: Any) -> Any:
    """``copy.deepcopy(node)`` for a document's tables and arrays (dicts and lists of scalars,
    as tomllib and json give them, nothing shared twice): a new dict or list at every level.
    Several times quicker than deepcopy's memo and dispatch, which were a third of building a
    fleet's scenario (a copy of the first ship per case); anything else is deep-copied."""
    if type(node) is dict:
        return {k: _copied(v) for k, v in node.items()}
    if type(node) is list:
        return [_copied(v) for v in node]
    if isinstance(node, _IMMUTABLE):
        return node
    return copy.deepcopy(node)


def _set(node: dict, path: list[str], value: float) -> None:
    for part in path[:-1]:
        node = node.setdefault(part, {})
        if not isinstance(node, dict):
            raise SweepError(f"--vary {'.'.join(path)}: {part} is not a table")
    node[path[-1]] = value
