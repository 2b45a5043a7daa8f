"""The screenshots of docs/serve.md: headless chromium (selenium, Debian's chromedriver) on a
``strol-bench serve`` at 127.0.0.1, a person pushing the arm's cup, then correcting the car.

    .venv/bin/python lab/serve_screenshot.py docs/img
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path


def main(dest: str) -> None:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    from strol_gym.benchmarks.serve.app import Server, serve_in_thread
    from strol_gym.benchmarks.serve.plan import StudyPlan

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or "chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1200,620"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)
    out = Path(tempfile.mkdtemp())
    stats = lambda: driver.execute_script("return window.strolStats")  # noqa: E731
    try:
        with serve_in_thread(Server(StudyPlan(practice=20.0), out, "shot")) as url:
            driver.get(f"{url}/?token=shot")
            time.sleep(1.0)
            driver.save_screenshot(str(Path(dest) / "serve_consent.png"))
            driver.find_element(By.ID, "agree").click()
            time.sleep(1.0)
            driver.find_element(By.ID, "start").click()
            while stats()["frames"] < 20:
                time.sleep(0.2)
            ActionChains(driver).key_down("d").perform()
            time.sleep(0.8)
            driver.save_screenshot(str(Path(dest) / "serve_arm.png"))
            ActionChains(driver).key_up("d").perform()
            while not driver.find_element(By.ID, "start").is_displayed():
                time.sleep(0.5)
            driver.find_element(By.ID, "start").click()
            frames = stats()["frames"]
            while stats()["frames"] < frames + 6:
                time.sleep(0.2)
            ActionChains(driver).key_down(Keys.ARROW_UP).perform()
            time.sleep(1.5)
            ActionChains(driver).key_up(Keys.ARROW_UP).perform()
            time.sleep(0.6)
            driver.save_screenshot(str(Path(dest) / "serve_car.png"))
    finally:
        driver.quit()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
