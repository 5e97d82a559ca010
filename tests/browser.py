"""Driving a real headless Chromium (Debian's ``chromium``) through Playwright's Python API.

Used by tests/analysis/viewer/test_viewer_browser.py, bench/bench_viewer.py and for the README's screenshot::

    python tests/browser.py PAGE.html OUT.png [--play SECONDS] [--seek FRAME] [--color-by MODE] [--fit] [--whole-page]

:class:`Browser` starts Chromium with a fresh profile and the flags that work on a machine without a
GPU (WebGL through SwiftShader); :meth:`Browser.open` loads a page from a ``file://`` URL with every
request that is not ``file:``, ``blob:`` or ``data:`` aborted and recorded, and collects the console's
errors and uncaught exceptions. Playwright's own browser downloads are never used.
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
LOCAL_SCHEMES = ("file:", "blob:", "data:")
VIEWPORT = {"width": 1280, "height": 760}


def chromium_path() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None:
        raise RuntimeError("Debian's chromium is not installed (apt-get install -y chromium; .ci/run does it)")
    return path


@dataclass
class Opened:
    page: object
    load_s: float
    errors: list = field(default_factory=list)
    blocked: list = field(default_factory=list)

    def screenshot(self, path=None, selector: str = "#stage") -> np.ndarray:
        """RGB array of the element (default: the 3-D stage); also saved to ``path`` when given."""
        from io import BytesIO

        from PIL import Image

        png = self.page.locator(selector).screenshot(path=str(path) if path else None)
        return np.asarray(Image.open(BytesIO(png)).convert("RGB"), dtype=np.int16)

    def state(self, expression: str):
        return self.page.evaluate(f"window.flockViewer.{expression}")


class Browser:
    def __init__(self):
        from playwright.sync_api import sync_playwright

        self._profile = tempfile.TemporaryDirectory(prefix="flocksweep-chromium-")
        self._playwright = sync_playwright().start()
        self.context = self._playwright.chromium.launch_persistent_context(
            self._profile.name, executable_path=chromium_path(), headless=True, args=FLAGS, viewport=VIEWPORT,
            service_workers="block")

    def open(self, html_path, timeout_s: float = 60.0, fragment: str = "") -> Opened:
        """Load the page (with ``fragment``, e.g. ``"t=15&color=group"``, as its URL fragment)."""
        page = self.context.new_page()
        opened = Opened(page, 0.0)

        def route(r):
            if r.request.url.startswith(LOCAL_SCHEMES):
                r.continue_()
            else:
                opened.blocked.append(r.request.url)
                r.abort()

        page.route("**/*", route)
        page.on("console", lambda m: opened.errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: opened.errors.append(f"uncaught: {e}"))
        start = time.perf_counter()
        page.goto(Path(html_path).resolve().as_uri() + (f"#{fragment}" if fragment else ""))
        page.wait_for_function("window.flockViewer && window.flockViewer.ready", timeout=timeout_s * 1000)
        opened.load_s = time.perf_counter() - start
        return opened

    def close(self) -> None:
        self.context.close()
        self._playwright.stop()
        self._profile.cleanup()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def measure_fps(opened: Opened, seconds: float = 3.0) -> float:
    """Frames the page renders per second while playing (after a half-second warm-up)."""
    opened.page.evaluate("window.flockViewer.play()")
    opened.page.wait_for_timeout(500)
    before, start = opened.state("renders"), time.perf_counter()
    opened.page.wait_for_timeout(seconds * 1000)
    after, elapsed = opened.state("renders"), time.perf_counter() - start
    opened.page.evaluate("window.flockViewer.pause()")
    return (after - before) / elapsed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Screenshot a flocksweep viewer page in headless Chromium.")
    parser.add_argument("page", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--play", type=float, default=0.0, help="seconds to play before the screenshot")
    parser.add_argument("--seek", type=int, help="frame to show")
    parser.add_argument("--color-by", help="colouring to select first")
    parser.add_argument("--fit", action="store_true", help="press 'fit view' before the screenshot")
    parser.add_argument("--whole-page", action="store_true", help="the page with its panel, not only the 3-D stage")
    args = parser.parse_args(argv)
    with Browser() as browser:
        opened = browser.open(args.page)
        if args.color_by:
            opened.page.select_option("#colorby", args.color_by)
        if args.seek is not None:
            opened.page.evaluate(f"window.flockViewer.seek({args.seek})")
        if args.play:
            opened.page.click("#play")
            opened.page.wait_for_timeout(args.play * 1000)
            opened.page.click("#play")
        if args.fit:
            opened.page.wait_for_timeout(300)
            opened.page.click("#fit")
        opened.page.wait_for_timeout(300)
        opened.screenshot(args.out, "body" if args.whole_page else "#stage")
        print(f"{args.out}: load {opened.load_s:.2f} s, console errors {len(opened.errors)}, "
              f"blocked requests {len(opened.blocked)}")
        return 1 if opened.errors or opened.blocked else 0


if __name__ == "__main__":
    sys.exit(main())
