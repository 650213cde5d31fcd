"""Content hashes for identical re-upload detection (sha256, hex)."""

import hashlib
import json
from collections.abc import Mapping
from typing import Any

from .csvtext import CanonicalDigest, decode_text

LOG_HASH_PREFIX = b"scm-swt-log/1\n"


def canonical_json(obj: Any) -> str:
    """JSON with sorted keys, no whitespace, floats as shortest round-trip repr."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def log_digest() -> CanonicalDigest:
    """A digest to feed a log's physical lines to; finish it with :func:`finish_log_hash`."""
    return CanonicalDigest(LOG_HASH_PREFIX)


def finish_log_hash(digest: CanonicalDigest, metadata: Mapping[str, Any]) -> str:
    """Hash of a time-series upload: canonical text (BOM, line endings, trailing blanks removed)
    plus the canonical JSON of the parsed metadata (conditions in SI and provenance)."""
    return digest.finish(b"\n", canonical_json(metadata).encode("utf-8"))


def log_hash(data: bytes | str, metadata: Mapping[str, Any]) -> str:
    """:func:`finish_log_hash` of a whole text in memory."""
    digest = log_digest()
    for line in decode_text(data).split("\n"):
        digest.add(line)
    return finish_log_hash(digest, metadata)


def summary_hash(content: Mapping[str, Any]) -> str:
    """Hash of a summary dataset's parsed SI content, so its JSON and CSV forms coincide."""
    h = hashlib.sha256(b"scm-swt-summary/1\n")
    h.update(canonical_json(content).encode("utf-8"))
    return h.hexdigest()
