"""Refresh ``docs/screenshots/``: every dashboard page at 1280 and 400 px wide.

Runs the browser tests that photograph the pages (``tests/web/test_dashboard_browser.py``:
every page, a comparison of two runs, a cancelled study; a real
``scm-calib serve`` with small studies of every kind) into a temporary folder, then keeps the
1280 and 400 px shots, reduced to 256 colours (a tenth of the bytes; text stays sharp). Needs
Debian's Chromium (``/usr/bin/chromium``) and, like the tests, PostgreSQL and Redis. About two
minutes on two cores.

    .venv/bin/python docs/screenshots.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "screenshots"
TESTS = ("every_page", "compare_page_of_two_runs", "cancel_works")
KEEP = ("_1280x800.png", "_400x800.png", "study_cancelled.png")


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="scm-calib-shots-") as tmp:
        env = dict(os.environ, SCM_CALIB_SHOTS_DIR=tmp)
        cmd = [sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider"]
        cmd += ["tests/web/test_dashboard_browser.py", "-k", " or ".join(TESTS)]
        subprocess.run(cmd, cwd=ROOT, env=env, check=True)
        OUT.mkdir(exist_ok=True)
        for old in OUT.glob("*.png"):
            old.unlink()
        for shot in sorted(Path(tmp).glob("*.png")):
            if shot.name.endswith(KEEP) and not shot.name.startswith("figure_"):
                image = Image.open(shot).convert("RGB").quantize(colors=256, dither=Image.NONE)
                image.save(OUT / shot.name, optimize=True)
                print(f"{shot.name}: {(OUT / shot.name).stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
