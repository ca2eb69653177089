"""The page's keyboard flow in headless Chromium, on a run whose recording was moved away (review of #6)."""

from __future__ import annotations

import json
import shutil
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = Path("/usr/bin/chromium")
SCREENSHOT = Path("/tmp/annotate_page_keys.png")

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian chromium at /usr/bin/chromium"),
]


@pytest.fixture
def moved_server(tmp_path_factory: pytest.TempPathFactory, tmp_path: Path) -> Iterator[str]:
    """The simulated run of the API tests with its recording moved away (run.json names a missing file)."""
    from test_annotate_api import make_sim_run

    from studio.annotate.app import serve_in_thread
    from studio.annotate.server import AnnotateServer

    run = tmp_path / "run"
    shutil.copytree(make_sim_run(tmp_path_factory.getbasetemp() / "annotate_sim"), run)
    info = json.loads((run / "run.json").read_text())
    info["recording"] = str(tmp_path / "moved" / "recording.mcap")
    (run / "run.json").write_text(json.dumps(info))
    # two doubts the test knows (the run's own review points depend on its tracks)
    from studio.labels import ReviewPoint, read_labels, write_review

    stamps = {f.frame: f.stamp_ns for f in read_labels(run / "labels.jsonl").frames}
    write_review(
        run / "review.jsonl",
        [
            ReviewPoint(30, stamps[30], (1,), "gap", "track 1 seen again after 1.4 s: the same person?", 0.2),
            ReviewPoint(45, stamps[45], (1, 2), "encounter", "tracks 1 and 2 came within 0.33 m: ...", 0.45),
        ],
    )
    state = AnnotateServer(run, author="keys")
    assert state.media.problem
    with serve_in_thread(state) as url:
        yield url
    state.close()


def _call(url: str, path: str) -> Any:
    with urllib.request.urlopen(url + path, timeout=60) as r:
        return json.loads(r.read())


def test_keyboard_flow_without_recording(moved_server: str) -> None:
    from playwright.sync_api import expect, sync_playwright

    url = moved_server
    with sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=str(CHROMIUM),
            args=["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"],
        )
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            errors: list[str] = []
            urls: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("request", lambda r: urls.append(r.url))
            page.goto(url + "/#10")
            expect(page.locator("#frameno")).to_have_value("10")
            # the page says why there are no images, and keeps a panorama-sized panel with the markers
            expect(page.locator("#media-note")).to_be_visible()
            expect(page.locator("#media-note")).to_contain_text("not found")
            expect(page.locator("#pano-msg")).to_contain_text("no recording")
            assert page.locator("#pano-wrap").bounding_box()["height"] > 200  # type: ignore[index]

            # arrows, Shift+arrow, N + click adds, Del deletes, Enter reviews and steps, Ctrl+Z undoes
            page.keyboard.press("ArrowRight")
            expect(page.locator("#frameno")).to_have_value("11")
            page.keyboard.press("Shift+ArrowRight")
            expect(page.locator("#frameno")).to_have_value("21")
            n_people = len(_call(url, "/api/frame/21")["gt"])
            # the frame number shows at once, its people once fetched: click on frame 21's view, not 11's
            page.wait_for_function("() => S.data !== null && S.data.frame === 21")
            page.keyboard.press("n")
            page.wait_for_function("() => S.addMode === true")
            box = page.locator("#bev").bounding_box()
            assert box is not None
            page.mouse.click(box["x"] + box["width"] * 0.2, box["y"] + box["height"] * 0.2)
            expect(page.locator("#status")).to_contain_text("saved · rev 1")
            expect(page.locator("#people tbody tr")).to_have_count(n_people + 1)
            added = page.evaluate("S.sel")
            page.keyboard.press("Escape")
            page.evaluate(f"() => {{ S.sel = {added}; render(); }}")
            page.keyboard.press("Delete")
            expect(page.locator("#status")).to_contain_text("saved · rev 2")
            expect(page.locator("#people tbody tr")).to_have_count(n_people)
            page.keyboard.press("Enter")
            expect(page.locator("#frameno")).to_have_value("22")
            assert 21 in _call(url, "/api/metrics")["reviewed"]
            page.keyboard.press("Control+z")
            expect(page.locator("#status")).to_contain_text("undo of #3 frame 21")
            assert 21 not in _call(url, "/api/metrics")["reviewed"]
            page.keyboard.press("u")  # next unreviewed: the next frame
            expect(page.locator("#frameno")).to_have_value("23")
            expect(page.locator("#status")).to_contain_text("unreviewed frame 23")

            # a typed #N in the address bar goes there
            page.evaluate("() => { location.hash = '#40'; }")
            expect(page.locator("#frameno")).to_have_value("40")
            expect(page.locator("#history li")).to_have_count(1)
            expect(page.locator("#doubt-note")).to_be_hidden()

            # C / Shift+C: the next / previous doubt, its note above the views
            page.keyboard.press("c")
            expect(page.locator("#frameno")).to_have_value("45")
            expect(page.locator("#doubt-note")).to_contain_text("tracks 1 and 2 came within 0.33 m")
            assert page.evaluate("S.sel") == 1  # the first track in doubt is selected
            # W with no ID typed: swap it with the encounter's other track from here on
            before = {p["id"]: p["x"] for p in _call(url, "/api/frame/50")["gt"]}
            page.keyboard.press("w")
            expect(page.locator("#history li").first).to_contain_text("swapped 1 ⇄ 2 (45–59)")
            after = {p["id"]: p["x"] for p in _call(url, "/api/frame/50")["gt"]}
            assert (after[1], after[2]) == (before[2], before[1])
            f44 = _call(url, "/api/frame/44")  # before the scope: as the auto labels
            assert {p["id"]: p["x"] for p in f44["gt"]} == {p["id"]: p["x"] for p in f44["auto"]}
            page.keyboard.press("Shift+C")
            expect(page.locator("#frameno")).to_have_value("30")
            expect(page.locator("#doubt-note")).to_contain_text("track 1 seen again after 1.4 s")
            status = "unreviewed doubt frame 30 · 2 unreviewed doubt frames"
            expect(page.locator("#status")).to_contain_text(status)
            # X: the most doubtful one, wherever it is, with its doubt in the note
            page.keyboard.press("x")
            expect(page.locator("#frameno")).to_have_value("45")
            expect(page.locator("#doubt-note")).to_contain_text("(doubt 0.45)")
            expect(page.locator("#status")).to_contain_text("most doubtful frame 45")

            # polling asks for the small state, not the whole run's meta
            urls.clear()
            page.wait_for_timeout(4500)
            assert any("/api/state" in u for u in urls), urls
            assert not any("/api/meta" in u for u in urls), urls
            page.screenshot(path=str(SCREENSHOT))
            assert not errors, errors
        finally:
            browser.close()
