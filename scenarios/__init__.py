"""Built-in scenarios: the TOML files beside this module, by file stem."""
from __future__ import annotations

import tomllib
from importlib import resources


def names() -> list[str]:
    return sorted(p.name[:-5] for p in resources.files(__name__).iterdir()
                  if p.name.endswith(".toml"))


def text(name: str) -> str:
    return resources.files(__name__).joinpath(name + ".toml").read_text(encoding="utf-8")


def description(name: str) -> str:
    return tomllib.loads(text(name)).get("description", "")
