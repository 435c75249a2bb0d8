"""The viewer page in a real headless browser (Playwright driving Debian's Chromium).

Skips where no browser is installed (``.ci/run`` installs the ``chromium`` package,
best effort). The page loads, a scan-line plan of a small z-map runs from the
page, the stage table and the preview picture appear, and the browser logs no
error; an .npy file picked in the page is parsed by its own reader and planned, an STL
becomes a z-map task that a plan names.
"""

from __future__ import annotations

import io
import shutil
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest

from tests.live_server import LiveServer, live_server
from tests.test_service_zmaps import steps_stl

playwright_api = pytest.importorskip("playwright.sync_api")
BROWSER = next((p for p in (shutil.which("chromium"), shutil.which("chromium-browser"),
                            "/usr/bin/chromium") if p and Path(p).exists()), None)
pytestmark = pytest.mark.skipif(BROWSER is None, reason="no Chromium installed")


@pytest.fixture(scope="module")
def server() -> Iterator[LiveServer]:
    # arcs fitted in the threads: no worker processes to start for one small curve
    with live_server({"ZW_MAX_GRID_CELLS": "65536", "ZW_PROCESS_WORKERS": "0"}) as s:
        yield s


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    with playwright_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=BROWSER, headless=True,
                               args=["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"])
        yield b
        b.close()


def _page(browser: object, errors: list[str]):  # type: ignore[no-untyped-def]
    page = browser.new_page()  # type: ignore[attr-defined]
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.set_default_timeout(30_000)
    return page


def _preview_decoded(page, selector: str) -> None:  # type: ignore[no-untyped-def]
    page.wait_for_function(
        f"document.querySelector('{selector}').complete && "
        f"document.querySelector('{selector}').naturalWidth > 300")


def test_root_redirects_and_static_files(server: LiveServer) -> None:
    r = httpx.get(server.url + "/", follow_redirects=False)
    assert r.status_code == 307 and r.headers["location"] == "/viewer"
    page = httpx.get(server.url + "/viewer")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "http://" not in page.text and "https://" not in page.text  # nothing from elsewhere
    js = httpx.get(server.url + "/static/viewer.js")
    assert js.status_code == 200 and "https://" not in js.text
    assert httpx.get(server.url + "/static/secret.py").status_code == 404


def test_a_plan_runs_from_the_page(server: LiveServer, browser: object) -> None:
    errors: list[str] = []
    page = _page(browser, errors)
    page.goto(server.url + "/viewer")
    page.wait_for_function("document.getElementById('tools').value.includes('ball')")
    page.click("#synthetic")
    page.click("#run-scanline")
    page.wait_for_selector("#stages tbody tr")
    _preview_decoded(page, "#preview")
    rows = page.locator("#stages tbody tr")
    assert rows.count() >= 1
    assert page.inner_text("#status") == "scanline plan done"
    assert "checks ok" in page.inner_text("#plan-info")
    # a stage alone
    rows.first.click()
    _preview_decoded(page, "#preview")
    assert errors == []
    page.close()


def test_npy_file_and_curve_from_the_page(server: LiveServer, browser: object,
                                          tmp_path: Path) -> None:
    errors: list[str] = []
    page = _page(browser, errors)
    page.goto(server.url + "/viewer")
    y, x = np.mgrid[0:40, 0:48]
    z = (6 * np.exp(-((x - 20) ** 2 + (y - 18) ** 2) / 60.0)).astype(np.float32)
    buf = io.BytesIO()
    np.save(buf, z)
    path = tmp_path / "part.npy"
    path.write_bytes(buf.getvalue())
    page.set_input_files("#npy-file", str(path))
    page.wait_for_function("document.getElementById('zmap-info').textContent.includes('40 x 48')")
    info = page.inner_text("#zmap-info")
    assert f"{z.max():.3f}" in info  # the page read the heights as numpy wrote them
    page.click("#run-contour")
    page.wait_for_function("document.getElementById('status').textContent === "
                           "'contour plan done'")
    assert page.locator("#stages thead th", has_text="contours").count() == 1
    _preview_decoded(page, "#preview")
    # the page sent exactly these heights: the same request from here is the same task
    same = httpx.post(server.url + "/v1/plans/contour", timeout=60, json={
        "grid": {"dx": 1.0, "dy": 1.0, "z": z.astype(np.float64).tolist()},
        "include_models": True})
    assert same.json()["task_id"][:12] in page.inner_text("#plan-info")
    page.screenshot(path=str(tmp_path / "viewer.png"), full_page=True)
    # an STL: the service makes the z-map, the plan names it by its task id
    stl = tmp_path / "steps.stl"
    stl.write_bytes(steps_stl())
    page.fill("#dx", "0.5")
    page.fill("#dy", "0.5")
    page.set_input_files("#npy-file", str(stl))
    page.wait_for_function("document.getElementById('zmap-info').textContent.includes("
                           "'z-map task')")
    assert "17 x 21 nodes" in page.inner_text("#zmap-info")  # 8 x 10 mm at 0.5 mm
    page.click("#run-scanline")
    page.wait_for_function("document.getElementById('status').textContent === "
                           "'scanline plan done'")
    _preview_decoded(page, "#preview")
    page.click("#curve-example")
    page.click("#run-arcs")
    page.wait_for_function("document.getElementById('status').textContent === 'arcs done'")
    _preview_decoded(page, "#chain-preview")
    assert '"n_arcs"' in page.inner_text("#arcs-info")
    assert "G17" in page.inner_text("#program")
    assert errors == []
    page.close()
