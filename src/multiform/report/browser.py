"""Open a report page in headless Chromium and read back what rendered (used by the report test)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--enable-logging=stderr", "--v=0", "--virtual-time-budget=10000"]


def chromium() -> str | None:
    """Path of a Chromium binary, if installed."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def render(page: str | os.PathLike, timeout: float = 60.0) -> dict[str, object]:
    """Load ``page`` headless; return the page's image/table counts and the console errors."""
    exe = chromium()
    if exe is None:
        raise FileNotFoundError("chromium is not installed (make setup installs it)")
    url = Path(page).resolve().as_uri()
    with tempfile.TemporaryDirectory() as profile:
        proc = subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--dump-dom", url],
                              capture_output=True, text=True, timeout=timeout)
    dom = proc.stdout
    attrs = {}
    m = re.search(r"<html[^>]*>", dom)
    if m:
        attrs = dict(re.findall(r'(data-[\w-]+)="([^"]*)"', m.group(0)))
    errors = [ln for ln in proc.stderr.splitlines()
              if "CONSOLE" in ln and ("Uncaught" in ln or "Error" in ln or "Failed to load" in ln)]
    return {"returncode": proc.returncode, "images": int(attrs.get("data-images", -1)),
            "images_ok": int(attrs.get("data-images-ok", -1)), "tables": int(attrs.get("data-tables", -1)),
            "console_errors": errors, "dom_length": len(dom), "dom": dom, "text": visible_text(dom)}


def visible_text(dom: str) -> str:
    """The text a reader sees on a page (scripts, styles and tags removed, entities decoded)."""
    import html
    dom = re.sub(r"(?is)<(script|style|title)[^>]*>.*?</\1>", " ", dom)
    return re.sub(r"\s+", " ", html.unescape(re.sub(r"<[^>]+>", " ", dom))).strip()


def screenshot(page: str | os.PathLike, out: str | os.PathLike, width: int = 1200, height: int = 6000,
               timeout: float = 60.0) -> Path:
    """A PNG of ``page`` as headless Chromium draws it (``width``×``height`` CSS pixels)."""
    exe = chromium()
    if exe is None:
        raise FileNotFoundError("chromium is not installed (make setup installs it)")
    out = Path(out).resolve()
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
                        f"--screenshot={out}", "--hide-scrollbars", Path(page).resolve().as_uri()],
                       capture_output=True, text=True, timeout=timeout, check=True)
    return out
