"""A real uvicorn process serving ``service.main:app`` for black-box tests and the benchmark.

Use :func:`live_server` as a context manager (or the ``live_server_url``
fixture in the modules that need one)::

    with live_server(env={"ZW_MAX_GRID_CELLS": "4096"}) as server:
        httpx.get(server.url + "/healthz")

The server runs on 127.0.0.1 at a free port with its own temporary
``ZW_DATA_DIR``; its stderr (the JSON access log) is kept in a file that
:attr:`LiveServer.log_text` reads.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@dataclass
class LiveServer:
    url: str
    port: int
    data_dir: Path
    log_path: Path
    process: subprocess.Popen[bytes]

    def log_text(self) -> str:
        return self.log_path.read_text(errors="replace")


def _wait_healthy(url: str, process: subprocess.Popen[bytes], log_path: Path,
                  timeout: float) -> None:
    deadline = time.monotonic() + timeout
    last: Exception | None = None
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"uvicorn exited with {process.returncode}:\n"
                               + log_path.read_text(errors="replace")[-4000:])
        try:
            r = httpx.get(url + "/healthz", timeout=1.0)
            if r.status_code == 200:
                return
        except httpx.HTTPError as exc:
            last = exc
        time.sleep(0.05)
    raise RuntimeError(f"uvicorn did not become healthy in {timeout} s ({last!r}):\n"
                       + log_path.read_text(errors="replace")[-4000:])


@contextmanager
def live_server(env: Mapping[str, str] | None = None, *, data_dir: Path | None = None,
                startup_timeout: float = 30.0,
                uvicorn_args: Sequence[str] = ("--no-access-log", "--log-level", "warning"),
                ) -> Iterator[LiveServer]:
    """Start ``python -m uvicorn service.main:app``, wait for /healthz, stop it on exit.

    ``uvicorn_args`` are uvicorn's logging options; ``()`` runs it as the image's
    command does (access log on, level info).

    ``env`` adds or overrides ``ZW_*`` settings; any ``ZW_*`` variable of the
    calling environment is dropped first so the server sees only what the
    caller chose.
    """
    with tempfile.TemporaryDirectory(prefix="zw-live-") as tmp:
        tmp_path = Path(tmp)
        data = data_dir or tmp_path / "data"
        log_path = tmp_path / "server.log"
        port = free_port()
        child_env = {k: v for k, v in os.environ.items() if not k.startswith("ZW_")}
        child_env.update({"ZW_DATA_DIR": str(data), "PYTHONUNBUFFERED": "1"})
        child_env.update(env or {})
        with open(log_path, "wb") as log:
            process = subprocess.Popen(
                [sys.executable, "-m", "uvicorn", "service.main:app", "--host", "127.0.0.1",
                 "--port", str(port), *uvicorn_args],
                cwd=ROOT, env=child_env, stdout=log, stderr=subprocess.STDOUT)
        url = f"http://127.0.0.1:{port}"
        try:
            _wait_healthy(url, process, log_path, startup_timeout)
            yield LiveServer(url=url, port=port, data_dir=data, log_path=log_path,
                             process=process)
        finally:
            process.terminate()
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=10)
