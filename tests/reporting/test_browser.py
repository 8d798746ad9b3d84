"""Load the HTML report in a real headless browser (Debian `chromium`).

Checks that the page parses and loads with no console message or uncaught error, that every
<img> decodes in the browser (naturalWidth > 0), that the embedded PNGs are not blank, and that
a screenshot of the rendered page is not blank. A negative control page (a script error and a
broken image) proves the checks catch what they claim to catch.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from report_helpers import decoded_images, n_colors

pytestmark = pytest.mark.browser

CHROMIUM = next((p for p in map(shutil.which, ("chromium", "chromium-browser", "google-chrome")) if p), None)
if CHROMIUM is None:
    pytest.skip("chromium not installed (Debian: apt-get install -y chromium); browser check skipped", allow_module_level=True)

# Appended to a COPY of the report (the report itself carries no script): after the load event,
# count images that did not decode, log each as a console error, and leave the counts in the DOM.
PROBE = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var broken = imgs.filter(function (i) { return !i.complete || i.naturalWidth === 0; });
  broken.forEach(function (i) { console.error('broken image: ' + i.alt); });
  document.body.setAttribute('data-probe', 'imgs=' + imgs.length + ';broken=' + broken.length);
});
</script>"""

CONSOLE_LINE = re.compile(r"CONSOLE|Uncaught|SyntaxError|ReferenceError|TypeError|Failed to load resource|ERR_")


def chromium(args: list[str], profile: Path) -> subprocess.CompletedProcess:
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
           "--disable-component-update", "--no-first-run", "--disable-extensions", f"--user-data-dir={profile}",
           "--enable-logging=stderr", "--v=0", "--virtual-time-budget=15000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=180)


def load_page(page: Path, tmp: Path) -> tuple[str, list[str]]:
    """(DOM after load, console/error lines from the browser log) for a local HTML file."""
    probed = tmp / f"probe_{page.name}"
    html = page.read_text()
    probed.write_text(html.replace("</body>", PROBE + "</body>"))
    proc = chromium(["--dump-dom", probed.as_uri()], tmp / "profile_dom")
    assert proc.returncode == 0, proc.stderr[-2000:]
    errors = [ln for ln in proc.stderr.splitlines() if CONSOLE_LINE.search(ln)]
    return proc.stdout, errors


def probe_counts(dom: str) -> tuple[int, int]:
    m = re.search(r'data-probe="imgs=(\d+);broken=(\d+)"', dom)
    assert m, "the load-event probe did not run: the page did not finish loading"
    return int(m.group(1)), int(m.group(2))


def test_report_loads_without_console_errors_and_images_decode(html_report, tmp_path):
    dom, errors = load_page(html_report, tmp_path)
    assert errors == [], "\n".join(errors)
    n_imgs, broken = probe_counts(dom)
    expected = len(decoded_images(html_report.read_text()))
    assert n_imgs == expected >= 10 and broken == 0
    assert 'id="navigation"' in dom and "Thresholds (regression gates)" in dom


def test_screenshot_is_not_blank(html_report, tmp_path):
    shot = tmp_path / "shot.png"
    proc = chromium([f"--screenshot={shot}", "--window-size=1200,4000", "--hide-scrollbars", html_report.as_uri()],
                    tmp_path / "profile_shot")
    assert proc.returncode == 0 and shot.is_file(), proc.stderr[-2000:]
    img = cv2.imread(str(shot), cv2.IMREAD_COLOR)
    assert img.shape[:2] == (4000, 1200)
    assert img.std() > 20.0
    # The lower part of the page holds figures (trajectory over the map, error plots): busy pixels.
    lower = img[2000:]
    non_white = np.mean(np.any(lower < 235, axis=2))
    assert non_white > 0.05 and n_colors(lower) > 500


def test_checks_catch_script_errors_and_broken_images(tmp_path):
    bad = tmp_path / "bad.html"
    bad.write_text("<!DOCTYPE html><html><head><meta charset='utf-8'><link rel='icon' href='data:,'></head><body>"
                   "<p>negative control</p><img alt='bad' src='data:image/png;base64,AAAAAAAA'>"
                   "<script>no_such_function();</script></body></html>")
    dom, errors = load_page(bad, tmp_path)
    assert any("no_such_function" in e for e in errors), errors
    assert any("broken image: bad" in e for e in errors), errors
    assert probe_counts(dom) == (1, 1)
