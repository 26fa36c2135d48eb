"""A headless Chromium for the studio's browser tests, benchmark and screenshot: Debian's
``chromium`` driven through its ``chromium-driver`` by Selenium (``.ci/run`` installs them).

:func:`browser_problem` says in one sentence why no browser can run here (the tests skip
with it); :func:`start_browser` starts one. Nothing is downloaded: Selenium is given the
system's driver and browser, so its own driver manager stays idle.
"""

from __future__ import annotations

import importlib.util
import shutil

#: Where Debian puts them (also found on PATH).
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
DRIVERS = ("chromedriver",)


def _which(names) -> str | None:
    for name in names:
        found = shutil.which(name) or shutil.which(name, path="/usr/bin:/usr/lib/chromium")
        if found:
            return found
    return None


def browser_problem() -> str | None:
    """None when a headless browser can be started, else why not (one sentence)."""
    if importlib.util.find_spec("selenium") is None:
        return "selenium is not installed (pip install 'mimarble[test]')"
    if _which(BROWSERS) is None:
        return "no chromium on PATH (apt-get install chromium chromium-driver)"
    if _which(DRIVERS) is None:
        return "no chromedriver on PATH (apt-get install chromium-driver)"
    return None


def start_browser(width: int = 1400, height: int = 900):
    """A headless Chromium under Selenium, its console log readable
    (``driver.get_log("browser")``); the caller quits it."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = _which(BROWSERS)
    for argument in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                     "--disable-gpu", f"--window-size={width},{height}",
                     "--disable-background-timer-throttling",
                     "--disable-renderer-backgrounding", "--no-first-run"):
        options.add_argument(argument)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(executable_path=_which(DRIVERS)), options=options)


def console_errors(driver) -> list[str]:
    """The browser console's errors (SEVERE entries) since the last call."""
    return [entry["message"] for entry in driver.get_log("browser")
            if entry.get("level") == "SEVERE"]
