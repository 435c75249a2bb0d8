"""Prometheus metrics (text exposition at ``GET /metrics``)."""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram

REGISTRY = CollectorRegistry(auto_describe=True)

_LATENCY = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60)

REQUESTS = Counter("zw_requests_total", "HTTP requests by operation and status",
                   ["operation", "status"], registry=REGISTRY)
REQUEST_SECONDS = Histogram("zw_request_seconds", "HTTP request latency by operation",
                            ["operation"], buckets=_LATENCY, registry=REGISTRY)
COMPUTE_SECONDS = Histogram("zw_compute_seconds", "Compute time of a task by operation",
                            ["operation"], buckets=_LATENCY, registry=REGISTRY)
CACHE = Counter("zw_cache_total", "Task cache lookups by outcome (hit, miss, shared)",
                ["operation", "outcome"], registry=REGISTRY)
POOL_BUSY = Gauge("zw_pool_busy", "Computations running or queued in the pool",
                  registry=REGISTRY)
POOL_CAPACITY = Gauge("zw_pool_capacity", "Computations the pool admits before shedding",
                      registry=REGISTRY)
POOL_SHED = Counter("zw_pool_shed_total", "Requests shed with 503 because the pool was full",
                    registry=REGISTRY)
