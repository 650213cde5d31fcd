"""``GET /health`` (the process answers), ``GET /health/live`` (it can still recover by itself:
a supervisor restarts it when not) and ``GET /health/ready`` (database writable; local pool
complete or broker reachable)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse

from services.config import Settings
from services.store import SchemaVersionError, Store
from services.store.engine import safe_url

from ..deps import SettingsDep, token_ok
from ..schemas import CheckOut, HealthOut, LiveOut, ReadyOut
from ..upload_slots import upload_slots
from . import errors

router = APIRouter(prefix="/health", tags=["health"])

BROKER_TIMEOUT_S = 2.0
#: a renewal of the database connections that has waited this long for the transactions in
#: flight to end will not come: the process cannot recover from the storage fault by itself
STUCK_RENEWAL_S = 60.0


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _reason(exc: BaseException) -> str:
    """The driver's error (``sqlite3.OperationalError: ...``) rather than SQLAlchemy's
    wrapper with its SQL and link."""
    orig = getattr(exc, "orig", None) or exc
    return _one_line(orig).split(" [SQL:")[0]


def check_database(store: Store | None, reveal: bool = True) -> CheckOut:
    """Reachable, at the code's schema revision and taking writes. ``reveal``: name the
    database (URL without password) and give the driver's message; otherwise only what is
    wrong (no path or host for callers without a token)."""
    if store is None:
        return CheckOut(ok=False, detail="the store is not open (server starting or stopping)")
    where = f"{safe_url(store.engine.url)} " if reveal else ""
    try:
        head = store.check_schema()
    except SchemaVersionError as exc:
        text = (
            str(exc)
            if reveal
            else (
                f"at revision {exc.current or 'base (empty)'}, code needs {exc.head}: "
                "run `scm-calib db upgrade`"
            )
        )
        return CheckOut(ok=False, detail=text)
    except Exception as exc:
        why = f": {_reason(exc)}" if reveal else f" ({type(exc).__name__})"
        return CheckOut(
            ok=False, detail=f"cannot reach the database {where}{why}".replace(" :", ":")
        )
    try:
        store.check_writable()
    except Exception as exc:
        why = _reason(exc) if reveal else type(exc).__name__
        return CheckOut(ok=False, detail=f"database {where}does not take writes ({why})")
    return CheckOut(ok=True, detail=f"{where}at revision {head}, writable".strip())


def check_pool(runtime) -> CheckOut:
    """The embedded server's local pool: loop alive, every process up."""
    if runtime is None:
        return CheckOut(ok=True, detail="no local workers (studies are recorded, not run here)")
    health = runtime.health()
    return CheckOut(ok=health.ok, detail=health.detail)


def check_broker(settings: Settings, reveal: bool = True) -> CheckOut:
    url = settings.broker_url or ""
    shown = (safe_url(url) if "://" in url else url) if reveal else "the broker"
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
        why = _one_line(exc) if reveal else type(exc).__name__
        return CheckOut(ok=False, detail=f"cannot reach {shown}: {why}")
    return CheckOut(ok=True, detail=f"{shown} reachable")


@router.get("", response_model=HealthOut, summary="Liveness")
def health(request: Request) -> HealthOut:
    """The process is up (no dependency is checked)."""
    return HealthOut(version=request.app.version, mode=request.app.state.mode)


def check_connections(store: Store | None) -> CheckOut:
    """The store's connections can be renewed after a storage fault (none held for good)."""
    if store is None:
        return CheckOut(ok=True, detail="the store is not open (server starting or stopping)")
    stuck = store.db.fault_reset.stuck_for()
    if stuck > STUCK_RENEWAL_S:
        return CheckOut(
            ok=False,
            detail=(
                f"the database connections wait {stuck:.0f} s for a renewal after a storage "
                "fault (a transaction never ended): restart the server"
            ),
        )
    renewed = store.db.fault_reset.resets
    return CheckOut(ok=True, detail=f"connections renewed {renewed} time(s) after storage faults")


def check_runtime(runtime) -> CheckOut:
    """The embedded server's local runtime loop runs (it stops only on an error it cannot
    pass, or with the server)."""
    if runtime is None:
        return CheckOut(ok=True, detail="no local workers")
    if runtime.alive:
        return CheckOut(ok=True, detail="the local runtime's loop runs")
    return CheckOut(ok=False, detail=runtime.health().detail)


@router.get(
    "/live",
    response_model=LiveOut,
    summary="Liveness",
    responses={503: {"model": LiveOut, "description": "Restart me: what failed."}, **errors()},
)
def live(request: Request):
    """Whether the server can still recover by itself: 503 when it cannot (the database
    connections cannot be renewed after a storage fault; the embedded server's local runtime
    has stopped), for a supervisor to restart it (Kubernetes' liveness probe). A database or
    broker that is down is not a reason (``/health/ready`` says so): the server recovers when
    it returns."""
    state = request.app.state
    checks = {
        "database": check_connections(getattr(state, "store", None)),
        "runtime": check_runtime(getattr(state, "runtime", None)),
    }
    failed = [f"{name}: {c.detail}" for name, c in checks.items() if not c.ok]
    if failed:
        body = LiveOut(status="not live", detail="; ".join(failed), checks=checks)
        return JSONResponse(body.model_dump(), status_code=503)
    return LiveOut(status="live", detail="ok", checks=checks)


@router.get(
    "/ready",
    response_model=ReadyOut,
    summary="Readiness",
    responses={503: {"model": ReadyOut, "description": "Not ready: what failed."}, **errors()},
)
def ready(request: Request, settings: SettingsDep):
    """The database is reachable, at the code's schema revision and takes writes; the
    embedded server's local pool is complete (distributed mode: the broker is reachable);
    ``uploads`` tells how many upload slots are in use (never a reason to be not ready).
    503 with what failed otherwise. Database and broker are named (and their drivers'
    messages given) only to callers with a valid token."""
    reveal = token_ok(request, settings)
    state = request.app.state
    checks = {"database": check_database(getattr(state, "store", None), reveal)}
    if settings.embedded:
        checks["pool"] = check_pool(getattr(state, "runtime", None))
    else:
        checks["broker"] = check_broker(settings, reveal)
    slots = upload_slots(request.app, settings)  # informative: full slots answer 429, not 503
    checks["uploads"] = CheckOut(
        ok=True, detail=f"{slots.busy} of {slots.limit} upload slots in use"
    )
    failed = [f"{name}: {c.detail}" for name, c in checks.items() if not c.ok]
    if failed:
        body = ReadyOut(status="not ready", detail="; ".join(failed), checks=checks)
        return JSONResponse(body.model_dump(), status_code=503)
    return ReadyOut(status="ready", detail="ok", checks=checks)
