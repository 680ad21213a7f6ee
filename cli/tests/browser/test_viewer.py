"""`freeform view`'s page in a real browser (Debian's headless Chromium through Playwright).

A small scene (the layered sphere dropped on the floor, 30 steps, stress written) is simulated
once; the page that `simulate` writes is opened from disk with no server and no network. The
tests look at pixels: the object drawn where the camera aims, the colour bar's two ends, the
object moving when the slider steps, and the size limit dropping frames and saying so.

Environment: FREEFORM_BIN (default target/release/freeform), CHROMIUM (default
/usr/bin/chromium).
"""

import io
import os
import pathlib
import shutil
import subprocess

import pytest
from PIL import Image
from playwright.sync_api import sync_playwright

ROOT = pathlib.Path(__file__).resolve().parents[3]
BINARY = pathlib.Path(os.environ.get("FREEFORM_BIN", ROOT / "target" / "release" / "freeform"))
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
SCENE = ROOT / "freeform" / "examples" / "scenes" / "layered_sphere.toml"
SHOTS = pathlib.Path(os.environ.get("FREEFORM_SHOTS", ROOT / "target" / "viewer-shots"))

# WebGL without a GPU (SwiftShader), and none of Chromium's background connections.
ARGS = [
    "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run", "--disable-quic",
]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """The layered sphere's output folder after `freeform simulate` (30 steps, stress)."""
    if not BINARY.exists():
        pytest.fail(f"{BINARY} is missing: build it with `cargo build --release -p freeform-cli`")
    work = tmp_path_factory.mktemp("viewer")
    scene = work / "layered_sphere.toml"
    text = SCENE.read_text().replace("steps = 100", "steps = 30")
    assert "steps = 30" in text, "the example scene no longer says `steps = 100`"
    scene.write_text(text)
    shutil.copy(SCENE.parent / "sphere.obj", work / "sphere.obj")
    subprocess.run(
        [BINARY, "simulate", "--quiet", "--stress", "--out", work / "out", "--cache", work / "cache", scene],
        check=True, capture_output=True,
    )
    return work / "out" / "layered_sphere"


@pytest.fixture(scope="module")
def browser():
    if not pathlib.Path(CHROMIUM).exists():
        pytest.fail(f"{CHROMIUM} is missing: install Debian's `chromium` package")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield browser
        browser.close()


def open_page(browser, html):
    page = browser.new_page(viewport={"width": 1000, "height": 700})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(html.as_uri())
    page.wait_for_function("document.body.dataset.ready === '1' || document.body.dataset.error", timeout=60_000)
    assert "error" not in page.evaluate("Object.keys(document.body.dataset)"), page.inner_text("#notes")
    return page, errors


def screenshot(page, name):
    png = page.screenshot()
    SHOTS.mkdir(parents=True, exist_ok=True)
    (SHOTS / name).write_bytes(png)
    return Image.open(io.BytesIO(png)).convert("RGB")


def object_pixels(image):
    """Pixels of the object: saturated colours (viridis), not the grey floor or background,
    left of the legend and above the control bar."""
    width, height = image.size
    found = []
    for y in range(0, height - 60, 2):
        for x in range(0, width - 230, 2):
            r, g, b = image.getpixel((x, y))
            if max(r, g, b) - min(r, g, b) > 40:
                found.append((x, y))
    return found


