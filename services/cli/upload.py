"""``scm-calib upload``: send an SWT log (or summary file) to a running server."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .common import CLIError


class ServerError(click.ClickException):
    """The server refused the request or could not be reached: exit code 1."""

    exit_code = 1


@click.command("upload")
@click.argument("log", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--meta",
    type=click.Path(dir_okay=False, path_type=Path),
    help="JSON object of metadata (test conditions, provenance); merged over the sidecar "
    "LOG.json, which is sent if present.",
)
@click.option(
    "--server",
    envvar="SCM_CALIB_SERVER",
    required=True,
    metavar="URL",
    help="Server, e.g. http://127.0.0.1:8000 [env SCM_CALIB_SERVER].",
)
@click.option(
    "--token", envvar="SCM_CALIB_TOKEN", metavar="T", help="API token [env SCM_CALIB_TOKEN]."
)
@click.option(
    "--offset",
    type=click.FloatRange(min=0),
    default=None,
    help="Averaging offset of the log [s] (server default 40).",
)
@click.option("--json", "as_json", is_flag=True, help="Print the dataset record as JSON.")
@click.option("--timeout", type=click.FloatRange(min=1), default=120.0, show_default=True)
def upload(
    log: Path,
    meta: Path | None,
    server: str,
    token: str | None,
    offset: float | None,
    as_json: bool,
    timeout: float,
) -> None:
    """Upload the SWT log LOG (CSV) and print the dataset id. An identical file uploaded
    before gives the same id. Exit code 2 for a bad command line or file, 1 when the server
    refuses the upload or cannot be reached."""
    from services.client import SCMCalibClient, SCMCalibError

    if not log.is_file():
        raise CLIError(f"{log}: no such file")
    metadata = None
    if meta is not None:
        try:
            metadata = json.loads(meta.read_text(encoding="utf-8-sig"))
        except OSError as exc:
            raise CLIError(f"--meta {meta}: {exc.strerror or exc}") from None
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise CLIError(f"--meta {meta}: not valid JSON ({exc})") from None
        if not isinstance(metadata, dict):
            raise CLIError(f"--meta {meta}: must be a JSON object")
    if not server.startswith(("http://", "https://")):
        raise CLIError(f"--server {server}: give a URL such as http://127.0.0.1:8000")
    try:
        with SCMCalibClient(server, token=token, timeout=timeout) as api:
            record = api.upload_log(log, metadata, offset=offset)
    except SCMCalibError as exc:
        where = f"server answered {exc.status_code}: " if exc.status_code else ""
        raise ServerError(f"{where}{' '.join(str(exc).split())}") from None
    if as_json:
        click.echo(json.dumps(record, indent=2))
        return
    click.echo(record["id"])
    state = "stored" if record.get("created") else "already stored (identical content)"
    click.echo(f"dataset {record['id']} ({record['name']}): {state}", err=True)
