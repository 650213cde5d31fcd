"""``GET /health`` (liveness) and ``GET /health/ready`` (database and broker reachable)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from services.config import Settings
from services.store import SchemaVersionError, Store
from services.store.engine import safe_url
from services.store.migrate import check_revision

from ..deps import SettingsDep
from ..schemas import CheckOut, HealthOut, ReadyOut
from . import errors

router = APIRouter(prefix="/health", tags=["health"])

BROKER_TIMEOUT_S = 2.0


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def check_database(store: Store | None) -> CheckOut:
    if store is None:
        return CheckOut(ok=False, detail="the store is not open (server starting or stopping)")
    try:
        head = check_revision(store.engine)
    except SchemaVersionError as exc:
        return CheckOut(ok=False, detail=str(exc))
    except Exception as exc:
        return CheckOut(
            ok=False, detail=f"cannot reach {safe_url(store.engine.url)}: {_one_line(exc)}"
        )
    return CheckOut(ok=True, detail=f"{safe_url(store.engine.url)} at revision {head}")


def check_broker(settings: Settings) -> CheckOut:
    url = settings.broker_url or ""
    shown = safe_url(url) if "://" in url else url
    try:
        if url.startswith(("redis://", "rediss://", "unix://")):
            import redis

            client = redis.Redis.from_url(
                url, socket_connect_timeout=BROKER_TIMEOUT_S, socket_timeout=BROKER_TIMEOUT_S
            )
            try:
                client.ping()
            finally:
                client.close()
        else:
            from kombu import Connection

            with Connection(url, connect_timeout=BROKER_TIMEOUT_S) as conn:
                conn.ensure_connection(max_retries=1, timeout=BROKER_TIMEOUT_S)
    except Exception as exc:
        return CheckOut(ok=False, detail=f"cannot reach {shown}: {_one_line(exc)}")
    return CheckOut(ok=True, detail=f"{shown} reachable")


@router.get("", response_model=HealthOut, summary="Liveness")
def health(request: Request) -> HealthOut:
    """The process is up (no dependency is checked)."""
    return HealthOut(version=request.app.version, mode=request.app.state.mode)


@router.get(
    "/ready",
    response_model=ReadyOut,
    summary="Readiness",
    responses={503: {"model": ReadyOut, "description": "Not ready: what failed."}, **errors()},
)
def ready(request: Request, settings: SettingsDep):
    """The database is reachable and at the code's schema revision; in distributed mode the
    broker is reachable too. 503 with what failed otherwise."""
    checks = {"database": check_database(getattr(request.app.state, "store", None))}
    if not settings.embedded:
        checks["broker"] = check_broker(settings)
    failed = [f"{name}: {c.detail}" for name, c in checks.items() if not c.ok]
    if failed:
        body = ReadyOut(status="not ready", detail="; ".join(failed), checks=checks)
        return JSONResponse(body.model_dump(), status_code=503)
    return ReadyOut(status="ready", detail="ok", checks=checks)
