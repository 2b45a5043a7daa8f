"""strol-bench serve in a real browser: Debian's headless chromium, driven by selenium through
chromedriver, on a server at 127.0.0.1. Keys pressed on the page become a correction on the arm
and one on the car, both logs replay, and closing the tab writes the session's end line."""

from __future__ import annotations

import contextlib
import json
import shutil
import time
from pathlib import Path

import pytest

pytest.importorskip("starlette")
pytest.importorskip("uvicorn")
pytest.importorskip("selenium")

CHROMIUM, DRIVER = shutil.which("chromium"), shutil.which("chromedriver")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None or DRIVER is None,
    reason="needs Debian's chromium and chromium-driver (.ci/run installs them)",
)
TOKEN = "browser-test-token"


def _browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1200,700", "--no-first-run", "--disable-extensions"):  # fmt: skip
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(DRIVER), options=options)


def _wait(what, timeout: float = 90.0, every: float = 0.2):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = what()
        if value:
            return value
        time.sleep(every)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def _lines(log: Path) -> list[dict]:
    return [json.loads(line) for line in log.read_text().splitlines() if line.strip()]


def _hold(driver, key: str, seconds: float) -> None:
    from selenium.webdriver.common.action_chains import ActionChains

    ActionChains(driver).key_down(key).perform()
    time.sleep(seconds)
    ActionChains(driver).key_up(key).perform()


def test_a_person_in_the_browser_corrects_the_arm_and_the_car(tmp_path):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    from strol_gym.benchmarks.cli import main
    from strol_gym.benchmarks.serve.app import Server, serve_in_thread
    from strol_gym.benchmarks.serve.plan import StudyPlan

    out = tmp_path / "out"
    server = Server(StudyPlan(practice=12.0), out, TOKEN, fps=6.0)
    driver = _browser()
    closed = False
    try:
        with serve_in_thread(server) as url:
            driver.get(f"{url}/?token={TOKEN}")
            consent = _wait(lambda: driver.find_element(By.ID, "consent").text)
            assert "anonymous id" in consent
            driver.find_element(By.ID, "agree").click()
            _wait(lambda: driver.find_element(By.ID, "start").is_displayed())
            driver.find_element(By.ID, "start").click()  # the arm's practice
            stats = lambda: driver.execute_script("return window.strolStats")  # noqa: E731
            _wait(lambda: stats()["frames"] >= 2, timeout=120)
            people = lambda: list(out.glob("p*/"))  # noqa: E731
            arm = _wait(lambda: next(people()[0].glob("00-arm-*.jsonl"), None))
            pushed = lambda: [  # noqa: E731  (a push's outcome: a correction or a reflex)
                r for r in _lines(arm) if r["type"] == "correction" or r.get("kind") == "reflex"
            ]
            for key in ("d", "a", "e"):  # as a person would: push, and again if it braked
                _hold(driver, key, 1.0)  # push the cup for a second, then let go
                with contextlib.suppress(AssertionError):
                    _wait(pushed, timeout=4.0)
                if any(r["type"] == "correction" for r in pushed()):
                    break
            _wait(lambda: any(r["type"] == "end" for r in _lines(arm)), timeout=60)
            kinds = [(r["type"], r.get("kind")) for r in _lines(arm)]
            assert sum(r["type"] == "correction" for r in _lines(arm)) >= 1, kinds
            # the car: hold Up for a step and more, then close the tab while it runs
            _wait(lambda: driver.find_element(By.ID, "start").is_displayed())
            driver.find_element(By.ID, "start").click()
            car = _wait(lambda: next(people()[0].glob("01-car-*.jsonl"), None), timeout=120)
            frames = stats()["frames"]
            _wait(lambda: stats()["frames"] > frames, timeout=120)
            _hold(driver, Keys.ARROW_UP, 1.2)
            _wait(lambda: any(r["type"] == "correction" for r in _lines(car)), timeout=30)
            assert not any(r["type"] == "end" for r in _lines(car))
            driver.quit()
            closed = True
            _wait(lambda: any(r["type"] == "end" for r in _lines(car)), timeout=60)
            assert _lines(car)[-1]["reason"] == "connection closed"
    finally:
        if not closed:
            driver.quit()
    for log in (arm, car):
        assert main(["replay", str(log), "--learners", "strol,gradient",
                     "--out", str(tmp_path / log.stem), "--no-plots"]) == 0  # fmt: skip
