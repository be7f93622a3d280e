"""Built-in scenarios: the TOML files beside this module, by file stem."""
from __future__ import annotations

import re
import tomllib
from importlib import resources


def names() -> list[str]:
    return sorted(p.name[:-5] for p in resources.files(__name__).iterdir()
                  if p.name.endswith(".toml"))


def text(name: str) -> str:
    return resources.files(__name__).joinpath(name + ".toml").read_text(encoding="utf-8")


def description(name: str) -> str:
    return tomllib.loads(text(name)).get("description", "")


def parse_sets(sets: tuple[str, ...]) -> dict:
    """``--set sim.dt=0.02`` -> {"sim.dt": 0.02}. Values are TOML (bare words are strings);
    ``ships[0].mass`` and ``ships.0.mass`` both address the first ship (the command line's
    overrides: record, what-if, sweep, bench starts3d)."""
    from touchdown.sim.errors import UserError
    from touchdown.sim.scenario import ScenarioError, load_toml
    out = {}
    for item in sets:
        if "=" not in item:
            raise UserError(f"--set {item!r}: expected KEY=VALUE")
        given, raw = item.split("=", 1)
        key = re.sub(r"\[(\d+)\]", r".\1", given.strip())
        try:
            value = load_toml(f"v = {raw}", "--set", given.strip())["v"]
        except ScenarioError as exc:
            if exc.problem.startswith(("arrays", "Exceeds")):
                raise UserError(str(exc)) from None
            value = raw  # not TOML: a bare word, taken as a string
        out[key] = value
    return out
