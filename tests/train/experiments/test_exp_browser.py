"""The demo's page in a real browser: every image loads and every video plays (headless Chromium); the README's
screenshot of it (assets/demo-page.png) is re-made here, so it shows the page as the code draws it now.

Skipped, with a message, where the distribution's Chromium (``/usr/bin/chromium``) is not installed
(``apt-get install chromium``).
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest

from train.cli import main

CHROMIUM = Path("/usr/bin/chromium")

CHECK_JS = """
window.addEventListener('load', async () => {
  const wait = (el, ok, bad) => new Promise(r => {
    el.addEventListener(ok, () => r(true)); el.addEventListener(bad, () => r(false)); setTimeout(() => r(null), 15000);
  });
  const images = [...document.images].map(i => ({src: i.getAttribute('src'), ok: i.complete && i.naturalWidth > 0}));
  const posters = await Promise.all([...document.querySelectorAll('video')].map(async v => {
    const im = new Image(); const loaded = wait(im, 'load', 'error'); im.src = v.getAttribute('poster') || '';
    return {src: v.getAttribute('poster'), ok: (await loaded) === true && im.naturalWidth > 0};
  }));
  const videos = await Promise.all([...document.querySelectorAll('video')].map(async v => {
    const s = v.querySelector('source');
    let ok = v.readyState >= 2;
    if (!ok) { const loaded = wait(v, 'loadeddata', 'error'); v.load(); ok = (await loaded) === true; }
    return {src: s.getAttribute('src'), canPlay: v.canPlayType(s.getAttribute('type')), ok: ok, width: v.videoWidth};
  }));
  const out = document.createElement('pre'); out.id = 'ecorl-check';
  out.textContent = JSON.stringify({images: images.concat(posters), videos: videos});
  document.body.appendChild(out);
});
"""


def browser_check(page: Path, profile: Path) -> dict:
    """Open ``page`` (with the check script appended) in headless Chromium; what loaded and what did not."""
    checked = page.with_name("browser-check.html")
    (page.parent / "browser-check.js").write_text(CHECK_JS)
    checked.write_text(page.read_text().replace("</body>", "<script src='browser-check.js'></script></body>"))
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
             "--disable-component-update", "--no-first-run", f"--user-data-dir={profile}",
             "--virtual-time-budget=30000", "--dump-dom"]
    proc = subprocess.run([str(CHROMIUM), *flags, checked.resolve().as_uri()], capture_output=True, text=True,
                          timeout=180)
    found = re.search(r'<pre id="ecorl-check">(.*?)</pre>', proc.stdout, re.S)
    assert found, f"the check script did not report; chromium said: {proc.stderr[-2000:]}"
    return json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))


@pytest.mark.skipif(not CHROMIUM.exists(), reason="no /usr/bin/chromium: install the distribution's chromium "
                                                   "package to open the demo page in a real browser")
def test_the_demo_page_shows_every_image_and_plays_every_video(tmp_path):
    out = tmp_path / "results"
    code = main(["run", "headline-waypoint", "--budget", "smoke", "--condition", "static-reset-free",
                 "dynamic-reset-free", "--out", str(out), "--report", "--no-progress"])
    assert code == 0
    page = out / "headline-waypoint" / "index.html"
    result = browser_check(page, tmp_path / "chromium-profile")
    images, videos = result["images"], result["videos"]
    assert len(images) >= 6 and len(videos) == 2  # 2 shipped panels, curves, heat-maps, 2 posters; 2 videos
    assert all(i["ok"] for i in images), [i for i in images if not i["ok"]]
    assert all(v["ok"] and v["canPlay"] in ("probably", "maybe") and v["width"] > 0 for v in videos), videos
    screenshot(page, tmp_path / "chromium-profile", SCREENSHOT)  # the README's picture of this page, re-made
    assert SCREENSHOT.stat().st_size > 20_000


SCREENSHOT = Path(__file__).resolve().parents[3] / "assets" / "demo-page.png"
"""The README's picture of the top of the demo's page, re-made by every run of the browser test."""


def screenshot(page: Path, profile: Path, out: Path) -> Path:
    """A PNG of the top of ``page`` as headless Chromium draws it at 1 200 x 1 500 pixels."""
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
             "--disable-component-update", "--no-first-run", "--hide-scrollbars", f"--user-data-dir={profile}",
             "--window-size=1200,1500", "--virtual-time-budget=10000", f"--screenshot={out}"]
    subprocess.run([str(CHROMIUM), *flags, page.resolve().as_uri()], capture_output=True, timeout=180, check=True)
    return out


def test_the_browser_check_sees_a_video_that_does_not_play(tmp_path):
    """The check can fail: OpenCV's MPEG-4 Part 2, which the page used to link, does not play in Chromium."""
    if not CHROMIUM.exists():
        pytest.skip("no /usr/bin/chromium: install the distribution's chromium package")
    import numpy as np

    from ecology import write_video

    write_video([np.full((64, 64, 3), 10 * i, np.uint8) for i in range(16)], tmp_path / "old.mp4", fps=8)
    (tmp_path / "index.html").write_text("<!doctype html><html><body><img src='missing.png'><video poster='no.png'>"
                                         "<source src='old.mp4' type='video/mp4'></video></body></html>")
    result = browser_check(tmp_path / "index.html", tmp_path / "chromium-profile")
    assert not any(i["ok"] for i in result["images"]) and not result["videos"][0]["ok"]
