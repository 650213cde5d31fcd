"""The ``scm-calib`` command line."""

from __future__ import annotations

import importlib
import sys

import click

# command name -> "module:attribute", imported only when the command runs (numba, scipy and the
# web stack are slow to import; `scm-calib upload` should not pay for them). The commands that
# run a kind of study are the kinds' own (``StudyKind.cli``), mounted from the registry between
# these two groups.
TOOLS_BEFORE = {
    "simulate": "services.cli.simulate:simulate",
    "synth": "services.cli.synth:synth",
}
TOOLS_AFTER = {
    "check": "services.cli.check:check",
    "diagnose": "services.cli.runs:diagnose",
    "compare": "services.cli.compare:compare",
    "export": "services.cli.export:export",
    "db": "services.cli.db:db",
    "serve": "services.cli.serve:serve",
    "worker": "services.cli.worker_cmd:worker",
    "reaper": "services.cli.worker_cmd:reaper",
    "upload": "services.cli.upload:upload",
}


def kind_commands() -> dict[str, str]:
    """The commands of the registry's kinds (name -> "module:attribute")."""
    from services.studies.kinds import KINDS

    return {k.cli.name: k.cli.command for k in KINDS.values() if k.cli is not None}


def commands() -> dict[str, str]:
    """Every command of ``scm-calib``, in the order ``--help`` lists them."""
    return {**TOOLS_BEFORE, **kind_commands(), **TOOLS_AFTER}


class _Group(click.Group):
    """Click group with lazily imported commands whose usage errors are one line on stderr
    with exit code 2."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(commands())

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        target = TOOLS_BEFORE.get(name) or TOOLS_AFTER.get(name) or kind_commands().get(name)
        if target is None:
            return None
        module, attr = target.split(":")
        return getattr(importlib.import_module(module), attr)

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
