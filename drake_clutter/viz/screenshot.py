"""A picture of an exported Meshcat page: headless Chromium renders the static HTML (software
WebGL) and writes a PNG.

Chromium is Debian's ``chromium`` package (`.ci/run` installs it when missing); nothing is
downloaded at run time.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

WINDOW = (800, 600)  # px; software WebGL: rendering cost grows with the area
BUDGET_MS = 2000  # virtual time for loading and drawing the page (measured: enough)


class ChromiumMissing(RuntimeError):
    """Debian's chromium is not on PATH."""


def chromium_path() -> str:
    """The chromium executable; raises ChromiumMissing naming the package to install."""
    path = shutil.which("chromium")
    if path is None:
        raise ChromiumMissing("Debian's chromium is not installed (apt-get install chromium)")
    return path


def screenshot(html: Path, png: Path, window: tuple[int, int] = WINDOW,
               budget_ms: int = BUDGET_MS, timeout_s: float = 120.0, tries: int = 2) -> Path:
    """Renders ``html`` in headless Chromium at ``window`` (width, height px) after
    ``budget_ms`` of virtual time and writes ``png``. A Chromium that hangs past ``timeout_s``
    is killed and started again, ``tries`` times in all (headless Chromium now and then never
    exits on a loaded machine); raises RuntimeError with Chromium's last output when no picture
    was written."""
    png = Path(png)
    for attempt in range(1, tries + 1):
        png.unlink(missing_ok=True)
        try:
            result = _chromium(html, png, window, budget_ms, timeout_s)
        except subprocess.TimeoutExpired:
            if attempt == tries:
                raise RuntimeError(f"chromium did not finish in {timeout_s:g} s, "
                                   f"{tries} times") from None
            continue
        if not png.exists():
            raise RuntimeError(f"chromium wrote no screenshot (exit {result.returncode}):\n"
                               f"{result.stderr[-2000:]}")
        return png
    raise RuntimeError("tries must be at least 1")


def _chromium(html: Path, png: Path, window: tuple[int, int], budget_ms: int,
              timeout_s: float) -> subprocess.CompletedProcess:
    """One headless Chromium run that writes ``png`` (a fresh profile each time)."""
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run(
            [chromium_path(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
             "--no-first-run", "--disable-background-networking", "--disable-component-update",
             "--disable-sync", f"--user-data-dir={profile}",
             f"--window-size={window[0]},{window[1]}", f"--virtual-time-budget={budget_ms}",
             f"--screenshot={png.resolve()}", Path(html).resolve().as_uri()],
            capture_output=True, text=True, timeout=timeout_s)
