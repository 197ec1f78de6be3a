"""A scripted person for tests and the docs' screenshot: headless Chromium driven by Selenium
(Debian's ``chromium`` and ``chromium-driver``; ``pip install selenium``) that answers each
question on the page by pressing the keyboard shortcut of the optimal DoorKey action for the
state the page shows (the question's ``data-state``)."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from tlac.teachers.human import decode_state

POLL = 0.005
"""Seconds between two looks at the page."""

_READ = """
const f = document.getElementById('frame'), plot = document.getElementById('plot');
if (!f || !plot) return ['', '', [], 0];  // the page is still loading
const b = Array.from(document.querySelectorAll('#buttons button')).map(x => x.dataset.key);
return [f.dataset.question || '', f.dataset.state || '', b, Number(plot.dataset.points || 0)];
"""


class BrowserPerson:
    """Opens ``url`` in headless Chromium and answers in a thread of its own until
    :meth:`stop`; ``policy(state) -> action`` (default: DoorKey's optimal teacher). Writes a
    screenshot of the page to ``screenshot`` once it has given ``shot_after`` answers and the
    plot has ``shot_points`` evaluations of the student (or at :meth:`stop`, if never)."""

    def __init__(
        self,
        url: str,
        browser: str,
        driver: str,
        policy: Any = None,
        screenshot: str | Path | None = None,
        shot_after: int = 40,
        shot_points: int = 3,
        window: tuple[int, int] = (1100, 760),
    ):
        self.url, self.browser, self.driver_path = url, browser, driver
        if policy is None:
            from tlac.domains.doorkey.planner import DoorKeyOptimalTeacher

            optimal = DoorKeyOptimalTeacher()
            policy = lambda state: int(optimal.predict(np.asarray(state)[None])[0])  # noqa: E731
        self.policy = policy
        self.screenshot = None if screenshot is None else Path(screenshot)
        self.shot_after, self.shot_points, self.window = shot_after, shot_points, window
        self.answers = 0
        self.error: str | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.driver: Any = None

    def start(self) -> None:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service

        options = webdriver.ChromeOptions()
        options.binary_location = self.browser
        for flag in (
            "--headless=new",
            "--no-sandbox",
            "--disable-dev-shm-usage",
            "--disable-gpu",
            f"--window-size={self.window[0]},{self.window[1]}",
        ):
            options.add_argument(flag)
        self.driver = webdriver.Chrome(service=Service(self.driver_path), options=options)
        self.driver.get(self.url)
        self._thread = threading.Thread(target=self._run, name="scripted-person", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
        if self.driver is not None:
            try:
                self.driver.quit()
            except Exception:  # noqa: BLE001 - the browser may be gone already
                pass

    def _key(self, key: str) -> str:
        from selenium.webdriver.common.keys import Keys

        return {
            "ArrowLeft": Keys.ARROW_LEFT,
            "ArrowRight": Keys.ARROW_RIGHT,
            "ArrowUp": Keys.ARROW_UP,
            "ArrowDown": Keys.ARROW_DOWN,
            "Enter": Keys.ENTER,
            " ": Keys.SPACE,
        }.get(key, key)

    def _run(self) -> None:
        from selenium.webdriver.common.by import By

        try:
            body = self.driver.find_element(By.TAG_NAME, "body")
            last = ""
            shot = False
            while not self._stop.is_set():
                question, state, keys, points = self.driver.execute_script(_READ)
                if not question or question == last or not state or not keys:
                    time.sleep(POLL)
                    continue
                action = self.policy(decode_state(state))
                body.send_keys(self._key(keys[action]))
                last = question
                self.answers += 1
                if (
                    self.screenshot is not None
                    and not shot
                    and self.answers >= self.shot_after
                    and points >= self.shot_points
                ):
                    self._shoot(question)
                    shot = True
            if self.screenshot is not None and not shot:
                self.driver.save_screenshot(str(self.screenshot))
        except Exception as exc:  # noqa: BLE001 - reported by the test, not raised in a thread
            if not self._stop.is_set():
                self.error = f"{type(exc).__name__}: {str(exc)[:300]}"

    def _shoot(self, question: str) -> None:
        """A screenshot with a question on the page (the next one to come)."""
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and not self._stop.is_set():
            shown, _, _, _ = self.driver.execute_script(_READ)
            if shown and shown != question:
                break
            time.sleep(POLL)
        self.screenshot.parent.mkdir(parents=True, exist_ok=True)
        self.driver.save_screenshot(str(self.screenshot))
