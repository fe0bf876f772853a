"""Headless Chromium for the viewer's tests and benchmark (Playwright, Debian's browser).

No browser is downloaded: Playwright drives the system's ``chromium`` (Debian's
package). :func:`chromium_executable` finds it and, asked to, installs it with
``apt-get`` (root only). Playwright is imported here only (heavy module, and a
development dependency).
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hierplan_opt.core.errors import InputError

log = logging.getLogger(__name__)

#: Where Debian's package puts the browser (the ``/usr/bin/chromium`` wrapper calls it).
_CANDIDATES = ("/usr/lib/chromium/chromium", "/usr/bin/chromium", "/usr/bin/chromium-browser")


def _find() -> str | None:
    env = os.environ.get("HIERPLAN_CHROMIUM")
    if env and Path(env).is_file():
        return env
    for c in _CANDIDATES:
        if Path(c).is_file() and os.access(c, os.X_OK):
            return c
    return shutil.which("chromium") or shutil.which("chromium-browser")


def chromium_executable(install: bool = False) -> str:
    """Path of a Chromium to drive (``HIERPLAN_CHROMIUM`` overrides).

    With ``install``, a missing browser is installed with ``apt-get install -y chromium``
    (after ``apt-get update`` if the first try fails); that needs root and apt.
    """
    found = _find()
    if found or not install:
        if found:
            return found
        raise InputError("no chromium found (apt-get install chromium, or set HIERPLAN_CHROMIUM)")
    if shutil.which("apt-get") is None or os.geteuid() != 0:
        raise InputError("no chromium found and apt-get (as root) is not available to install it")
    cmd = ["apt-get", "install", "-y", "-q", "chromium"]
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    log.info("installing chromium: %s", " ".join(cmd))
    if subprocess.run(cmd, env=env, capture_output=True).returncode != 0:
        subprocess.run(["apt-get", "update", "-q"], env=env, capture_output=True)
        done = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            raise InputError(f"apt-get install chromium failed: {done.stderr.strip()[-300:]}")
    found = _find()
    if not found:
        raise InputError("apt-get installed chromium but no executable was found")
    return found


@contextlib.contextmanager
def browser(executable: str | None = None) -> Iterator[Any]:
    """A headless Chromium (Playwright ``Browser``), closed on exit."""
    from playwright.sync_api import sync_playwright  # heavy module, development dependency

    exe = executable or chromium_executable()
    with sync_playwright() as pw:
        b = pw.chromium.launch(
            executable_path=exe,
            headless=True,
            args=["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"],
        )
        try:
            yield b
        finally:
            b.close()


def open_view(
    b: Any, path: str | Path, *, width: int = 1200, height: int = 800, timeout: float = 30.0
) -> tuple[Any, list[str], float]:
    """Open a viewer page in a new page of ``b``: ``(page, console errors, load seconds)``.

    The load time runs from navigation start to the first drawn frame (the page's own
    ``performance.now()`` clock).
    """
    page = b.new_page(viewport={"width": width, "height": height})
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(Path(path).resolve().as_uri(), timeout=timeout * 1000)
    ok = page.evaluate("window.hierplan.ready")
    if not ok:
        errors.extend(page.evaluate("window.hierplan.errors"))
    first = page.evaluate("window.hierplan.firstFrameMs")
    return page, errors, (float(first) / 1000.0 if first is not None else float("nan"))


__all__ = ["browser", "chromium_executable", "open_view"]
