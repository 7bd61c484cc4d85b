"""Render one frame of a replay page in headless Chromium and save it as PNG.

    python scripts/replay_screenshot.py                       # 3-s solo12 trot -> docs/replay_solo12.png
    python scripts/replay_screenshot.py --html run.html --time 0.8 --out run.png
    python scripts/replay_screenshot.py --quick --out /tmp/x.png   # a 0.3-s trot's page at t = 0.2 s (smoke run)

Without --html it first writes the page of the 3-s solo12 trot
(``contactdiff simulate solo12_trot --t-final 3 --html ...``) to a temporary folder.

The browser: playwright (``pip install 'contactdiff[browser]'``) driving its own Chromium if
``playwright install chromium`` was run, else a Chromium or Chrome found on PATH
(``chromium``, ``chromium-browser``, ``google-chrome``, ...); without playwright,
that binary's own ``--headless --screenshot`` (which cannot seek: it shows the
animation at the moment the screenshot is taken). WebGL runs in software
(SwiftShader). Every request other than ``file:`` and ``data:`` is blocked, so the
picture also shows that the page needs no network.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BINARIES = (
    "chromium",
    "chromium-browser",
    "google-chrome",
    "google-chrome-stable",
    "chrome",
    "chrome-headless-shell",
    "headless_shell",
)
GL_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]


class NoBrowserError(RuntimeError):
    """Neither playwright's Chromium nor a Chromium/Chrome binary is available."""


def chromium_binary() -> str | None:
    """Path of a Chromium or Chrome on PATH, or None."""
    return next((path for name in BINARIES if (path := shutil.which(name))), None)


def open_page(playwright, width: int, height: int):
    """A headless Chromium page (playwright's own browser, else a binary on PATH) that
    refuses every request but ``file:`` and ``data:``; returns ``(browser, page, blocked)``
    where ``blocked`` collects the refused URLs."""
    try:
        browser = playwright.chromium.launch(args=GL_ARGS)
    except Exception as exc:  # noqa: BLE001 - playwright's browser not installed: try PATH
        binary = chromium_binary()
        if binary is None:
            raise NoBrowserError(
                f"no headless Chromium: playwright has none ({str(exc).splitlines()[0]}) "
                f"and none of {', '.join(BINARIES)} is on PATH"
            ) from None
        browser = playwright.chromium.launch(executable_path=binary, args=GL_ARGS)
    page = browser.new_page(viewport={"width": width, "height": height})
    blocked: list[str] = []

    def route(r):
        if r.request.url.startswith(("file:", "data:")):
            r.continue_()
        else:
            blocked.append(r.request.url)
            r.abort()

    page.route("**/*", route)
    return browser, page, blocked


def load_replay(page, html: Path, timeout_ms: float = 60_000) -> dict:
    """Open the replay page and wait until its animation is loaded; return the viewer's
    animation facts (``actions``, ``duration`` in s) and page errors."""
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(html.resolve().as_uri())
    page.wait_for_function("window.viewer && viewer.animator && viewer.animator.actions.length > 0", timeout=timeout_ms)
    facts = page.evaluate("({actions: viewer.animator.actions.length, duration: viewer.animator.duration})")
    return facts | {"errors": errors}


def seek(page, time: float) -> None:
    """Pause the animation at ``time`` (s after the run's start) and let it render."""
    page.evaluate(
        f"viewer.animator.pause(); viewer.animator.seek({time!r}); "
        f"viewer.animator.display_progress({time!r}); viewer.set_dirty();"
    )
    page.wait_for_timeout(800)


def screenshot(html: Path, out: Path, time: float, width: int, height: int) -> None:
    """Save the frame at ``time`` of the page ``html`` to ``out`` (PNG)."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _screenshot_with_binary(html, out, width, height)
        return
    with sync_playwright() as p:
        browser, page, blocked = open_page(p, width, height)
        try:
            facts = load_replay(page, html)
            seek(page, time)
            page.screenshot(path=str(out))
        finally:
            browser.close()
    if facts["errors"] or blocked:
        raise RuntimeError(f"the page raised {facts['errors']} and asked for {blocked}")
    print(f"{out}: frame at t0 + {time} s of {html} ({facts['actions']} animated nodes, {facts['duration']:.3f} s)")


def _screenshot_with_binary(html: Path, out: Path, width: int, height: int) -> None:
    binary = chromium_binary()
    if binary is None:
        raise NoBrowserError(f"no headless browser: install playwright, or one of {', '.join(BINARIES)}")
    subprocess.run(
        [
            binary,
            "--headless",
            "--no-sandbox",
            *GL_ARGS,
            f"--window-size={width},{height}",
            "--virtual-time-budget=3000",
            f"--screenshot={out.resolve()}",
            html.resolve().as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    print(f"{out}: {html} as first shown (no playwright: no seeking)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--html", type=Path, help="replay page (default: write the 3-s solo12 trot's)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "replay_solo12.png", help="PNG to write")
    parser.add_argument("--time", type=float, default=1.5, help="animation time of the frame, s (default 1.5)")
    parser.add_argument("--size", default="1000x650", help="viewport WIDTHxHEIGHT in pixels")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="without --html, the page of a 0.3-s trot instead of 3 s, at t = 0.2 s: a smoke run",
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.time = min(args.time, 0.2)
    width, height = (int(x) for x in args.size.lower().split("x"))
    with tempfile.TemporaryDirectory() as folder:
        html = args.html
        if html is None:
            from contactdiff.cli import main as contactdiff

            html = Path(folder) / "solo12.html"
            t_final = "0.3" if args.quick else "3"
            status = contactdiff(["simulate", "solo12_trot", "--t-final", t_final, "--html", str(html)])
            if status:
                return status
        try:
            screenshot(html, args.out, args.time, width, height)
        except NoBrowserError as exc:
            print(f"replay_screenshot: {exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
