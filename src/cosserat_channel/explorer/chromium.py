"""Headless Chromium driven by selenium, for the explorer's browser test and its benchmark.

Debian's ``chromium`` and ``chromium-driver`` and the Python package ``selenium`` (the ``test``
extra) are needed; :func:`missing` says which is absent, in one line.
"""

from __future__ import annotations

import shutil
import tempfile

# Chromium's flags for an unattended run: no sandbox (containers, root), no GPU, nothing
# fetched from the network but the page, a window wide enough for the page's three columns.
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--window-size=1600,1050")


def _paths():
    return (shutil.which("chromium") or shutil.which("chromium-browser"),
            shutil.which("chromedriver"))


def missing() -> str | None:
    """What to install before a browser can be driven (one line), or None when all is there."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed: pip install 'cosserat-channel[test]'"
    browser, driver = _paths()
    if not (browser and driver):
        return "Chromium is not installed: apt-get install chromium chromium-driver"
    return None


def driver():
    """``(webdriver, profile directory)``: a fresh headless Chromium with its own empty profile
    (remove the directory after ``webdriver.quit()``)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    browser, chromedriver = _paths()
    profile = tempfile.mkdtemp(prefix="cosserat-channel-chromium-")
    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for flag in (*FLAGS, f"--user-data-dir={profile}"):
        opts.add_argument(flag)
    return webdriver.Chrome(service=Service(chromedriver), options=opts), profile
