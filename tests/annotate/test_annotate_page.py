"""The annotation page in headless Chromium (Debian's /usr/bin/chromium via Playwright, never a download)."""

from __future__ import annotations

import json
import shutil
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = Path("/usr/bin/chromium")
SCREENSHOT = Path("/tmp/annotate_page.png")

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian chromium at /usr/bin/chromium"),
]


@pytest.fixture
def server(tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> Iterator[str]:
    from test_annotate_api import make_sim_run  # same session cache as the API tests

    from studio.annotate.app import serve_in_thread
    from studio.annotate.server import AnnotateServer

    run = tmp_path / "run"
    shutil.copytree(make_sim_run(tmp_path_factory.getbasetemp() / "annotate_sim"), run)
    state = AnnotateServer(run, author="browser-test")
    with serve_in_thread(state) as url:
        yield url
    state.close()


def _call(url: str, path: str, body: dict[str, Any] | None = None) -> Any:
    data = None if body is None else json.dumps(body).encode()
    with urllib.request.urlopen(urllib.request.Request(url + path, data=data), timeout=60) as r:
        return json.loads(r.read())


def _gt(url: str, frame: int) -> dict[int, dict[str, Any]]:
    return {p["id"]: p for p in _call(url, f"/api/frame/{frame}")["gt"]}


def _drag_person(page: Any, pid: int, dx_m: float, dy_m: float) -> None:
    """Drag ground-truth person ``pid`` in the bird's-eye view by (dx, dy) metres of the base frame."""
    page.evaluate("() => renderBev()")  # the view fits the people to the canvas as it is now
    pts = page.evaluate(
        """([pid, dx, dy]) => {
            const p = S.data.gt.find((q) => q.id === pid);
            const g = bevGeom(), r = document.getElementById("bev").getBoundingClientRect();
            const a = g.toScreen(p.x, p.y), b = g.toScreen(p.x + dx, p.y + dy);
            return [a[0] + r.left, a[1] + r.top, b[0] + r.left, b[1] + r.top];
        }""",
        [pid, dx_m, dy_m],
    )
    page.mouse.move(pts[0], pts[1])
    page.mouse.down()
    for k in range(1, 6):
        page.mouse.move(pts[0] + (pts[2] - pts[0]) * k / 5, pts[1] + (pts[3] - pts[1]) * k / 5)
    page.mouse.up()


def _metric(page: Any, key: str) -> str:
    return str(page.locator(f'#metrics td[data-key="{key}"]').inner_text())


def test_page_move_merge_reload_conflict(server: str) -> None:
    from playwright.sync_api import expect, sync_playwright

    url = server
    rev = _call(url, "/api/op", {"op": {"op": "review", "start": 0, "end": 59}})["rev"]
    rev = _call(url, "/api/op", {"op": {"op": "split", "id": 0, "frame": 30, "new_id": 50}, "base_rev": rev})[
        "rev"
    ]
    before = _call(url, "/api/metrics?wait=30")["metrics"]
    assert before["f1"] == 1.0
    assert before["idf1"] < 0.95
    p1 = _gt(url, 20)[1]

    with sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=str(CHROMIUM),
            args=["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"],
        )
        try:
            page = browser.new_page(viewport={"width": 1500, "height": 950})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url + "/#20")
            expect(page.locator("#people tbody tr")).to_have_count(len(_gt(url, 20)))
            expect(page.locator("#frameno")).to_have_value("20")
            page.wait_for_function(
                "document.getElementById('pano').complete && document.getElementById('pano').naturalWidth > 0"
            )
            expect(page.locator('#metrics td[data-key="F1"]')).to_have_text("1.000")

            # move person 1 by one metre in this frame only
            page.uncheck("#propagate")
            _drag_person(page, 1, 1.0, 0.0)
            expect(page.locator("#status")).to_contain_text("saved")
            expect(page.locator('#metrics td[data-key="TP / FP / FN"]')).to_contain_text("/ 1 / 1")

            # merge 50 back into 0 over the whole run (select 0 in the people table)
            page.locator("#people tbody tr", has_text="manual").first.wait_for()
            page.locator("#people tbody tr").filter(has=page.locator("td", has_text="0")).first.click()
            page.evaluate("() => { S.sel = 0; render(); }")
            page.select_option("#scope", "all")
            page.fill("#new-id", "50")
            page.click("#merge")
            expect(page.locator("#status")).to_contain_text("saved")
            page.wait_for_function("S.metricsRev === S.rev")

            # reload: both edits persisted, metrics as implied
            page.reload()
            expect(page.locator("#frameno")).to_have_value("20")
            expect(page.locator('#metrics td[data-key="TP / FP / FN"]')).to_contain_text("/ 1 / 1")
            after = _call(url, "/api/metrics?wait=30")["metrics"]
            assert (after["tp"], after["fp"], after["fn"]) == (before["tp"] - 1, 1, 1)
            assert after["idf1"] > before["idf1"]
            assert after["num_gt_tracks"] == before["num_gt_tracks"] - 1
            moved = _gt(url, 20)[1]
            assert moved["x"] == pytest.approx(p1["x"] + 1.0, abs=0.05)
            assert moved["y"] == pytest.approx(p1["y"], abs=0.05)
            assert moved["changed"]["author"] == "browser-test"
            assert 50 not in _gt(url, 40)
            assert 0 in _gt(url, 40)
            assert _gt(url, 21)[1]["x"] != moved["x"]  # not propagated

            # a second tab with a stale view gets a conflict, and nothing is overwritten
            page2 = browser.new_page(viewport={"width": 1500, "height": 950})
            page2.goto(url + "/#20")
            expect(page2.locator("#people tbody tr")).to_have_count(len(_gt(url, 20)))
            page2.evaluate("() => { window.studioNoPoll = true; }")
            page.evaluate("() => { window.studioNoPoll = true; }")
            page.uncheck("#propagate")
            _drag_person(page, 2, 0.0, 0.5)
            expect(page.locator("#status")).to_contain_text("saved")
            p2 = _gt(url, 20)[2]
            page2.uncheck("#propagate")
            _drag_person(page2, 2, 0.0, -0.5)
            expect(page2.locator("#banner")).to_contain_text("Conflict")
            assert _gt(url, 20)[2]["y"] == p2["y"]
            page2.close()

            page.evaluate("() => { window.studioNoPoll = false; }")
            page.evaluate("() => { S.sel = 1; render(); }")
            page.wait_for_timeout(300)
            page.screenshot(path=str(SCREENSHOT))
            assert not errors, errors
        finally:
            browser.close()
