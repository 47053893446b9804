"""The HTML pages in a real browser: Debian's Chromium driven by Playwright, at 1280 px wide.

A per-recording report of a height log and of a video (with its contact sheet), a failed recording's page,
the batch summary (with that failed recording and the sample sheet's free columns) and a QC page, made with
dropfit's stages in a temporary directory, are opened in headless Chromium. Each must show every image, log
no console error, link only to files that exist and cut nothing off: the document no wider than the window
and no element sticking out of its container.
Nothing is downloaded: Playwright drives the system's Chromium (CI installs both, ``.ci/run``).
"""

import os
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest

from dropfit import stages
from dropfit.files import write_failure
from dropfit.settings import Ball
from dropfit.synth import simulate_drop

from helpers import CLIP_BALL_RADIUS_M, TENNIS_SHORT_SCENARIOS, render_drop_clip

pytestmark = pytest.mark.slow

CHROMIUM = Path("/usr/bin/chromium")
#: Headless Chromium as a test runs it: no sandbox (containers, root), no GPU, no network of its own.
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]
WIDTH_PX = 1280

#: The sample sheet: the workflow's columns and free ones (text and numbers).
SHEET = ("sample_id\tkind\tpath\tball_type\tball_radius_m\tball_mass_kg\tsurface\ttemperature_C\tpressure_kPa\n"
         "log_drop\theight_log\tlog.csv\ttennis\t0.0335\t0.057\tconcrete slab, lab 2\t21.5\t58\n"
         "video_drop\tvideo\tclip.avi\trubber\t0.025\t0.057\toak floor\t19.0\t61\n"
         "broken_drop\theight_log\tbroken.csv\ttennis\t0.0335\t0.057\tconcrete slab, lab 2\t20.0\t59\n")

#: Every element whose box sticks out of its parent's box, or out of the window (px, 1 px of rounding).
OVERFLOWING = """() => {
  const width = document.documentElement.clientWidth;
  const found = [];
  for (const element of document.body.querySelectorAll('*')) {
    const box = element.getBoundingClientRect();
    if (box.width === 0 && box.height === 0) continue;
    const parent = element.parentElement.getBoundingClientRect();
    if (box.right > parent.right + 1 || box.left < parent.left - 1 || box.right > width + 1
        || element.scrollWidth > element.clientWidth + 1 && element.clientWidth > 0) {
      found.push(`${element.tagName} "${element.textContent.slice(0, 50)}" ${box.left}–${box.right} px in `
                 + `${parent.left}–${parent.right} px`);
    }
  }
  return found;
}"""


def _playwright():
    """Playwright's sync API, or a failure saying what to install (the test never passes without a browser)."""
    if not CHROMIUM.exists():
        pytest.fail(f"{CHROMIUM} is missing: install Debian's Chromium (apt-get install -y chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("Playwright for Python is missing: pip install playwright (the browser is the system's "
                    "Chromium; do not run `playwright install`)")
    return sync_playwright


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    """The four pages, laid out as the workflow lays them out (results/<sample>/, results/batch/)."""
    root = tmp_path_factory.mktemp("browser")
    results = root / "results"
    (root / "sc.yaml").write_text(TENNIS_SHORT_SCENARIOS, encoding="utf-8")
    stages.synth(root / "sc.yaml", "tennis_short", root / "log.csv", root / "truth.json")
    stages.run(root / "log.csv", results / "log_drop", Ball(radius_m=0.0335, mass_kg=0.057, type="tennis"),
               sample_id="log_drop")
    drop = simulate_drop(0.8, CLIP_BALL_RADIUS_M, {"kind": "constant", "e0": 0.75}, mass_kg=0.057,
                         release_time_s=0.1)
    clip = render_drop_clip(root / "clip.avi", drop, fps=120.0).attrs["video_path"]
    stages.run(clip, results / "video_drop", Ball(radius_m=CLIP_BALL_RADIUS_M, mass_kg=0.057),
               sample_id="video_drop")
    broken = results / "broken_drop"
    broken.mkdir()
    message = (f"{root / 'a_rather_long_directory_name_for_the_logs' / 'broken.csv'}: time does not increase at "
               f"data row 12 (0.11 s then 0.11 s); sort the log or remove repeated rows")
    for name in ("fit.json", "report.html"):
        write_failure(broken / name, message)
    (root / "samples.tsv").write_text(SHEET, encoding="utf-8")
    fits = [results / sample / "fit.json" for sample in ("log_drop", "video_drop", "broken_drop")]
    batch = results / "batch"
    stages.summary(fits, batch / "summary.csv", batch / "summary.html", root / "samples.tsv",
                   batch / "summary_extras.png")
    stages.qc(fits, "lot", batch / "qc_lot.html", batch / "qc_lot.png", batch / "qc_lot_balls.csv",
              ball_ids=["A", "A", "B"])
    return {"log report": results / "log_drop" / "report.html", "video report": results / "video_drop" / "report.html",
            "failed recording's report": broken / "report.html", "summary": batch / "summary.html",
            "qc": batch / "qc_lot.html"}


def test_pages_show_every_image_log_no_error_and_cut_nothing_off_at_1280_px(pages):
    sync_playwright = _playwright()
    problems, shown = {}, {}
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": WIDTH_PX, "height": 900})
            errors = []
            page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
            page.on("pageerror", lambda error: errors.append(str(error)))
            for name, path in pages.items():
                errors.clear()
                page.goto(path.as_uri(), wait_until="load")
                images = page.evaluate("Array.from(document.images).map(image => [image.alt, image.naturalWidth])")
                links = page.evaluate("Array.from(document.links).map(link => link.href)")
                found = [f"console: {text}" for text in errors]
                found += [f"broken image: {alt}" for alt, width in images if width == 0]
                found += [f"link to a missing file: {link}" for link in links
                          if not os.path.exists(unquote(urlparse(link).path))]
                scroll_width = page.evaluate("document.documentElement.scrollWidth")
                if scroll_width > WIDTH_PX:
                    found.append(f"the page is {scroll_width} px wide")
                found += page.evaluate(OVERFLOWING)
                shown[name] = len(images)
                if found:
                    problems[name] = found[:10]
        finally:
            browser.close()
    assert not problems, problems
    assert all(shown[name] for name in pages if name != "failed recording's report"), shown
    assert "contact sheet of the video" in pages["video report"].read_text(encoding="utf-8")
