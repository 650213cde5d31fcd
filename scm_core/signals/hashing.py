"""Content hashes for identical re-upload detection (sha256, hex)."""

import hashlib
import json
from collections.abc import Mapping
from typing import Any

from .csvtext import canonical_text


def canonical_json(obj: Any) -> str:
    """JSON with sorted keys, no whitespace, floats as shortest round-trip repr."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def log_hash(data: bytes | str, metadata: Mapping[str, Any]) -> str:
    """Hash of a time-series upload: canonical text (BOM, line endings, trailing blanks removed)
    plus the canonical JSON of the parsed metadata (conditions in SI and provenance)."""
    h = hashlib.sha256(b"scm-swt-log/1\n")
    h.update(canonical_text(data).encode("utf-8"))
    h.update(b"\n")
    h.update(canonical_json(metadata).encode("utf-8"))
    return h.hexdigest()


def summary_hash(content: Mapping[str, Any]) -> str:
    """Hash of a summary dataset's parsed SI content, so its JSON and CSV forms coincide."""
    h = hashlib.sha256(b"scm-swt-summary/1\n")
    h.update(canonical_json(content).encode("utf-8"))
    return h.hexdigest()