def test_the_page_draws_the_object_at_the_centre_with_a_colour_bar_and_the_slider_moves_it(browser, run_dir):
    page, errors = open_page(browser, run_dir / "view.html")
    first = screenshot(page, "layered_sphere_first.png")
    pixels = object_pixels(first)
    assert len(pixels) > 2000, f"only {len(pixels)} object pixels"
    cx = sum(x for x, _ in pixels) / len(pixels)
    cy = sum(y for _, y in pixels) / len(pixels)
    assert 300 < cx < 700 and 200 < cy < 500, f"object centred at ({cx:.0f}, {cy:.0f})"

    bar = Image.open(io.BytesIO(page.locator("#colour-bar").screenshot())).convert("RGB")
    top, bottom = bar.getpixel((bar.width // 2, 3)), bar.getpixel((bar.width // 2, bar.height - 4))
    assert top[0] > 200 and top[1] > 180 and top[2] < 100, f"top of the bar {top} is not yellow"
    assert bottom[0] < 110 and bottom[1] < 40 and bottom[2] > 60, f"bottom of the bar {bottom} is not purple"
    assert "(Pa)" in page.inner_text("#legend")

    frames = page.evaluate("window.freeformViewer.frameCount")
    assert frames >= 4
    page.locator("#frame").fill(str(frames - 1))
    page.wait_for_function(f"document.body.dataset.frame === '{frames - 1}'")
    page.wait_for_timeout(300)
    last = screenshot(page, "layered_sphere_last.png")
    moved = object_pixels(last)
    ly = sum(y for _, y in moved) / len(moved)
    # The sphere falls onto the floor: its image moves down the screen.
    assert ly > cy + 10, f"object centre at y = {cy:.0f} in the first frame and {ly:.0f} in the last"
    assert f"frame {frames} of {frames}" in page.inner_text("#time")
    assert errors == []
    page.close()


def test_the_size_limit_drops_frames_says_so_and_refuses_a_limit_too_small(browser, run_dir, tmp_path):
    small = tmp_path / "run"
    shutil.copytree(run_dir, small)
    full = (run_dir / "view.html").stat().st_size
    limit_mb = (full - 40_000) / 1e6
    done = subprocess.run([BINARY, "view", small, "--max-mb", str(limit_mb)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    html = small / "view.html"
    assert html.stat().st_size <= limit_mb * 1e6
    assert "dropped" in done.stdout
    page, errors = open_page(browser, html)
    kept = page.evaluate("window.freeformViewer.frameCount")
    notes = page.inner_text("#notes")
    assert "dropped" in notes and f"{kept} of" not in notes, notes
    full_frames = len(list(run_dir.glob("frame_*.ply")))
    assert 1 < kept < full_frames
    assert f"{full_frames - kept} of the run's {full_frames} frames dropped" in notes
    assert errors == []
    page.close()

    refused = subprocess.run([BINARY, "view", small, "--max-mb", "0.1"], capture_output=True, text=True)
    assert refused.returncode != 0
    assert "over the limit" in refused.stderr


EXAMPLES = ["layered_sphere", "pusher", "donut_drop", "container"]


@pytest.mark.parametrize("name", EXAMPLES)
def test_an_example_scenes_page_opens_offline_and_plays(browser, tmp_path, name):
    """The example scene run in full as a user would, its page opened from disk, screenshots of
    its first frame and of a frame reached by playing (in FREEFORM_SHOTS)."""
    out = tmp_path / "out"
    done = subprocess.run(
        [BINARY, "simulate", "--quiet", "--out", out, "--cache", tmp_path / "cache",
         SCENE.parent / f"{name}.toml"],
        capture_output=True, text=True,
    )
    assert done.returncode == 0, done.stderr
    html = out / name / "view.html"
    print(f"{name}: view.html {html.stat().st_size / 1e6:.2f} MB")
    page, errors = open_page(browser, html)
    first = screenshot(page, f"{name}.png")
    drawn = sum(1 for p in first.getdata() if p != (244, 245, 247))
    assert drawn > 0.2 * first.width * first.height, f"only {drawn} pixels drawn"
    page.click("#play")
    page.wait_for_function("Number(document.body.dataset.frame) >= 3", timeout=30_000)
    page.click("#play")
    played = screenshot(page, f"{name}_played.png")
    changed = sum(1 for a, b in zip(first.getdata(), played.getdata()) if a != b)
    assert changed > 500, f"playing changed {changed} pixels"
    assert errors == []
    page.close()
