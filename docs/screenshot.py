"""Make ``docs/dashboard_study.png``: serve a fresh embedded database, calibrate
``examples/quick.toml`` (500 samples per stage, leader moves) on the two example logs through
the API, and photograph the study page in Debian's Chromium (Playwright). About a minute on
two cores.

    .venv/bin/python docs/screenshot.py [--out docs/dashboard_study.png]
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

from services.client import SCMCalibClient

ROOT = Path(__file__).resolve().parents[1]
TOKEN = "screenshot-token"
LOGS = ("wf34_s020.csv", "wf34_s050.csv")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "dashboard_study.png")
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    args = ap.parse_args()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    tmp = Path(tempfile.mkdtemp(prefix="scm-calib-shot-"))
    env = {k: v for k, v in os.environ.items() if not k.startswith("SCM_CALIB_")}
    env.update(SCM_CALIB_DATA_DIR=str(tmp / "data"), SCM_CALIB_API_TOKENS=TOKEN)
    base = f"http://127.0.0.1:{port}"
    server = subprocess.Popen(
        [sys.executable, "-m", "services.cli", "serve", "--port", str(port)],
        env=env,
        cwd=tmp,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        for _ in range(300):
            try:
                if httpx.get(base + "/health/ready").status_code == 200:
                    break
            except httpx.HTTPError:
                time.sleep(0.2)
        with SCMCalibClient(base, token=TOKEN) as api:
            ids = [api.upload_log(ROOT / "examples" / f)["id"] for f in LOGS]
            study = api.create_study(case=str(ROOT / "examples" / "quick.toml"), dataset_ids=ids)
            api.wait(study["id"], timeout=1800)
        from playwright.sync_api import sync_playwright

        with sync_playwright() as p:
            browser = p.chromium.launch(
                executable_path=args.chromium, headless=True, args=["--no-sandbox", "--disable-gpu"]
            )
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.goto(f"{base}/ui/studies/{study['id']}")
            page.wait_for_function(
                "() => document.querySelectorAll('[data-chart]').length >= 4 && "
                "[...document.querySelectorAll('[data-chart]')].every(c =>"
                " c.dataset.drawn === c.dataset.chart && c.querySelector('svg.chart[data-ready]'))",
                timeout=120_000,
            )
            page.screenshot(path=str(args.out), full_page=True)
            browser.close()
        print(f"wrote {args.out}")
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(timeout=30)


if __name__ == "__main__":
    main()
