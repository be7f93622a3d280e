"""A real Redis for the tests: the one on 127.0.0.1:6379, or a private redis-server started on a
free port when none answers. In CI (CI=true) a missing Redis is a failure, never a skip."""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time

import pytest
import redis


def _answers(url: str) -> bool:
    try:
        client = redis.Redis.from_url(url, socket_connect_timeout=1)
        ok = client.ping()
        client.close()
        return bool(ok)
    except redis.exceptions.RedisError:
        return False


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="session")
def redis_url():
    url = "redis://127.0.0.1:6379/0"
    if _answers(url):
        yield url
        return
    binary = shutil.which("redis-server")
    proc = None
    if binary:
        port = _free_port()
        workdir = tempfile.mkdtemp(prefix="touchdown-redis-")
        proc = subprocess.Popen([binary, "--port", str(port), "--bind", "127.0.0.1", "--save", "",
                                 "--appendonly", "no", "--dir", workdir],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        url = f"redis://127.0.0.1:{port}/0"
        for _ in range(100):
            if _answers(url):
                break
            time.sleep(0.05)
    if proc is None or not _answers(url):
        if proc is not None:
            proc.kill()
        message = "no Redis on 127.0.0.1:6379 and no redis-server to start"
        if os.environ.get("CI") == "true":
            pytest.fail(message)
        pytest.skip(message)
    try:
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def remove_prefix(url: str, prefix: str) -> None:
    """Delete a test's own keys (``prefix:*``), never anything else: no flush."""
    client = redis.Redis.from_url(url)
    keys = list(client.scan_iter(f"{prefix}:*", count=10_000))
    for i in range(0, len(keys), 1000):
        client.delete(*keys[i:i + 1000])
    client.close()
