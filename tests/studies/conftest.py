"""The study-service tests import the API tests' helpers (fresh databases, the app)."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "api"))
