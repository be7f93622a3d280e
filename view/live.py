"""``touchdown view --redis URL``: the running service's fleet in Rerun, live, from the telemetry
stream as it arrives (``P:telemetry``, service.serve) and the event stream (``P:ships``):

- ``fleet/ships``: every ship seen, at its last sample, in the landing-site frame (east, north,
  up; m), coloured by state (the log view's colours), labelled with its id;
- ``counts/{state}``: how many ships are in each state, over time (``tick`` and ``sim_time``);
- ``events``: the event stream as a text log (transitions, rejections, retirements, the
  autopilot's reports), levels by kind;
- ``health``: the service's health, once a second, from each live worker's stats hash
  (``P:worker:{id}:stats``; the live workers are ``P:service:workers``): ``health/workers`` a
  table of the workers, their shards (each shard's tick and last step time), ships, tick time,
  lag, late ticks, held entries and what they see of Redis; ``health/{worker}/...`` the tick
  time (p50, p99, ms), the lag (s), the late ticks, the held entries and Redis up (1) or not (0),
  over wall-clock time (``service_time``, seconds since the view began).

Telemetry is a rolling slice (each ship once per telemetry period), so the picture is each
ship's latest sample. On a Redis Cluster (found by asking the node of ``--redis``: ``INFO
cluster``) the view reads through a cluster client, and the events from every shard's own
stream (``P:ships:{k}``, the service's shard count from its config), one XREAD per stream: a
cluster refuses one over keys of several slots. Without a display: ``-o OUT.rrd`` records ``--seconds`` of it to a file,
``--screenshot PNG`` renders it with Rerun's headless viewer.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import redis

from touchdown.proto import service_pb2 as spb
from touchdown.service import redis_io as rio
from touchdown.sim.enums import SurfaceState
from touchdown.sim.frames import body_rotation
from touchdown.view.rerun_view import ViewError
from touchdown.view.scene import STATE_COLORS

LEVELS = {"ship.crashed": "ERROR", "ship.tipped": "WARN", "ship.command_rejected": "WARN",
          "ship.autoland_failed": "WARN"}


class Fleet:
    """Each ship's latest sample, in site coordinates."""

    def __init__(self, scene: dict):
        body = scene.get("body", {})
        self.radius = float(body.get("radius", 1737400.0))
        period = float(body.get("rotation_period", 0.0) or 0.0)
        self.omega = 2.0 * math.pi / period if period else 0.0
        self.ships: dict[str, tuple[np.ndarray, int]] = {}
        self.tick = 0
        self.t_s = 0.0

    def add(self, sample: spb.Telemetry) -> None:
        n = len(sample.ship_ids)
        if not n:
            return
        pos = np.array(sample.pos_m, dtype=float).reshape(n, 3)
        # body-centred inertial -> body-fixed (the body turned by omega t about z) -> the site's
        # east (y), north (z), up (x - R): the log view's frame near the site
        c, s = body_rotation(self.omega, sample.t_s)
        x = c * pos[:, 0] + s * pos[:, 1]
        y = -s * pos[:, 0] + c * pos[:, 1]
        site = np.stack([y, pos[:, 2], x - self.radius], axis=1)
        for sid, p, st in zip(sample.ship_ids, site, sample.state):
            self.ships[sid] = (p, int(st))
        self.tick = max(self.tick, int(sample.tick))
        self.t_s = max(self.t_s, float(sample.t_s))

    def drop(self, ship_id: str) -> None:
        self.ships.pop(ship_id, None)


def connect(url: str, password: str | None) -> redis.Redis:
    """A client of the service's Redis (a cluster client on a node of a Redis Cluster); a
    bad URL or a Redis that cannot be reached is a ViewError (exit 2) naming the URL, without
    its password."""
    try:
        client = rio.connect(url, password)
        client.ping()
        if _cluster_enabled(client):  # a node of a Redis Cluster: follow its slot map
            client.close()
            client = rio.connect(url, password, cluster=True)
    except ValueError as exc:
        raise ViewError(f"--redis {rio.redact(url)}: {exc}", exit_code=2) from None
    except redis.exceptions.RedisError as exc:
        raise ViewError(f"redis {rio.redact(url)}: "
                        f"{rio.scrub(str(exc), password, rio.password_of(url))}",
                        exit_code=2) from None
    return client


def _cluster_enabled(client: redis.Redis) -> bool:
    try:
        return bool(int(client.info("cluster").get("cluster_enabled", 0)))
    except (redis.exceptions.RedisError, ValueError, TypeError):
        return False  # (an ACL user without INFO: a single Redis, as before)


def read_streams(client, last: dict, block_ms: int, cluster: bool):
    """New entries of the streams in ``last`` (stream -> the last id seen): one blocking XREAD
    on a single Redis; on a cluster one XREAD per stream (pipelined: a batch per master), and a
    short sleep when none had anything."""
    if not cluster:
        return client.xread(last, count=500, block=block_ms)
    pipe = client.pipeline(transaction=False)
    for stream, after in last.items():
        pipe.xread({stream: after}, count=500)
    out = [r for reply in pipe.execute() for r in (reply or [])]
    if not out:
        time.sleep(min(block_ms, 100) / 1e3)
    return out


