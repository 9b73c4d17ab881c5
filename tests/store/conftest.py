"""Fixtures of the store tests: a moto S3 server and a bucket of one's own on it."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import pytest


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def s3_env():
    """A moto S3 server for this module, and the environment that points fsspec at it (the
    way a user configures an endpoint: FSSPEC_S3_ENDPOINT_URL and AWS credentials)."""
    port = _free_port()
    server = subprocess.Popen(
        [sys.executable, "-m", "moto.server", "-H", "127.0.0.1", "-p", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    env = {
        "AWS_ACCESS_KEY_ID": "testing",
        "AWS_SECRET_ACCESS_KEY": "testing",
        "AWS_DEFAULT_REGION": "us-east-1",
        "FSSPEC_S3_ENDPOINT_URL": f"http://127.0.0.1:{port}",
    }
    try:
        deadline = time.time() + 60
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.time() < deadline, "moto's server did not start"
                time.sleep(0.2)
        yield env
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)


@pytest.fixture()
def s3(s3_env, monkeypatch, tmp_path):
    """This process pointed at the server (fsspec reads its FSSPEC_* configuration when a
    filesystem is made), with an empty bucket of its own; yields the bucket's URL."""
    import fsspec
    import s3fs

    for key, value in s3_env.items():
        monkeypatch.setenv(key, value)
    monkeypatch.setitem(fsspec.config.conf, "s3", {"endpoint_url": s3_env["FSSPEC_S3_ENDPOINT_URL"]})
    s3fs.S3FileSystem.clear_instance_cache()
    bucket = f"b{tmp_path.name.lower().replace('_', '-')[-40:]}".strip("-")
    s3fs.S3FileSystem().mkdir(bucket)
    return f"s3://{bucket}"
