"""Screenshot a Rerun recording on a machine with no screen (for docs/img/).

Serves the recording with ``rerun FILE --serve-web`` (the web viewer bundled
in rerun-sdk), opens it in headless Chromium driven by Playwright (software
WebGL: SwiftShader), waits until the data has arrived and saves a PNG.

Needs, besides dexplan's ``viz`` extra, Chromium and Playwright's Python
package (neither is a dexplan dependency; nothing in the tests uses them)::

    apt-get install chromium            # or any Chromium / Chrome binary
    pip install playwright              # the browser download is not needed

Usage::

    python scripts/rerun_screenshot.py plan.rrd docs/img/plan.png --wait 60

The first frames after loading can lag on a busy machine: give ``--wait``
enough seconds for the recording to load (60-90 s for a few MB on 2 cores).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.parse
from pathlib import Path

CHROMIUM_ARGS = [
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _wait_for_port(port: int, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    raise SystemExit(f"rerun's web viewer did not start on port {port}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recording", type=Path, help=".rrd file")
    ap.add_argument("output", type=Path, help=".png file to write")
    ap.add_argument("--wait", type=float, default=60.0, help="seconds to let it load")
    ap.add_argument("--width", type=int, default=1600)
    ap.add_argument("--height", type=int, default=1000)
    ap.add_argument("--chromium", default=shutil.which("chromium") or "/usr/bin/chromium")
    args = ap.parse_args()
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        print("needs playwright: pip install playwright", file=sys.stderr)
        return 2
    if not args.recording.is_file():
        print(f"no such recording: {args.recording}", file=sys.stderr)
        return 2
    rerun = shutil.which("rerun")
    if rerun is None:
        print("needs rerun-sdk: pip install 'dexplan[viz]'", file=sys.stderr)
        return 2
    web, grpc = _free_port(), _free_port()
    command = [rerun, str(args.recording), "--serve-web", "--web-viewer-port", str(web)]
    command += ["--port", str(grpc)]
    server = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # `rerun` execs a viewer child: stop the whole group
    )
    try:
        _wait_for_port(web, 30.0)
        proxy = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc}/proxy", safe="")
        url = f"http://127.0.0.1:{web}/?url={proxy}&renderer=webgl"
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=args.chromium, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": args.width, "height": args.height})
            page.goto(url)
            time.sleep(args.wait)
            page.screenshot(path=str(args.output))
            browser.close()
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=10)
    print(args.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
