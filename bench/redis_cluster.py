"""A private Redis Cluster for the tests, ``bench serve --cluster`` and ``bench chaos``: three
masters (and, if asked, a replica each), each a redis-server on free loopback ports (its client port and its cluster bus port)
with its data and its nodes.conf in a folder of its own (``appendonly yes``; by default fsync
on every write: a master stopped and started again keeps what it acknowledged). A missing
redis-server or redis-cli is a failure, never a skip."""
from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

import redis
from redis.cluster import RedisCluster


def free_ports(n: int) -> list[int]:
    socks, ports = [], []
    for _ in range(n):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        socks.append(s)
        ports.append(s.getsockname()[1])
    for s in socks:
        s.close()
    return ports


class Cluster:
    def __init__(self, folder: Path, masters: int = 3, node_timeout_ms: int = 3000,
                 fsync: str = "always", cpus: set[int] | None = None, replicas: int = 0):
        self.fsync = fsync
        self.cpus = cpus  # the CPUs the masters are pinned to (None: not pinned)
        self.binary = shutil.which("redis-server")
        self.cli = shutil.which("redis-cli")
        if self.binary is None or self.cli is None:
            raise RuntimeError("a Redis Cluster needs redis-server and redis-cli on PATH")
        self.folder = folder
        self.node_timeout_ms = node_timeout_ms
        nodes = masters * (1 + replicas)
        ports = free_ports(2 * nodes)
        self.ports, self.bus = ports[:nodes], ports[nodes:]
        self.masters = masters
        self.procs: list[subprocess.Popen | None] = [None] * nodes
        for i in range(nodes):
            self.start(i)
        for i in range(nodes):
            self._wait(lambda i=i: self._pings(i), 10, f"node {i} to start")
        out = subprocess.run([self.cli, "--cluster", "create",
                              *[f"127.0.0.1:{p}" for p in self.ports],
                              "--cluster-replicas", str(replicas), "--cluster-yes"],
                             capture_output=True, text=True, timeout=60)
        if out.returncode != 0:
            self.stop()
            raise RuntimeError(f"redis-cli --cluster create failed: {out.stdout[-500:]}"
                               f"{out.stderr[-500:]}")
        self.wait_ok()

    @property
    def url(self) -> str:
        return f"redis://127.0.0.1:{self.ports[0]}"

    def start(self, i: int) -> None:
        d = self.folder / f"node-{i}"
        d.mkdir(parents=True, exist_ok=True)
        self.procs[i] = subprocess.Popen(
            [self.binary, "--port", str(self.ports[i]), "--bind", "127.0.0.1", "--dir", str(d),
             "--cluster-enabled", "yes", "--cluster-port", str(self.bus[i]),
             "--cluster-config-file", "nodes.conf",
             "--cluster-node-timeout", str(self.node_timeout_ms),
             "--appendonly", "yes", "--appendfsync", self.fsync, "--save", ""],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            preexec_fn=(lambda c=self.cpus: os.sched_setaffinity(0, c)) if self.cpus else None)

    def kill(self, i: int) -> None:
        p = self.procs[i]
        if p is not None and p.poll() is None:
            p.send_signal(signal.SIGKILL)
            p.wait()

    def restart(self, i: int, down_s: float = 0.5) -> None:
        """Master i SIGKILLed (no goodbye to its clients), then started again on its ports
        with its data; back when the cluster says ok again."""
        self.kill(i)
        time.sleep(down_s)
        self.start(i)
        self._wait(lambda: self._pings(i), 10, f"node {i} to start again")
        self.wait_ok()

    def role(self, i: int) -> str:
        """'master', 'slave' (a replica) or 'down'."""
        try:
            c = redis.Redis(port=self.ports[i], socket_connect_timeout=0.5, socket_timeout=1)
            role = c.execute_command("ROLE")[0]
            c.close()
            return role.decode() if isinstance(role, bytes) else str(role)
        except redis.exceptions.RedisError:
            return "down"

    def wait_promoted(self, dead: int, timeout: float = 30.0) -> None:
        """After master ``dead`` was killed: until a replica has taken its slots and the
        cluster says ok on every node that is up."""
        def ok():
            for i in range(len(self.ports)):
                if i == dead or self.role(i) == "down":
                    continue
                try:
                    c = redis.Redis(port=self.ports[i], socket_connect_timeout=0.5)
                    info = c.cluster("info")
                    c.close()
                except redis.exceptions.RedisError:
                    return False
                text = info if isinstance(info, dict) else {}
                state = text.get("cluster_state") if text else (
                    "ok" if "cluster_state:ok" in str(info) else "fail")
                if state != "ok":
                    return False
            return True
        self._wait(ok, timeout, "a replica to be promoted")

    def move_slot_of(self, key: str) -> str:
        """Move the slot of ``key`` (with every key in it) to another master, as
        ``redis-cli --cluster reshard`` does: SETSLOT IMPORTING / MIGRATING, MIGRATE the keys in
        batches, SETSLOT NODE on both. Returns what moved."""
        c = self.client()
        try:
            slot = c.keyslot(key)
            src = c.get_node_from_key(key)
            masters = [n for n in c.get_primaries() if n.name != src.name]
            dst = masters[0]
            ids = {}
            for n in (src, dst):
                r = redis.Redis(host=n.host, port=n.port)
                ids[n.name] = r.execute_command("CLUSTER", "MYID")
                ids[n.name] = ids[n.name].decode() if isinstance(ids[n.name], bytes) else ids[n.name]
                r.close()
        finally:
            c.close()
        rs = redis.Redis(host=src.host, port=src.port)
        rd = redis.Redis(host=dst.host, port=dst.port)
        try:
            rd.execute_command("CLUSTER", "SETSLOT", slot, "IMPORTING", ids[src.name])
            rs.execute_command("CLUSTER", "SETSLOT", slot, "MIGRATING", ids[dst.name])
            moved = 0
            for _ in range(100_000):
                names = rs.execute_command("CLUSTER", "GETKEYSINSLOT", slot, 10)
                if not names:
                    break
                rs.execute_command("MIGRATE", dst.host, dst.port, "", 0, 5000, "KEYS", *names)
                moved += len(names)
                time.sleep(0.05)  # the service keeps working between batches (ASK, TRYAGAIN)
            for r in (rd, rs):
                r.execute_command("CLUSTER", "SETSLOT", slot, "NODE", ids[dst.name])
            for p in self.ports:
                try:
                    r = redis.Redis(port=p, socket_connect_timeout=0.5)
                    r.execute_command("CLUSTER", "SETSLOT", slot, "NODE", ids[dst.name])
                    r.close()
                except redis.exceptions.RedisError:
                    pass
        finally:
            rs.close()
            rd.close()
        return f"slot {slot}: {moved} keys from {src.name} to {dst.name}"

    def node_of(self, key: str) -> int:
        """Which master holds ``key``'s slot."""
        c = self.client()
        try:
            node = c.get_node_from_key(key)
            return self.ports.index(int(node.port))
        finally:
            c.close()

    def client(self) -> RedisCluster:
        return RedisCluster.from_url(self.url)

    def _pings(self, i: int) -> bool:
        try:
            c = redis.Redis(port=self.ports[i], socket_connect_timeout=0.5)
            ok = c.ping()
            c.close()
            return bool(ok)
        except redis.exceptions.RedisError:
            return False

    def wait_ok(self, timeout: float = 30.0) -> None:
        def ok():
            for p in self.ports:
                try:
                    c = redis.Redis(port=p, socket_connect_timeout=0.5)
                    info = c.cluster("info")
                    c.close()
                except redis.exceptions.RedisError:
                    return False
                state = info.get("cluster_state") if isinstance(info, dict) else None
                if state is None:
                    text = info.decode() if isinstance(info, bytes) else str(info)
                    state = "ok" if "cluster_state:ok" in text else "fail"
                if state != "ok":
                    return False
            return True
        self._wait(ok, timeout, "the cluster to say ok")

    @staticmethod
    def _wait(pred, timeout: float, what: str) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if pred():
                return
            time.sleep(0.05)
        raise RuntimeError(f"timed out waiting for {what}")

    def stop(self) -> None:
        for i in range(len(self.procs)):
            self.kill(i)
