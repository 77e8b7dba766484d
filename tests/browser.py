"""A real headless browser for the report page's tests: Chromium driven from the command line
(``--dump-dom`` after the page's own load-status script ran, ``--screenshot``). Tests skip, with
the reason, where no Chromium is installed (CI installs Debian's, see ``.ci/run``)."""

from __future__ import annotations

import pathlib
import re
import shutil
import subprocess
import tempfile

import pytest

NAMES = ("chromium", "chromium-browser", "google-chrome")
#: Virtual milliseconds the page may take to load its images and videos.
BUDGET_MS = 20_000


def chromium() -> str:
    """Returns the Chromium executable, or skips the calling test saying that none is installed."""
    for name in NAMES:
        path = shutil.which(name)
        if path:
            return path
    pytest.skip(f"no headless browser: none of {', '.join(NAMES)} is installed (CI installs one)")


def _run(page: pathlib.Path, *options: str) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory() as profile:
        return subprocess.run(
            [
                chromium(),
                "--headless",
                "--no-sandbox",  # as root (CI containers)
                "--disable-gpu",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--no-first-run",
                "--mute-audio",
                f"--user-data-dir={profile}",
                f"--virtual-time-budget={BUDGET_MS}",
                *options,
                pathlib.Path(page).resolve().as_uri(),
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=True,
        )


def loaded_dom(page) -> str:
    """Returns the page's DOM after it loaded (its script marks each image and video)."""
    return _run(page, "--dump-dom").stdout


def load_states(dom: str) -> dict[str, str]:
    """Returns each image's and video's ``src`` -> its ``data-loaded`` ("1", "0" or "" if the page
    never decided)."""
    states = {}
    for tag in re.findall(r"<(?:img|video)\b[^>]*>", dom):
        src = re.search(r'src="([^"]*)"', tag)
        state = re.search(r'data-loaded="([01])"', tag)
        states[src.group(1) if src else ""] = state.group(1) if state else ""
    return states


def screenshot(page, path, width: int = 1300, height: int = 2400) -> pathlib.Path:
    """Saves a PNG screenshot of the page; returns its path."""
    path = pathlib.Path(path)
    _run(page, f"--screenshot={path}", f"--window-size={width},{height}", "--hide-scrollbars")
    return path
