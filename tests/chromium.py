"""A screenshot of a live page by headless Chromium, taken ``wait`` seconds after it opened, and
:func:`screenshot_until`: screenshots taken later and later until one shows what is expected.

Headless Chromium's ``--screenshot`` shoots at the page's load event, before a Meshcat page has
received its scene over the websocket. So the page opened is a local wrapper: the live page in a
full-window iframe, plus a 1-pixel image whose server answers only after ``wait`` seconds, which
holds the load event (and the shot) back until then.
"""

from __future__ import annotations

import http.server
import shutil
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

_GIF = bytes.fromhex("47494638396101000100800000000000ffffff21f90401000000002c00000000010001000002024401003b")


#: The waits of :func:`screenshot_until` (s): a page that a loaded host has not drawn after the
#: first is shot again later; the last is the test's stated time-out.
WAITS = (10.0, 30.0, 120.0)


def screenshot_until(url: str, path: Path, shows: Callable[[Path], bool], waits: tuple[float, ...] = WAITS,
                     size: tuple[int, int] = (800, 600)) -> tuple[Path, bool]:
    """Screenshots of ``url`` after each of ``waits`` seconds until ``shows(picture)`` holds: the
    picture and whether it does. The test then asserts on it, whatever the host's load."""
    for wait in waits:
        picture = screenshot_after(url, path, wait=wait, size=size)
        if shows(picture):
            return picture, True
    return picture, False


def screenshot_after(url: str, path: Path, wait: float = 10.0, size: tuple[int, int] = (800, 600)) -> Path:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise FileNotFoundError("chromium (apt-get install chromium)")

    class Page(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            if self.path.startswith("/hold"):
                time.sleep(wait)
                body, kind = _GIF, "image/gif"
            else:
                body = (f'<html><body style="margin:0"><iframe src="{url}" style="border:0;width:100vw;height:100vh">'
                        '</iframe><img src="/hold" width="1" height="1"></body></html>').encode()
                kind = "text/html"
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Page)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        path = Path(path)
        # A profile of its own: another Chromium on the host (another test run) never shares it.
        with tempfile.TemporaryDirectory(prefix="chromium-profile-", ignore_cleanup_errors=True) as profile:
            subprocess.run(
                [chromium, "--headless", "--no-sandbox", "--enable-unsafe-swiftshader", "--hide-scrollbars",
                 f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}", f"--screenshot={path}",
                 f"http://127.0.0.1:{server.server_address[1]}/"],
                capture_output=True, timeout=wait + 90, check=True)
        return path
    finally:
        server.shutdown()
        server.server_close()
