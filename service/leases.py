"""A live-service worker's leases (service.serve.Worker's first part, beside its shards' policy
and its reporter): its heartbeat and every lease it holds, renewed every lease / 4 on a thread
and a connection of their own, whatever the tick is doing (a long tick never loses a lease it
holds); and the round, run by the loop, that takes free shards up to a fair share of the live
workers and hands the extra ones over.

What the renewals find is handed to the loop (:meth:`Leases.take_lost`: a lease another worker
took; :meth:`Leases.take_gone`: a shard whose state Redis lost); taking a shard over and handing
one over are the worker's own (its shards' policy: ``Worker._take_over``, ``_hand_over``).
"""
from __future__ import annotations

import gc
import math
import threading
import time

from touchdown.service.store import ERRORS, UNREACHABLE, Fence


class Leases:
    """The leases of ``worker`` (service.serve.Worker). ``refused``: the error a take-over
    raises for a shard this worker cannot take (a checkpoint it cannot read): that shard's lease
    is freed and the round goes on."""

    def __init__(self, worker, refused: type[Exception]):
        self.worker = worker
        self._refused = refused
        self.lease_ms = int(worker.cfg.lease_s * 1000)
        #: the fence of each shard owned or being taken (every owner-only script checks it)
        self.fences: dict[int, Fence] = {}
        self.taking: set[int] = set()  # shards being taken over (their leases renewed too)
        self.take_after = 0.0  # no shard of another worker is taken before (after an outage)
        self.next_round = 0.0  # when the loop runs the next round (:meth:`round`)
        self.live = 1  # live workers, as the last heartbeat counted them
        self._lost: set[int] = set()  # found by a renewal: another worker's now
        self._gone: set[int] = set()  # found by a renewal: their epoch gone (Redis lost them)
        self._started = time.monotonic()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        # held by a renewal from reading the fences to its reply, and by a release while it
        # takes its shard out of them: RENEW takes a lapsed lease back, so a renewal that read
        # the fences before a release and ran after it would take the freed lease again
        self._renewing = threading.Lock()

    # -- the renewal thread ------------------------------------------------------------------------
    def start(self) -> None:
        self._thread = threading.Thread(target=self._renew_loop, daemon=True,
                                        name=f"touchdown-leases-{self.worker.id}")
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def take_lost(self) -> set[int]:
        """The shards a renewal found another worker's since the last call."""
        lost, self._lost = self._lost, set()
        return lost

    def take_gone(self) -> set[int]:
        """The shards a renewal found gone from Redis (their epoch) since the last call."""
        gone, self._gone = self._gone, set()
        return gone

    def forget(self, k: int) -> None:
        """Shard k is no longer this worker's (lost): not renewed again."""
        self.fences.pop(k, None)

    def release(self, k: int, fence: Fence) -> None:
        """Free shard k's lease (handed over, stopping, not taken): out of the renewals first,
        once no renewal that read it is in flight, then RELEASE; renewed again if RELEASE
        fails (the shard is still this worker's)."""
        with self._renewing:
            self.fences.pop(k, None)
        try:
            self.worker.store.release(k, fence)
        except BaseException:
            self.fences[k] = fence
            raise

    def _renew_loop(self) -> None:
        """Renew this worker's heartbeat and leases every lease / 4 on a connection of its own.
        A lease found lost is handed to the loop (:meth:`take_lost`)."""
        w = self.worker
        cfg = w.cfg
        keeper = None
        try:
            while not self._stop.is_set():
                try:
                    if keeper is None:
                        keeper = w.store.lease_keeper(timeout=max(0.2, cfg.lease_s / 4))
                    self.live = keeper.heartbeat(cfg.lease_s)
                    with self._renewing:
                        # (and a shard being taken: restoring a large one outlasts a lease)
                        fences = dict(self.fences)
                        order = sorted(k for k in set(w.owned) | self.taking if k in fences)
                        kept = keeper.renew([(k, fences[k].epoch) for k in order],
                                            self.lease_ms)
                    self._lost.update(k for k, ok in zip(order, kept) if ok == 0)
                    self._gone.update(k for k, ok in zip(order, kept) if ok == -3)
                except UNREACHABLE:
                    pass  # the loop says Redis is away
                except (*ERRORS, RuntimeError) as exc:
                    w.log_every("leases", f"redis {w.where}: leases not renewed "
                                f"({w._text(exc)}): shards will pass to other workers", "error")
                self._stop.wait(cfg.lease_s / 4)
        finally:
            if keeper is not None:
                keeper.close()

    # -- the round (the loop's) ----------------------------------------------------------------
    def round(self) -> None:
        """Hand one shard over if this worker holds more than its fair share (once a lease has
        passed since it started), then take free shards, in order, up to that share (not until
        ``take_after``: after an outage the owners take their own shards back first)."""
        w = self.worker
        cfg = w.cfg
        live = w.store.live_workers()
        share = math.ceil(cfg.shards / max(1, live))
        if cfg.max_shards is not None:
            share = min(share, cfg.max_shards)
        if len(w.owned) > share and time.monotonic() - self._started > cfg.lease_s:
            w._hand_over(max(w.owned))
        if time.monotonic() < self.take_after:
            return
        for k in range(cfg.shards):
            if len(w.owned) >= share:
                break
            if k in w.owned:
                continue
            taken_at = time.monotonic()
            fence = w.store.take_lease(k, self.lease_ms)
            if fence:
                self.fences[k] = fence
                self.taking.add(k)  # the renewal thread renews it meanwhile
                try:
                    w._take_over(k, fence)
                except self._refused as exc:  # (a checkpoint this worker cannot read)
                    self.release(k, fence)
                    w.log_every(f"take:{k}", f"shard {k}: not taken: {exc}", "error")
                    continue
                except BaseException:
                    try:
                        self.release(k, fence)
                    finally:
                        self.fences.pop(k, None)
                    raise
                finally:
                    self.taking.discard(k)
                w.owned[k].taken_at = taken_at
                # what a take-over built (the ships' tables, ids, the log's header cache: a
                # million objects at 50,000 ships) lives as long as the shard: out of the
                # collector's sight, a full collection no longer walks it (a pause of tens of
                # milliseconds in whichever tick it struck); reference counting still frees it
                gc.freeze()


__all__ = ["Leases"]