class ServiceStreams:
    """What a view of a running service follows: its telemetry stream and event stream(s), from
    their last ``history`` entries on, and its config (its scene and shard count, where this
    client may read them: defaults otherwise). ``batches`` yields each read's entries."""

    def __init__(self, url: str, prefix: str = "galaxy", password: str | None = None,
                 history: int = 2000):
        self.client = connect(url, password)
        self.cluster = not isinstance(self.client, redis.Redis)
        self.keys = rio.Keys(prefix, cluster=self.cluster)
        self.telemetry = self.keys.telemetry
        try:  # (a reader's ACL user may not see the config)
            scene_json = self.client.hget(self.keys.config, "scenario_json") or b""
            self.shards = int(self.client.hget(self.keys.config, "shards") or 1)
        except (redis.exceptions.RedisError, ValueError):
            scene_json, self.shards = b"", 1
        try:
            self.scene = json.loads(scene_json) if scene_json else {}
        except ValueError:
            self.scene = {}
        self.last = {self.telemetry: "0",
                     **{stream: "0" for stream in self.keys.all_events(self.shards)}}
        for stream in self.last:
            tail = self.client.xrevrange(stream, count=history)
            if tail:
                self.last[stream] = entry_before(tail[-1][0].decode())

    def batches(self, seconds: float | None, block_ms: int = 200):
        """Each read's entries as a list of (stream, fields), for ``seconds`` (None: until the
        caller stops); an empty list when nothing came (the caller's periodic work goes on).
        Redis away: a short wait and another read."""
        end = None if seconds is None else time.monotonic() + seconds
        while end is None or time.monotonic() < end:
            block = block_ms if end is None else max(
                1, int(min(block_ms, (end - time.monotonic()) * 1e3)))
            try:
                reply = read_streams(self.client, self.last, block, self.cluster)
            except (redis.exceptions.RedisError, redis.exceptions.RedisClusterException):
                time.sleep(0.25)
                continue
            out = []
            for stream, entries in reply or []:
                stream = stream.decode()
                for entry_id, fields in entries:
                    self.last[stream] = entry_id.decode()
                    out.append((stream, fields))
            yield out

    def close(self) -> None:
        self.client.close()


