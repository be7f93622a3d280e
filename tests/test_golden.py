"""Golden logs: today's bits and today's log format, pinned.

tests/data/golden holds logs of five scenes recorded by this version (log format 6): the bounce and
the trip (built-in scenarios), a 10-degree tilted touchdown, a ship held and a ship sliding on a
30-degree slope, and a fleet with a join, a leave and commands. Two checks, as Box2D's determinism
test does:

- each committed log verifies bit for bit against a re-run (`replay --verify`, exit 0);
- a digest of every tick's state, outputs and events of each scene equals the committed literal.

A change that alters bits fails both, says why in its commit message, and regenerates the logs and
the digests in a commit of its own (``python tests/test_golden.py`` prints the new digests and
rewrites the logs). Older formats stay readable: one test per format (1: 0.2.0, 2: 0.4.0, 3: 0.5.0,
4: 0.6.0, 5: 0.7.0) replays, verifies with a version notice (their physics differs from today's, so a
divergence is expected and said), and exports the logs those versions wrote.
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from touchdown.cli import main  # noqa: E402
from touchdown.logs.header import LOG_FORMAT_VERSION  # noqa: E402
from touchdown.logs.reader import LogReader  # noqa: E402
from touchdown.sim.run import run  # noqa: E402
from touchdown.sim.scenario import parse_text  # noqa: E402

DATA = ROOT / "tests" / "data"
GOLDEN = DATA / "golden"

#: scene -> its scenario file; the log is tests/data/golden/<scene>.mcap
SCENES = {
    "bounce": ROOT / "scenarios" / "bounce.toml",
    "trip": ROOT / "scenarios" / "trip.toml",
    "tilted": GOLDEN / "tilted.toml",
    "slope": GOLDEN / "slope.toml",
    "fleet": GOLDEN / "fleet.toml",
}

#: sha256 of every tick's state rows, outputs and events (digest() below), since touchdown 0.8.0
#: (issue 35: landing, friction and tipped ships changed the physics; the stiff feet in pieces,
#: sim.stiff_substep, changed the tilted touchdown and the fleet; cut in every sub-step, the
#: tilted touchdown, the slope and the fleet; an absorbed foot's release, MODEL-NOTES 52, the
#: trip, the tilted touchdown and the slope; three or four feet's friction solved by the
#: interior-point method after two sweeps, MODEL-NOTES 56, the tilted touchdown, the slope and the
#: fleet; coarse contact sub-steps, MODEL-NOTES 57, the trip, the tilted touchdown, the slope and
#: the fleet; the interior-point method's active-set finish and the mirrored Delassus matrix,
#: MODEL-NOTES 59, the bounce, the tilted touchdown, the slope and the fleet; a stiff foot's
#: pieces beside a foot at its transition, MODEL-NOTES 58, the tilted touchdown and the fleet;
#: a flying ship clear of the ground for the tick in one step, MODEL-NOTES 63, the bounce (its
#: tick outputs only: positions and events the same), the tilted touchdown and the fleet; the
#: carried-impulse try for two or three feet, MODEL-NOTES 64, the tilted touchdown, the slope and
#: the fleet; a purely vertical ship's own path, MODEL-NOTES 65, the bounce and the fleet: the
#: feet's onset at the ballistic flow's root, no friction solve; a ship at rest already taking the
#: coarse contact sub-step, MODEL-NOTES 69, the tilted touchdown, the slope and the fleet; the
#: slope's tangent, sine and cosine from sim.trig rather than libm, log format 6, the slope)
EXPECTED = {
    "bounce": "dc4bf9d1ecfa9ca66832db31fda03d1c1e1b65069e8c090a0410551f020f7982",
    "trip": "73e877ecc8eedef2c421dd1fd7478e307d3c3edb6650ed3c8ed4704e2dc80c9b",
    "tilted": "427bcd61ac633c535e45b08adb1eb59a6b1e8bb2912a410cdd033621b09b660b",
    "slope": "9adfbfc26b0cc4e3e9a63af896a1390589cc4e499c72b3b5deaef8dda10584da",
    "fleet": "81b6e926f44ea6e5d552148a5f86bad064aca40cefa0a16620449c3360708e4f",
}


def digest(path: Path) -> str:
    """The run's bits: per tick, the ship ids, the state and output rows as stored, and each
    event's fields (its instant's float bits included)."""
    h = hashlib.sha256()
    for rec in run(parse_text(path.read_text(), str(path))):
        h.update(rec.tick.to_bytes(8, "little"))
        h.update("\0".join(rec.ship_ids).encode())
        for rows in (rec.state.rows, rec.outputs.rows):
            for name in rows.dtype.names:  # field by field: an aligned record's padding is junk
                h.update(np.ascontiguousarray(rows[name]).tobytes())
        for ev in rec.events:
            h.update(repr((ev.tick, ev.ship_id, ev.kind, ev.from_state, ev.to_state,
                           ev.v_radial_mps.hex(), ev.t_event_s.hex())).encode())
    return h.hexdigest()


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_the_run_gives_the_committed_bits(scene):
    assert digest(SCENES[scene]) == EXPECTED[scene], (
        f"{scene}: the bits changed; if that is intended, say why and regenerate "
        "(python tests/test_golden.py) in a commit of its own")


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_the_golden_log_verifies_bit_for_bit(scene):
    log = GOLDEN / f"{scene}.mcap"
    with LogReader(str(log)) as reader:
        assert reader.scenario.log_format_version == LOG_FORMAT_VERSION
    r = CliRunner().invoke(main, ["replay", str(log), "--verify"])
    assert r.exit_code == 0, r.output
    assert "identical" in r.output


OLD = {  # format: (log, project version that wrote it, ships, ticks)
    1: ("bounce-0.2.0.mcap", "0.2.0", 1, None),
    2: ("bounce-0.4.0.mcap", "0.4.0", 1, 601),
    3: ("fleet-0.5.0.mcap", "0.5.0", 3, 41),
    # the golden fleet as 0.6.0 recorded it, keyframes every 5 ticks (at their multiples)
    4: ("fleet-0.6.0-kf5.mcap", "0.6.0", 3, 41),
    # and as 0.7.0 recorded it (its events' tilt from the host's BLAS and libm)
    5: ("fleet-0.7.0-kf5.mcap", "0.7.0", 3, 41),
}


@pytest.mark.parametrize("fmt", sorted(OLD))
def test_every_older_format_stays_readable(fmt, tmp_path):
    """A log of each older format opens, verifies against today's physics with a notice that a
    divergence is expected (the physics changed since), replays into a today's-format log that
    verifies, and exports every tick."""
    name, version, n_ships, n_ticks = OLD[fmt]
    log = DATA / name
    with LogReader(str(log)) as reader:
        assert reader.scenario.log_format_version == fmt
    r = CliRunner().invoke(main, ["replay", str(log), "--verify"])
    assert f"written by touchdown {version}" in r.output, r.output
    assert r.exit_code in (0, 1) and "Traceback" not in r.output
    if r.exit_code == 1:
        assert "divergence is expected" in r.output
    if fmt >= 4:  # its keyframes where format 4 put them (0.8's physics is not 0.6's: issue 35)
        with LogReader(str(log)) as reader:
            assert reader.keyframe_phase == 0 and reader.keyframe_at_or_before(39) == 35
            assert [td.tick for td in reader.ticks() if td.is_keyframe] == list(range(0, 41, 5))
    again = tmp_path / "again.mcap"
    r = CliRunner().invoke(main, ["replay", str(log), "-o", str(again)])
    assert r.exit_code == 0, r.output
    assert CliRunner().invoke(main, ["replay", str(again), "--verify"]).exit_code == 0
    r = CliRunner().invoke(main, ["export", str(log)])
    assert r.exit_code == 0, r.output
    rows = [json.loads(line) for line in r.output.splitlines()]
    assert {row["ship_id"] for row in rows} and len({row["ship_id"] for row in rows}) == n_ships
    if n_ticks is not None:
        assert len({row["tick"] for row in rows}) == n_ticks
    assert all(row["altitude"] is not None for row in rows)


def test_format_3_bounce_log_stays_readable_too():
    r = CliRunner().invoke(main, ["export", "--events", str(DATA / "bounce-0.5.0.mcap")])
    assert r.exit_code == 0, r.output
    kinds = [json.loads(line)["event"] for line in r.output.splitlines()]
    assert kinds[0] == "ship.contact" and "ship.liftoff" in kinds


if __name__ == "__main__":  # regenerate: the logs and the digests to paste into EXPECTED
    for scene, path in SCENES.items():
        out = GOLDEN / f"{scene}.mcap"
        res = CliRunner().invoke(main, ["record", str(path), "-o", str(out)])
        assert res.exit_code == 0, res.output
        print(f'    "{scene}": "{digest(path)}",')
