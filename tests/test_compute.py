"""The compute pool's worker processes (Python-bound work: arc fitting)."""

from __future__ import annotations

import asyncio
import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from service.compute import ComputePool
from service.problems import Problem
from tests.conftest import make_client
from zwcore.errors import InvalidInputError, LimitExceededError, PlanningError, ZwError


@pytest.mark.parametrize("cls", [ZwError, InvalidInputError, LimitExceededError, PlanningError])
def test_core_errors_survive_pickling(cls: type[ZwError]) -> None:
    err = pickle.loads(pickle.dumps(cls("points", "fewer than two distinct points")))
    assert type(err) is cls
    assert (err.field, err.reason) == ("points", "fewer than two distinct points")
    assert str(err) == "points: fewer than two distinct points"


def _die() -> None:
    os._exit(3)


def test_in_process_jobs_run_elsewhere_and_a_dead_worker_costs_only_its_job() -> None:
    async def scenario() -> None:
        pool = ComputePool(1, 2, processes=1)
        try:
            here = os.getpid()
            assert await pool.run("op", os.getpid) == here  # threads: this process
            worker = await pool.run("op", os.getpid, in_process=True)
            assert worker != here
            with pytest.raises(Problem) as lost:
                await pool.run("op", _die, in_process=True)
            assert lost.value.status == 503 and lost.value.headers["Retry-After"]
            assert pool.busy == 0
            # fresh workers serve the next job
            assert await pool.run("op", os.getpid, in_process=True) not in (here, worker)
        finally:
            pool.shutdown()

    asyncio.run(scenario())


def test_core_errors_from_a_worker_are_problems_naming_the_field(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with make_client(tmp_path, process_workers=1) as c:
        ok = c.post("/v1/arcs", json={"points": [[0, 0], [10, 0], [20, 1]], "tolerance": 0.1})
        assert ok.status_code == 200, ok.text
        assert ok.json()["summary"]["n_segments"] >= 1
        # distinct for the schema, one point for the fitter (1e-12 apart at tolerance 0.1)
        r = c.post("/v1/arcs", json={"points": [[1, 1], [1, 1 + 1e-12]], "tolerance": 0.1})
        assert r.status_code == 422, r.text
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["errors"][0]["field"] == "points"


@pytest.mark.parametrize(("files", "expected"), [
    ({"cpu.max": "150000 100000\n"}, 1.5),          # cgroup v2, docker --cpus 1.5
    ({"cpu.max": "max 100000\n"}, None),            # v2, unlimited
    ({"cpu/cpu.cfs_quota_us": "200000\n", "cpu/cpu.cfs_period_us": "100000\n"}, 2.0),  # v1
    ({"cpu/cpu.cfs_quota_us": "-1\n", "cpu/cpu.cfs_period_us": "100000\n"}, None),
    ({}, None),                                     # no cgroup files: not limited
])
def test_cpu_quota_of_the_container_is_read(tmp_path, files: dict[str, str],  # type: ignore[no-untyped-def]
                                            expected: float | None) -> None:
    from service.settings import _cgroup_cpu_limit

    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    assert _cgroup_cpu_limit(tmp_path) == expected


def test_pool_size_follows_the_quota(monkeypatch: pytest.MonkeyPatch) -> None:
    from service import settings

    monkeypatch.setattr(settings, "_cgroup_cpu_limit", lambda: 0.5)
    assert settings._cpu_count() == 1
    monkeypatch.setattr(settings, "_cgroup_cpu_limit", lambda: 1.5)
    assert settings._cpu_count() == min(2, len(os.sched_getaffinity(0)))
    monkeypatch.setattr(settings, "_cgroup_cpu_limit", lambda: None)
    assert settings._cpu_count() == len(os.sched_getaffinity(0))


def _gone(pid: int, within: float) -> bool:
    """The process has exited (or is a zombie waiting to be reaped) within ``within`` s.
    Judged from /proc's own status line, independently of the watchdog under test."""
    import time
    from pathlib import Path

    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            status = Path(f"/proc/{pid}/status").read_text()
        except FileNotFoundError:
            return True
        if "\nState:\tZ" in status:
            return True
        time.sleep(0.05)
    return False


def test_shutdown_stops_a_worker_in_the_middle_of_a_long_job() -> None:
    import time

    async def scenario() -> int:
        pool = ComputePool(1, 2, processes=1)
        worker = await pool.run("op", os.getpid, in_process=True)
        job = asyncio.ensure_future(pool.run("op", time.sleep, 60, in_process=True))
        await asyncio.sleep(0.3)  # the worker is inside the sleep
        pool.shutdown()
        job.cancel()
        return worker

    worker = asyncio.run(scenario())
    assert _gone(worker, within=10), "worker left running after shutdown"


def test_workers_exit_when_the_server_is_killed_hard() -> None:
    """A server killed with SIGKILL runs no shutdown: its workers must notice alone."""
    import subprocess
    import sys

    script = (
        "import asyncio, os, signal\n"
        "from service.compute import ComputePool\n"
        "async def main():\n"
        "    pool = ComputePool(1, 1, processes=2)\n"
        "    pids = {await pool.run('op', os.getpid, in_process=True) for _ in range(4)}\n"
        "    print(*pids, flush=True)\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
        "asyncio.run(main())\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, timeout=60,
                         cwd=os.path.dirname(os.path.dirname(__file__)))
    pids = [int(p) for p in out.stdout.split()]
    assert pids, out.stderr.decode()
    for pid in pids:
        assert _gone(pid, within=10), f"worker {pid} outlived its server"


def test_workers_start_with_the_service_when_asked(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # a cold worker costs seconds of CPU: paid at start, not by the first arc request
    with make_client(tmp_path, process_workers=1, prestart_workers=True) as c:
        pool = c.app.state.pool  # type: ignore[attr-defined]
        assert pool._process_pool is not None and pool._process_pool.active
        # the service served only once its worker had answered (another process)
        (pid,) = c.app.state.worker_pids  # type: ignore[attr-defined]
        assert pid != os.getpid()
        (job,) = pool.start_processes()  # one more no-op on the already started worker
        assert job.result(timeout=60) not in (os.getpid(), None)
    with make_client(tmp_path, process_workers=1) as c:  # tests' default: on first use
        assert c.app.state.pool._process_pool is None  # type: ignore[attr-defined]


def test_worker_processes_preload_every_process_jobs_module() -> None:
    """Every function the routers run in a worker process lives in a module the forkserver
    imports before forking (else each worker's first job imports the web stack)."""
    from service import cadfiles
    from service.compute import PROCESS_JOB_MODULES
    from service.routers import arcs

    jobs = [arcs.arcs_result, cadfiles.gcode_result, cadfiles.dxf_result]
    code = ("import importlib, sys\n"
            f"for m in {list(PROCESS_JOB_MODULES)!r}: importlib.import_module(m)\n"
            f"print(all(m in sys.modules for m in {[f.__module__ for f in jobs]!r}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).resolve().parents[1])
    assert out.stdout.strip() == "True"
