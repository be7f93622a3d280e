"""The settings table (sim.settings) against what is derived from it: the scenario's key tables,
the parameters' dataclasses and records, the README's table of defaults."""
from __future__ import annotations

import dataclasses
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from touchdown.sim import params as P
from touchdown.sim import scenario as S
from touchdown.sim.settings import (BY_KEY, REQUIRED, SETTINGS, FrictionModel, Integrator,
    SurfaceNormal, in_scene, in_table, landing_in)

README = Path(__file__).resolve().parents[1] / "README.md"

MINIMAL = {"name": "m", "duration": 1.0, "ships": [{"id": "a"}]}


def test_every_key_has_exactly_one_row():
    keys = [s.key for s in SETTINGS]
    assert len(keys) == len(set(keys))
    tables = {"": S.TOP, "sim": S.SIM, "contact": S.CONTACT, "body": S.BODY,
              "body.terrain": S.TERRAIN, "body.terrain.bumps": S.BUMP,
              "controller": S.CONTROLLER, "ships": S.SHIP, "ships.initial": S.INITIAL,
              "ships.inputs": S.INPUT}
    assert {s.table for s in SETTINGS} == set(tables)
    for table, spec in tables.items():
        assert list(spec) == [s.name for s in in_table(table)]


def test_every_destination_exists():
    sections = {"sim": P.SimParams, "contact": P.ContactParams, "body": P.BodyParams,
                "controller": P.ControllerParams, "terrain": P.Terrain}
    for s in SETTINGS:
        if not s.dest:
            continue
        if s.section == "ships":
            assert s.field in P.SHIP_DTYPE.names, s.key
        else:
            assert s.field in {f.name for f in dataclasses.fields(sections[s.section])}, s.key
    for s in in_scene():
        assert s.scene in P.SCENE_DTYPE.names and s.dest, s.key


def test_ship_record_layout_is_kept():
    # a live service's checkpoints hold these bytes (service.redis_io)
    assert P.SHIP_DTYPE == np.dtype([
        ("mass0_kg", "f8"), ("fuel0_kg", "f8"), ("com_height_m", "f8"), ("leg_radius_m", "f8"),
        ("inertia0_kgm2", "f8", (3,)), ("max_thrust_n", "f8"), ("max_rcs_torque_nm", "f8"),
        ("isp_s", "f8"), ("rcs_isp_s", "f8"), ("rcs_arm_m", "f8"), ("stiffness_per_kg", "f8"),
        ("contact_omega_radps", "f8"), ("n_substeps", "i8")], align=True)
    assert [s.field for s in landing_in("ships")] == list(P.SHIP_DTYPE.names[:-2])


def test_parameters_default_to_the_scenario_defaults():
    scn = S.parse(MINIMAL, "m.toml")
    assert scn.params.contact == P.ContactParams()
    assert scn.params.controller == P.ControllerParams()
    assert dataclasses.replace(scn.params.sim, duration_s=30.0) == P.SimParams()
    assert dataclasses.replace(scn.params.body, terrain=P.Terrain()) == P.BodyParams()


def test_models_are_enums_named_as_the_scenario_says():
    assert BY_KEY["contact.friction_model"].enum is FrictionModel
    assert BY_KEY["contact.surface_normal"].enum is SurfaceNormal
    from touchdown.sim.integrators import METHODS
    assert METHODS == {m.label: int(m) for m in Integrator}
    scn = S.parse({**MINIMAL, "contact": {"friction_model": "seed", "surface_normal": "radial"}},
                  "m.toml")
    assert scn.params.contact.friction_model is FrictionModel.SEED
    assert scn.params.contact.surface_normal is SurfaceNormal.RADIAL
    rec = scn.params.scene[0]
    assert rec["friction_model"] == FrictionModel.SEED and rec["surface_normal"] == SurfaceNormal.RADIAL
    # the resolved document (what a log records) keeps the strings
    assert scn.resolved["contact"]["friction_model"] == "seed"


@pytest.mark.parametrize("key,value,problem", [
    ("contact.friction_static", 11.0, "must be <= 10, got 11"),
    ("contact.crash_speed", 0.0, "must be > 0, got 0"),
    ("contact.friction_model", "magic", "must be one of coulomb, seed; got 'magic'"),
    ("sim.on_unstable", "never", "must be one of allow, error, substep; got 'never'"),
])
def test_checks_come_from_the_table(key, value, problem):
    with pytest.raises(S.ScenarioError) as err:
        S.parse(MINIMAL, "m.toml", {key: value})
    assert str(err.value) == f"m.toml: {key}: {problem}"


def _readme_defaults() -> dict[str, object]:
    """The README's Scenarios table: each key whose default is one literal."""
    text = README.read_text()
    section = text[text.index("## Scenarios"):]
    section = section[:section.index("\nA start must")]
    out = {}
    for m in re.finditer(r"^\| `([a-z_.]+)` \| `([^`|]+)` \|", section, re.M):
        key, literal = m.groups()
        try:
            out[key] = tomllib.loads(f"x = {literal}")["x"]
        except tomllib.TOMLDecodeError:
            continue  # a reference to another key
    return out


def test_readme_defaults_match_the_table():
    rows = _readme_defaults()
    assert len(rows) >= 15
    for key, value in rows.items():
        s = BY_KEY[key]
        assert s.default is not REQUIRED and s.default == value, key


def _source(*dirs: str, skip: tuple[str, ...] = ()) -> str:
    root = Path(__file__).resolve().parents[1]
    return "\n".join(p.read_text() for d in dirs for p in sorted((root / d).glob("*.py"))
                     if p.name not in skip)


def test_every_setting_is_read():
    """A setting nothing reads is a key a user sets to no effect. The step reads the scene's
    record as ``cfg`` and a ship's as ``sp`` (sim.step, sim.contact, ...); a scene field no kernel
    reads, a ship field read nowhere in sim/, or a parameter no module names, fails here."""
    kernels = _source("sim", skip=("settings.py", "params.py"))
    unread = [f"scene record field {f}" for f in P.SCENE_DTYPE.names
              if not re.search(rf"\bcfg\.{f}\b", kernels)]
    sim_side = _source("sim", skip=("settings.py",))
    unread += [f"ship record field {f}" for f in P.SHIP_DTYPE.names
               if not re.search(rf"\.{f}\b|\[\"{f}\"\]", sim_side)]
    every = _source("sim", "sweep", "service", "logs", "replay", "view", ".", skip=("settings.py",))
    unread += [f"setting {s.key} ({s.dest})" for s in SETTINGS
               if s.dest and not s.scene and s.section != "ships"
               and not re.search(rf"\.{s.field}\b", every)]
    assert not unread, unread
