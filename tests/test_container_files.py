"""Dockerfile, .dockerignore, compose.yaml and deploy/nginx.conf, checked without a Docker engine.

What can be checked here is: the instructions' structure (stages, user,
health check, exec-form command), that the build context the Dockerfile
copies exists and is not ignored and is enough to build the project, that
the health-check command really probes a live service, and that compose
wires two replicas to one Redis behind nginx on port 8000.
"""

from __future__ import annotations

import fnmatch
import json
import re
import shlex
import subprocess
import sys
import tomllib
from typing import Any

import pytest

from tests.live_server import ROOT, live_server

yaml = pytest.importorskip("yaml")

DOCKERFILE = ROOT / "Dockerfile"
COMPOSE = ROOT / "compose.yaml"
NGINX = ROOT / "deploy" / "nginx.conf"


def instructions() -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) with continuations joined and comments dropped."""
    out: list[tuple[str, str]] = []
    current = ""
    for raw in DOCKERFILE.read_text().splitlines():
        line = raw.strip()
        if not current and (not line or line.startswith("#")):
            continue
        if line.endswith("\\"):
            current += line[:-1] + " "
            continue
        current += line
        word, _, rest = current.partition(" ")
        out.append((word.upper(), rest.strip()))
        current = ""
    assert not current, "dangling line continuation"
    return out


def stages() -> list[list[tuple[str, str]]]:
    result: list[list[tuple[str, str]]] = []
    for ins in instructions():
        if ins[0] == "FROM":
            result.append([])
        assert result, "instructions before the first FROM"
        result[-1].append(ins)
    return result


def exec_form(args: str) -> list[str]:
    value = json.loads(args)
    assert isinstance(value, list) and all(isinstance(v, str) for v in value), args
    return value


def test_multi_stage_on_python_311_slim() -> None:
    froms = [args for stage in stages() for name, args in stage if name == "FROM"]
    assert len(froms) >= 2
    assert all(f.split()[0] == "python:3.11-slim" for f in froms), froms
    build_name = froms[0].split()[-1]
    assert froms[0].lower().split()[1:] == ["as", build_name.lower()]
    runtime = stages()[-1]
    copies = [args for name, args in runtime if name == "COPY"]
    assert copies and all(c.startswith(f"--from={build_name}") for c in copies), copies
    # The runtime stage installs nothing itself: no compilers, no pip.
    assert not [a for n, a in runtime if n == "RUN" and re.search(r"\bpip\b|apt-get", a)]


def test_runs_as_non_root_with_data_volume() -> None:
    runtime = stages()[-1]
    users = [args for name, args in runtime if name == "USER"]
    assert users, "no USER in the final stage"
    user = users[-1].split(":")[0]
    assert user not in ("root", "0")
    # The user is created in the image, and owns the data directory.
    setup = " ".join(a for n, a in runtime if n == "RUN")
    assert re.search(rf"useradd\b.*\b{re.escape(user)}\b", setup)
    assert re.search(rf"chown\s+{re.escape(user)}", setup) and "/data" in setup
    env = " ".join(a for n, a in runtime if n == "ENV")
    assert re.search(r"\bZW_DATA_DIR=/data\b", env)
    volumes = [a for n, a in runtime if n == "VOLUME"]
    assert volumes and "/data" in exec_form(volumes[-1])
    # USER comes after every RUN: nothing of the final image's runtime is root's.
    names = [n for n, _a in runtime]
    assert max(i for i, n in enumerate(names) if n == "RUN") < names.index("USER")


def test_exec_form_cmd_serves_the_app() -> None:
    cmds = [a for n, a in stages()[-1] if n == "CMD"]
    assert len(cmds) == 1
    assert exec_form(cmds[0]) == ["python", "-m", "uvicorn", "service.main:app",
                                  "--host", "0.0.0.0", "--port", "8000"]
    assert not [a for n, a in instructions() if n == "ENTRYPOINT"]
    assert "8000" in [a for n, a in stages()[-1] if n == "EXPOSE"]


def _healthcheck() -> tuple[list[str], list[str]]:
    checks = [a for n, a in stages()[-1] if n == "HEALTHCHECK"]
    assert len(checks) == 1
    options, sep, command = checks[0].partition("CMD ")
    assert sep, checks[0]
    return shlex.split(options), exec_form(command)


def test_healthcheck_uses_python_against_healthz() -> None:
    options, cmd = _healthcheck()
    assert cmd[:2] == ["python", "-c"]
    assert "http://127.0.0.1:8000/healthz" in cmd[2]
    assert "curl" not in cmd[2] and "wget" not in cmd[2]
    opts = dict(o.lstrip("-").split("=", 1) for o in options)
    assert {"interval", "timeout", "retries"} <= set(opts)


def test_healthcheck_command_really_probes() -> None:
    """The probe exits 0 against a healthy service and non-zero when nothing listens."""
    _options, cmd = _healthcheck()
    with live_server() as server:
        code = cmd[2].replace("127.0.0.1:8000", f"127.0.0.1:{server.port}")
        ok = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=30)
        assert ok.returncode == 0, ok.stderr
        port = server.port
    down = subprocess.run([sys.executable, "-c", cmd[2].replace("8000", str(port))],
                          capture_output=True, timeout=30)
    assert down.returncode != 0


def _ignored(path: str, patterns: list[str]) -> bool:
    return any(fnmatch.fnmatch(path, p) or fnmatch.fnmatch(path.split("/")[0], p)
               for p in patterns)


def test_build_context_is_what_the_build_needs() -> None:
    patterns = [p.strip().rstrip("/") for p in (ROOT / ".dockerignore").read_text().splitlines()
                if p.strip() and not p.startswith("#")]
    for heavy in (".git", ".venv", "data", ".hypothesis"):
        assert _ignored(heavy, patterns), heavy
    # Every COPY source of the build context exists and is not ignored.
    sources: list[str] = []
    for name, args in instructions():
        if name == "COPY" and not args.startswith("--from"):
            parts = args.split()
            sources += [s.rstrip("/") for s in parts[:-1] if not s.startswith("--")]
    for src in sources:
        assert (ROOT / src).exists(), src
        assert not _ignored(src, patterns), src
    # ... and they are the whole of what `pip install .` needs: the metadata,
    # its readme and every package pyproject includes.
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    needed = {"pyproject.toml", project["project"]["readme"]}
    needed |= {inc.rstrip("*") for inc in project["tool"]["setuptools"]["packages"]["find"]
               ["include"]}
    assert needed <= set(sources), needed - set(sources)
    assert re.search(r"pip install[^&]*\s\.(\s|$)", " ".join(
        a for n, a in instructions() if n == "RUN"))


def compose() -> dict[str, Any]:
    doc: dict[str, Any] = yaml.safe_load(COMPOSE.read_text())
    return doc


def test_compose_two_replicas_share_redis_behind_nginx() -> None:
    services = compose()["services"]
    redis = [n for n, s in services.items() if str(s.get("image", "")).startswith("redis:7")]
    assert len(redis) == 1
    redis_name = redis[0]
    apis = [n for n, s in services.items() if "build" in s]
    assert len(apis) == 1
    api_name = apis[0]
    api = services[api_name]
    build = api["build"] if isinstance(api["build"], dict) else {"context": api["build"]}
    assert (COMPOSE.parent / build["context"] / build.get("dockerfile", "Dockerfile")) \
        .resolve() == DOCKERFILE
    assert api["deploy"]["replicas"] == 2
    # a CPU quota the pool sizes itself to, and a PID 1 that reaps the fitting workers
    assert float(api["deploy"]["resources"]["limits"]["cpus"]) >= 1
    assert api.get("init") is True
    # Replicas cannot each publish the same host port: only the balancer publishes.
    assert "ports" not in api
    env = api["environment"]
    env = env if isinstance(env, dict) else dict(e.split("=", 1) for e in env)
    assert re.fullmatch(rf"redis://{redis_name}:6379/\d+", env["ZW_CACHE_URL"])
    assert redis_name in api["depends_on"]

    lbs = [n for n, s in services.items() if str(s.get("image", "")).startswith("nginx")]
    assert len(lbs) == 1
    lb = services[lbs[0]]
    assert [str(p) for p in lb["ports"]] == ["8000:8000"]
    mounts = [v.split(":") for v in lb["volumes"]]
    assert ["./deploy/nginx.conf", "/etc/nginx/nginx.conf", "ro"] in mounts
    assert api_name in lb["depends_on"]
    # Redis is a cache here: no persistence.
    cmd = services[redis_name]["command"]
    assert cmd[cmd.index("--save") + 1] == "" and cmd[cmd.index("--appendonly") + 1] == "no"


def test_nginx_balances_the_api_service() -> None:
    text = NGINX.read_text()
    body = re.sub(r"#[^\n]*", "", text)
    assert body.count("{") == body.count("}")
    api_name = next(n for n, s in compose()["services"].items() if "build" in s)
    upstream = re.search(r"upstream\s+(\w+)\s*\{([^}]*)\}", body)
    assert upstream, "no upstream block"
    assert re.search(rf"server\s+{api_name}:8000\b", upstream.group(2))
    assert re.search(rf"proxy_pass\s+http://{upstream.group(1)}\s*;", body)
    assert re.search(r"listen\s+8000\s*;", body)
    # Big grids pass the balancer: the service applies its own body limit.
    size = re.search(r"client_max_body_size\s+(\d+)([kmg]?)\s*;", body)
    assert size and int(size.group(1)) * {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30}[
        size.group(2)] >= 256 << 20
    assert re.search(r"proxy_set_header\s+X-Request-ID\s", body)
    # Every directive line ends with ';' or opens/closes a block.
    for line in body.splitlines():
        line = line.strip()
        if line and not line.endswith((";", "{", "}")):
            # Only multi-line directives (log_format) may continue.
            assert line.startswith(("log_format", "'")), line
