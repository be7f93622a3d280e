"""A live-service worker's reporter (service.serve.Worker's third part, beside its leases and its
shards' policy): what the worker says of itself, every ``stats_every_s``, as a JSON stats line on
stderr, a stats hash in Redis with a time-out (``view --redis`` reads it), and Prometheus metrics
(``--metrics-port``). It reads the worker's figures and changes nothing of it.
"""
from __future__ import annotations

import json
import math
import time
from typing import NamedTuple

from touchdown.service import redis_io as rio
from touchdown.sim import __version__ as PROJECT_VERSION


class Counts(NamedTuple):
    """Commands applied and rejected, and rejections counted but not published."""

    applied: int = 0
    rejected: int = 0
    unpublished: int = 0


class Reporter:
    """The figures of ``worker`` (service.serve.Worker): :meth:`figures`, said by :meth:`report`
    when due; the metrics served on ``metrics_port`` (None: none; a port that cannot be served
    raises ``error``, the worker's one-line refusal)."""

    def __init__(self, worker, metrics_port: int | None,
                 error: type[Exception] = OSError):
        self.worker = worker
        self._error = error
        self.next_at = time.monotonic() + worker.cfg.stats_every_s
        #: (when, commands read, entries sent) at the last report: the rates' start
        self._last = (time.monotonic(), 0, 0)
        #: the counts of the shards this worker no longer owns (handed over, lost)
        self._gone = Counts()
        self.metrics: dict | None = None
        self._server = None
        if metrics_port is not None:
            self._start_metrics(metrics_port)

    def due(self) -> bool:
        return time.monotonic() >= self.next_at

    def tick_took(self, seconds: float) -> None:
        """A loop's working time (the tick histogram)."""
        if self.metrics:
            self.metrics["tick"].observe(seconds)

    def keep_counts(self, o) -> None:
        """A shard leaves this worker: its counts stay in the worker's totals."""
        c = o.shard.counts
        g = self._gone
        self._gone = Counts(g.applied + c.applied, g.rejected + c.rejected,
                            g.unpublished + c.unpublished)

    # -- what is said ------------------------------------------------------------------------------
    def figures(self) -> dict:
        """What the stats line, the stats hash and the metrics say."""
        w = self.worker
        now = time.monotonic()
        recent = sorted(d for t, d in w.stats.recent if t >= now - 60.0)
        pct = (lambda q: recent[min(len(recent) - 1, int(q * len(recent)))] * 1e3
               ) if recent else (lambda q: 0.0)
        counts = [o.shard.counts for o in w.owned.values()]
        applied = sum(c.applied for c in counts) + self._gone.applied
        rejected = sum(c.rejected for c in counts) + self._gone.rejected
        unpublished = sum(c.unpublished for c in counts) + self._gone.unpublished
        t0, c0, e0 = self._last
        span = max(1e-9, now - t0)
        cmds = w.stats.commands_read
        fig = {
            "tick": max((o.shard.tick for o in w.owned.values()), default=0),
            "ticks": w.stats.ticks, "lag_s": round(w.stats.lag_s, 4),
            "tick_p50_ms": round(pct(0.5), 3), "tick_p99_ms": round(pct(0.99), 3),
            "late": w.stats.late,
            "late_share": round(min(1.0, w.stats.late / max(1, w.stats.ticks)), 4),
            "ships": sum(o.shard.world.state.n for o in w.owned.values()),
            "shards": len(w.owned),
            "held": sum(len(o.unsent) + len(o.backlog) + len(o.results)
                        for o in w.owned.values()),
            "commands_per_s": round((cmds - c0) / span, 1),
            "events_per_s": round((w.stats.entries_sent - e0) / span, 1),
            "applied": applied, "rejected": rejected, "rejections_unpublished": unpublished,
            # events lost: dropped from a full buffer while Redis was away (the logs have them)
            "dropped": w.stats.entries_dropped,
            "redis": "up" if w.redis_up and w._refused is None else
                     ("refusing" if w.redis_up else "down"),
            "redis_down_s": round(now - w._down_since, 1) if not w.redis_up else 0.0,
            "logs_paused": sum(o.shard.log.paused for o in w.owned.values()),
            # each shard this worker owns: its tick and the wall time of its last step
            "shard_ticks": json.dumps({str(k): o.shard.tick for k, o in
                                       sorted(w.owned.items())}),
            "shard_step_ms": json.dumps({str(k): round(o.step_s * 1e3, 3) for k, o in
                                         sorted(w.owned.items())}),
            "version": PROJECT_VERSION,
        }
        return fig

    def report(self) -> None:
        """The stats line, the metrics, and (Redis answering) the stats hash."""
        w = self.worker
        self.next_at = time.monotonic() + w.cfg.stats_every_s
        fig = self.figures()
        self._last = (time.monotonic(), w.stats.commands_read, w.stats.entries_sent)
        w.log("stats", "info", **fig)
        if self.metrics:
            self._set_metrics(fig)
        if w.redis_up:
            w._redis(w.store.write_stats, fig, max(1, int(math.ceil(3 * w.cfg.stats_every_s))))

    def close(self) -> None:
        if self._server is not None:
            self._server.shutdown()

    # -- Prometheus ----------------------------------------------------------------------------
    def _set_metrics(self, fig: dict) -> None:
        w = self.worker
        m, seen = self.metrics, self._seen
        m["ships"].set(fig["ships"])
        m["shards"].set(fig["shards"])
        m["lag"].set(fig["lag_s"])
        m["held"].set(fig["held"])
        m["tick_no"].set(fig["tick"])
        m["redis_up"].set(0 if fig["redis"] == "down" else 1)
        for state in ("up", "refusing", "down"):
            m["redis_state"].labels(state).set(1 if fig["redis"] == state else 0)
        m["logs_paused"].set(fig["logs_paused"])
        now_shards = set()
        for k, o in w.owned.items():
            now_shards.add(str(k))
            m["shard_tick"].labels(str(k), w.id).set(o.shard.tick)
            m["shard_step"].labels(str(k), w.id).set(o.step_s)
        for k in self._shards - now_shards:  # a shard gone: its series too
            m["shard_tick"].remove(k, w.id)
            m["shard_step"].remove(k, w.id)
        self._shards = now_shards
        for name, value in (("applied", fig["applied"]), ("rejected", fig["rejected"]),
                            ("dropped", fig["dropped"]),
                            ("unpublished", fig["rejections_unpublished"]),
                            ("events", w.stats.entries_sent), ("late", fig["late"])):
            if value > seen[name]:
                m[name].inc(value - seen[name])
                seen[name] = value

    def _start_metrics(self, port: int) -> None:
        from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram
        from prometheus_client import start_http_server

        reg = CollectorRegistry()
        m = {
            "tick": Histogram("touchdown_tick_seconds", "working time of a tick",
                              buckets=(.001, .0025, .005, .01, .025, .05, .075, .1, .25, .5, 1,
                                       2.5, 5, 10), registry=reg),
            "ships": Gauge("touchdown_ships", "ships this worker steps", registry=reg),
            "shards": Gauge("touchdown_shards", "shards this worker owns", registry=reg),
            "late": Counter("touchdown_late_ticks", "ticks begun a period or more late",
                            registry=reg),
            "lag": Gauge("touchdown_lag_seconds", "how far behind schedule the last tick began",
                         registry=reg),
            "applied": Counter("touchdown_commands_applied", "commands applied", registry=reg),
            "rejected": Counter("touchdown_commands_rejected", "commands rejected (published "
                                "or only counted)", registry=reg),
            "events": Counter("touchdown_events_published", "entries put on the event stream",
                              registry=reg),
            "dropped": Counter("touchdown_dropped", "events lost: dropped from a full buffer "
                               "while Redis was away (the flight logs have them)", registry=reg),
            "unpublished": Counter("touchdown_rejections_unpublished", "rejections counted, "
                                   "not published (past a sender's cap in a tick)",
                                   registry=reg),
            "redis_up": Gauge("touchdown_redis_up", "1 while Redis answers, 0 while it is "
                              "unreachable (or its replies time out)", registry=reg),
            "redis_state": Gauge("touchdown_redis_state", "1 for the state Redis is in, as "
                                 "this worker sees it: up, refusing (OOM, NOPERM, READONLY, "
                                 "...) or down", ["state"], registry=reg),
            "logs_paused": Gauge("touchdown_logs_paused", "shards whose flight log is paused "
                                 "(disk full, unwritable)", registry=reg),
            "shard_tick": Gauge("touchdown_shard_tick", "the tick of each shard this worker "
                                "owns", ["shard", "worker"], registry=reg),
            "shard_step": Gauge("touchdown_shard_step_seconds", "the wall time of each owned "
                                "shard's last step", ["shard", "worker"], registry=reg),
            "held": Gauge("touchdown_held_entries", "entries and requests waiting for Redis",
                          registry=reg),
            "tick_no": Gauge("touchdown_tick", "the latest tick of this worker's shards",
                             registry=reg),
        }
        from prometheus_client import Info
        import platform
        import redis as redis_py
        from touchdown.sim.fields import LOG_FORMAT
        Info("touchdown_build", "the build this worker runs", registry=reg).info({
            "version": PROJECT_VERSION, "log_format": str(LOG_FORMAT),
            "checkpoint_format": str(rio.CHECKPOINT_FORMAT), "python": platform.python_version(),
            "redis_py": redis_py.__version__, "worker": self.worker.id})
        try:
            out = start_http_server(port, addr="127.0.0.1", registry=reg)
        except OSError as exc:
            raise self._error(f"--metrics-port {port}: {exc.strerror or exc}") from None
        self._server = out[0] if isinstance(out, tuple) else None
        self.metrics = m
        self._seen = {"applied": 0, "rejected": 0, "dropped": 0, "events": 0, "late": 0,
                      "unpublished": 0}
        self._shards: set = set()


__all__ = ["Counts", "Reporter"]