def follow(rec, url: str, prefix: str = "galaxy", seconds: float | None = None,
           password: str | None = None, history: int = 2000) -> int:
    """Log the fleet into ``rec`` as it arrives, for ``seconds`` (None: until Ctrl-C); starts
    from the last ``history`` telemetry samples and events. Returns the samples drawn."""
    import rerun as rr

    streams = ServiceStreams(url, prefix, password, history)
    fleet = Fleet(streams.scene)
    rec.log("fleet", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    drawn = 0
    begun = time.monotonic()
    next_health = begun
    try:
        for batch in streams.batches(seconds):
            if time.monotonic() >= next_health:
                next_health += 1.0
                try:
                    _health(rr, rec, health(streams.client, streams.keys),
                            time.monotonic() - begun)
                except (redis.exceptions.RedisError, redis.exceptions.RedisClusterException):
                    pass  # (a reader's ACL user may not read the workers' figures)
            changed = False
            for stream, fields in batch:
                if stream == streams.telemetry:
                    sample = spb.Telemetry.FromString(fields.get(b"proto", b""))
                    fleet.add(sample)
                    changed = True
                    drawn += 1
                else:
                    _event(rr, rec, fleet, fields)
            if changed:
                _draw(rr, rec, fleet)
    except KeyboardInterrupt:
        pass
    finally:
        streams.close()
    return drawn


#: a worker's figures the health view plots, by the stats hash's names
HEALTH_SERIES = ("tick_p50_ms", "tick_p99_ms", "lag_s", "late", "held")


def health(client, keys) -> list[dict]:
    """Each live worker's figures (its stats hash, decoded; ``shards`` a dict shard -> (tick,
    step ms)), by worker id."""
    now_s = _server_s(client)
    ids = [w.decode() for w in client.zrangebyscore(keys.workers, now_s, "+inf")]
    pipe = client.pipeline(transaction=False)
    for wid in ids:
        pipe.hgetall(keys.stats(wid))
    out = []
    for wid, raw in zip(ids, pipe.execute()):
        fig = {k.decode(): v.decode() for k, v in (raw or {}).items()}
        ticks = json.loads(fig.get("shard_ticks") or "{}")
        steps = json.loads(fig.get("shard_step_ms") or "{}")
        fig["worker"] = wid
        fig["shards"] = {int(k): (int(t), float(steps.get(k, 0.0))) for k, t in ticks.items()}
        out.append(fig)
    return out


def _server_s(client) -> float:
    t = client.time()
    if isinstance(t, dict):  # a cluster client may answer per node
        t = next(iter(t.values()))
    return t[0] + t[1] * 1e-6


def health_table(workers: list[dict]) -> str:
    """The health view's table (Markdown): a row per live worker."""
    lines = ["| worker | shards (tick, step ms) | ships | tick p50 / p99 ms | lag s | late | "
             "held | redis | logs paused |", "| --- | --- | --- | --- | --- | --- | --- | --- "
             "| --- |"]
    for w in sorted(workers, key=lambda w: w["worker"]):
        shards = ", ".join(f"{k} ({t}, {ms:.1f})" for k, (t, ms) in sorted(w["shards"].items()))
        lines.append(f"| {w['worker']} | {shards or 'none'} | {w.get('ships', '?')} | "
                     f"{w.get('tick_p50_ms', '?')} / {w.get('tick_p99_ms', '?')} | "
                     f"{w.get('lag_s', '?')} | {w.get('late', '?')} | {w.get('held', '?')} | "
                     f"{w.get('redis', '?')} | {w.get('logs_paused', '?')} |")
    if not workers:
        lines.append("| (no live worker) | | | | | | | | |")
    return "\n".join(lines)


def _health(rr, rec, workers: list[dict], t_s: float) -> None:
    if hasattr(rec, "reset_time"):
        rec.reset_time()
    rec.set_time("service_time", duration=t_s)
    rec.log("health/workers", rr.TextDocument(health_table(workers),
                                              media_type=rr.MediaType.MARKDOWN))
    for w in workers:
        for name in HEALTH_SERIES:
            try:
                rec.log(f"health/{w['worker']}/{name}", rr.Scalars(float(w[name])))
            except (KeyError, ValueError):
                pass
        rec.log(f"health/{w['worker']}/redis_up", rr.Scalars(0.0 if w.get("redis") == "down"
                                                             else 1.0))


def entry_before(entry_id: str) -> str:
    """The id just before ``entry_id`` (XREAD returns entries after the id it is given)."""
    ms, seq = (int(x) for x in entry_id.split("-"))
    return f"{ms}-{seq - 1}" if seq else f"{ms - 1}-18446744073709551615"


def _time(rr, rec, tick: int, t_s: float) -> None:
    rec.set_time("tick", sequence=tick)
    rec.set_time("sim_time", duration=t_s)


def _draw(rr, rec, fleet: Fleet) -> None:
    _time(rr, rec, fleet.tick, fleet.t_s)
    ids = list(fleet.ships)
    pos = np.array([fleet.ships[s][0] for s in ids]) if ids else np.zeros((0, 3))
    states = [fleet.ships[s][1] for s in ids]
    colors = [STATE_COLORS.get(SurfaceState(st), (200, 200, 200)) for st in states]
    labels = ids if len(ids) <= 200 else None
    rec.log("fleet/ships", rr.Points3D(pos, colors=colors, radii=3.0, labels=labels))
    for state in SurfaceState:
        rec.log(f"counts/{state.label}", rr.Scalars(sum(1 for st in states if st == int(state))))


def _event(rr, rec, fleet: Fleet, fields: dict) -> None:
    f = {k.decode(): v.decode("utf-8", "replace") for k, v in fields.items() if k != b"proto"}
    kind = f.get("event", "")
    tick = int(f.get("tick", fleet.tick) or 0)
    rec.set_time("tick", sequence=tick)
    text = f"{kind} {f.get('ship_id', '')} (player {f.get('player_id', '')})"
    if "reason" in f:
        text += f": {f['reason']}"
    if "result" in f:
        text += f": {f['result']}"
    rec.log("events", rr.TextLog(text, level=LEVELS.get(kind, "INFO")))
    if kind == "ship.retired":
        fleet.drop(f.get("ship_id", ""))


def record(url: str, prefix: str, seconds: float, out: Path, password: str | None = None
           ) -> int:
    """``seconds`` of the live view into ``out`` (an .rrd, via ``out.partial``)."""
    import os

    import rerun as rr
    out = Path(out)
    rec = rr.RecordingStream("touchdown-live", recording_id=f"live-{prefix}")
    rec.set_log_time_enabled(False) if hasattr(rec, "set_log_time_enabled") else None
    partial = Path(f"{out}.partial")
    try:
        rec.save(partial)
        n = follow(rec, url, prefix, seconds, password)
        rec.flush()
        rec.disconnect()
        os.replace(partial, out)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return n


def live(url: str, prefix: str, seconds: float | None, password: str | None = None) -> int:
    """Open the native viewer and draw into it as the fleet moves (until Ctrl-C or
    ``seconds``)."""
    import rerun as rr

    from touchdown.view.rerun_view import last_line, start_viewer

    proc, port, err = start_viewer(["--hide-welcome-screen"])
    try:
        time.sleep(2.0)
        if proc.poll() is not None:
            raise ViewError(f"the viewer could not open a window ({last_line(err)}); record the "
                            f"live view with -o OUT.rrd --seconds S, or a picture with "
                            f"--screenshot PNG")
        rec = rr.RecordingStream("touchdown-live", recording_id=f"live-{prefix}")
        rec.connect_grpc(f"rerun+http://127.0.0.1:{port}/proxy")
        return follow(rec, url, prefix, seconds, password)
    finally:
        err.unlink(missing_ok=True)
