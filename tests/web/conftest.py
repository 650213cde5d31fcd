"""The dashboard's browser tests import the API tests' helpers (a real ``scm-calib serve``)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "api"))
