"""The ``scm-calib`` command line."""

from __future__ import annotations

import sys

import click

from .calibrate import calibrate
from .db import db
from .sensitivity import sensitivity
from .serve import serve
from .simulate import simulate
from .synth import synth
from .upload import upload
from .worker_cmd import reaper, worker


class _Group(click.Group):
    """Click group whose usage errors are one line on stderr with exit code 2."""

    def main(self, *args, **kwargs):  # type: ignore[override]
        kwargs.setdefault("standalone_mode", False)
        try:
            return super().main(*args, **kwargs)
        except click.exceptions.Abort:
            click.echo("aborted", err=True)
            sys.exit(130)
        except click.ClickException as exc:
            click.echo(f"error: {exc.format_message()}", err=True)
            sys.exit(exc.exit_code)
        except click.exceptions.Exit as exc:
            sys.exit(exc.exit_code)


@click.group(cls=_Group)
@click.version_option(package_name="scm-calib")
def cli() -> None:
    """Calibrate SCM wheel-soil contact models from single-wheel tests (Bayesian TMCMC)."""


cli.add_command(simulate)
cli.add_command(synth)
cli.add_command(calibrate)
cli.add_command(sensitivity)
cli.add_command(db)
cli.add_command(worker)
cli.add_command(reaper)
cli.add_command(serve)
cli.add_command(upload)
