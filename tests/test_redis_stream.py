"""record --redis publishes the log's events to a real Redis stream (SPEC.md section 5)."""
import uuid

import redis
from click.testing import CliRunner

from touchdown.cli import main
from touchdown.logs.export import event_rows
from touchdown.logs.reader import LogReader
from touchdown.proto import touchdown_pb2 as pb
from redis_server import redis_url  # noqa: F401  (a pytest fixture)
import pytest

pytestmark = pytest.mark.redis


def test_record_publishes_every_event_in_order(redis_url, tmp_path):  # noqa: F811
    stream = f"test:touchdown:{uuid.uuid4().hex}"
    out = tmp_path / "fleet.mcap"
    r = CliRunner().invoke(main, ["record", "fleet", "--set", "duration=20", "-o", str(out),
                                  "--redis", redis_url, "--stream", stream])
    assert r.exit_code == 0, r.output
    client = redis.Redis.from_url(redis_url)
    try:
        entries = client.xrange(stream)
        with LogReader(out) as reader:
            logged = list(event_rows(reader))
        assert len(entries) == len(logged) > 5
        for (_id, fields), row in zip(entries, logged):
            f = {k.decode(): v for k, v in fields.items()}
            assert f["event"].decode() == row["event"]
            assert f["ship_id"].decode() == row["ship_id"]
            assert f["player_id"].decode() == row["player_id"]
            assert f["body"].decode() == row["body"] == "Luna"
            assert int(f["tick"]) == row["tick"]
            ev = pb.TransitionEvent.FromString(f["proto"])
            assert (ev.event, ev.ship_id, ev.tick) == (row["event"], row["ship_id"], row["tick"])
    finally:
        client.delete(stream)
        client.close()


def test_an_unreachable_redis_is_a_user_error_and_leaves_no_log(tmp_path):
    out = tmp_path / "x.mcap"
    r = CliRunner().invoke(main, ["record", "bounce", "--set", "duration=1", "-o", str(out),
                                  "--redis", "redis://127.0.0.1:1/0"])
    assert r.exit_code == 2
    assert "redis://127.0.0.1:1/0" in r.output and "Traceback" not in r.output
    assert not out.exists() and not (tmp_path / "x.mcap.partial").exists()
