"""Shared pieces of the ``scm-calib`` commands: one-line errors and input loading."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import logging
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import click

from scm_core.calibration import CaseDefinition, CaseError, load_case
from scm_core.signals import LogFormatError, SWTDataset, load_dataset


def data_option(help: str):
    """The repeatable ``--data PATH`` option of the commands that read SWT datasets."""
    return click.option(
        "--data",
        "data",
        multiple=True,
        type=click.Path(dir_okay=False, path_type=Path),
        help=help,
    )


def option_group(name: str, cls: type, *options: Callable[[Any], Any]):
    """Decorator: the click ``options`` (named as the fields of the dataclass ``cls``) reach
    the command as one ``cls`` value under the keyword ``name``."""
    fields = [f.name for f in dataclasses.fields(cls)]

    def decorate(command: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(command)
        def grouped(*args: Any, **kwargs: Any) -> Any:
            kwargs[name] = cls(**{f: kwargs.pop(f) for f in fields})
            return command(*args, **kwargs)

        for option in reversed(options):
            grouped = option(grouped)
        return grouped

    return decorate


class CLIError(click.ClickException):
    """A bad input (case file, dataset, option): one line on stderr, exit code 2."""

    exit_code = 2


class StudyFailed(click.ClickException):
    """A study that ran and failed (a batch failed at every attempt): one line on stderr
    naming why, exit code 1 (not a bad input; its stored stages stay)."""

    exit_code = 1


class _OneLine(logging.Formatter):
    """``warning: message`` on one line; an exception as its type and message, no traceback."""

    def format(self, record: logging.LogRecord) -> str:
        text = " ".join(record.getMessage().split())
        exc = record.exc_info[1] if record.exc_info else None
        if exc is not None:
            text += f": {type(exc).__name__}: {' '.join(str(exc).split())}"
        return f"{record.levelname.lower()}: {text}"


@contextlib.contextmanager
def one_line_logs() -> Iterator[None]:
    """While a command runs a study: the service's warnings and errors (a pool process
    replaced, a batch that failed and is tried again) as one line each on stderr. Left alone
    when logging is already configured (a script, the tests)."""
    root = logging.getLogger()
    if root.handlers:
        yield
        return
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(logging.WARNING)
    handler.setFormatter(_OneLine())
    root.addHandler(handler)
    try:
        yield
    finally:
        root.removeHandler(handler)


def as_option(message: str, options: Mapping[str, str]) -> str:
    """A study service's one-line error, which names a request field ("r: ...",
    "bounds.c: ..."), naming the command's option instead (``options``: field -> option)."""
    head, sep, rest = message.partition(":")
    field, dot, part = head.partition(".")
    if sep and field in options:
        return f"{options[field]}{' ' + part if dot else ''}:{rest}"
    return message


def read_case(path: Path) -> CaseDefinition:
    try:
        return load_case(path)
    except CaseError as exc:
        raise CLIError(str(exc)) from None


def data_paths(case: CaseDefinition, data: Sequence[Path]) -> list[Path]:
    """``--data`` paths if given, else the case's ``[data] files``; at least one."""
    paths = list(data) if data else case.data_paths()
    if not paths:
        raise CLIError(
            "no datasets: give --data LOG.csv (repeatable) or list files under [data] in the case"
        )
    return paths


def read_datasets(case: CaseDefinition, paths: Sequence[Path]) -> list[SWTDataset]:
    """Load every dataset with the case's averaging offset and cutoff; one-line errors."""
    out = []
    for path in paths:
        if not Path(path).is_file():
            raise CLIError(f"dataset {path}: no such file")
        try:
            out.append(load_dataset(path, offset=case.data.offset, cutoff_hz=case.data.cutoff_hz))
        except (LogFormatError, ValueError, OSError) as exc:
            msg = " ".join(str(exc).split())
            raise CLIError(msg if str(path.name) in msg else f"{path.name}: {msg}") from None
    names = [d.name for d in out]
    if len(set(names)) != len(names):
        # keep response column names unique
        out = [replace(d, name=f"{d.name}#{i}") for i, d in enumerate(out)]
    return out


def settings_or_fail():
    """The service settings; a one-line error for a bad value or config file."""
    from services.config import get_settings

    try:
        return get_settings()
    except Exception as exc:
        raise click.ClickException(f"settings: {' '.join(str(exc).split())}") from None


def open_store_or_fail(settings, wait: float = 0.0):
    """The settings' store once the database answers and takes writes, retrying for
    ``wait`` seconds (a database container starting next to us); otherwise a one-line error
    naming the database (exit 1). A database at the wrong schema revision fails at once."""
    import time

    from services.store import SchemaVersionError, Store
    from services.store.engine import safe_url

    deadline = time.monotonic() + max(0.0, wait)
    while True:
        try:
            store = Store.from_settings(settings)
        except SchemaVersionError as exc:
            raise click.ClickException(str(exc)) from None
        except Exception as exc:
            error = exc
        else:
            try:
                store.check_writable()
                return store
            except Exception as exc:
                store.close()
                error = exc
        if time.monotonic() >= deadline:
            orig = getattr(error, "orig", None) or error
            text = " ".join(str(orig).split()).split(" [SQL:")[0]
            raise click.ClickException(
                f"cannot use the database {safe_url(settings.database_url)}: "
                f"{type(orig).__name__}: {text}"
            ) from None
        time.sleep(1.0)


def compile_simulator_once(quiet: bool = False) -> None:
    """Compile the simulator in this process, saying so, when numba's disk cache does not hold
    it yet (the first run after an install or an upgrade: about 20 s, silent otherwise);
    worker processes started afterwards load it from the cache instead of each compiling it."""
    from scm_core.simulator import warm_up
    from scm_core.simulator.jit_cache import kernel_is_cached

    if kernel_is_cached() is not False:
        return
    if not quiet:
        click.echo("compiling the simulator, first run only (about 20 s) ...", err=True)
    seconds = warm_up()
    if not quiet:
        click.echo(f"simulator compiled in {seconds:.0f} s", err=True)
