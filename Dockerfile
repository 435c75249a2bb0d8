# syntax=docker/dockerfile:1
# zwplan service image: `docker build -t zwplan .` then
# `docker run --init -p 8000:8000 -v zwdata:/data zwplan` (or `docker compose up` for
# two replicas behind nginx sharing Redis; see compose.yaml).

# --- build: install the project and its dependencies into a virtualenv -------
FROM python:3.11-slim AS build

ENV PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PYTHONDONTWRITEBYTECODE=1

RUN python -m venv /opt/venv
ENV PATH=/opt/venv/bin:$PATH

WORKDIR /src
# The project's own metadata names every runtime dependency (pyproject.toml);
# README.md is its declared readme, needed to build it.
COPY pyproject.toml README.md ./
COPY zwcore/ zwcore/
COPY service/ service/
# numba compiles the kernels once here (about 10 s of CPU) into a cache the runtime
# reads: the installed package is read-only for the service's user, and without the
# cache every server start would compile them again.
ENV NUMBA_CACHE_DIR=/opt/venv/numba-cache
RUN pip install --upgrade pip setuptools wheel \
 && pip install . \
 && python -c "import service.main, zwcore.arcs.warmup; from zwcore.scanline.warmup import warm_up; warm_up()"

# --- runtime: the virtualenv only, run as an unprivileged user ---------------
FROM python:3.11-slim AS runtime

ENV PATH=/opt/venv/bin:$PATH \
    PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    NUMBA_CACHE_DIR=/opt/venv/numba-cache \
    ZW_DATA_DIR=/data

RUN groupadd --system --gid 10001 zwplan \
 && useradd --system --uid 10001 --gid zwplan --home-dir /nonexistent \
      --no-create-home --shell /usr/sbin/nologin zwplan \
 && mkdir -p /data \
 && chown zwplan:zwplan /data

COPY --from=build /opt/venv /opt/venv
# numba refuses a cache directory it cannot write (no locator, import fails): the
# service's user owns it, so kernels compiled later (new signatures) are cached too.
RUN chown -R zwplan:zwplan /opt/venv/numba-cache

WORKDIR /app
USER zwplan:zwplan

# The embedded task store (unused when ZW_CACHE_URL points at Redis).
VOLUME ["/data"]
EXPOSE 8000

# No curl in the slim image: probe /healthz with the interpreter itself.
HEALTHCHECK --interval=15s --timeout=5s --start-period=20s --retries=3 \
  CMD ["python", "-c", "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status == 200 else 1)"]

CMD ["python", "-m", "uvicorn", "service.main:app", "--host", "0.0.0.0", "--port", "8000"]
