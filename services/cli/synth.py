"""``scm-calib synth``: a synthetic lab log (CSV + JSON sidecar) from known SCM parameters."""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console
from rich.table import Table

from scm_core.calibration import NoiseModel, SyntheticError, synthesize_log
from scm_core.signals import RESPONSES, LogFormatError, load_log, write_log

from .common import CLIError
from .overrides import OverrideError, build_configs, set_option


@click.command()
@set_option("True soil / wheel value or rig condition (as `simulate`), e.g. --set phi=27.")
@click.option(
    "--out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Log to write (CSV); the JSON sidecar goes beside it.",
)
@click.option("--seed", default=0, show_default=True, type=click.IntRange(min=0))
@click.option("--duration", default=180.0, show_default=True, type=float, help="Log length [s].")
@click.option("--rate", default=50.0, show_default=True, type=float, help="Lab rate [Hz].")
@click.option("--ramp", default=5.0, show_default=True, type=float, help="Drive spin-up ramp [s].")
@click.option(
    "--noise-scale",
    default=1.0,
    show_default=True,
    type=float,
    help="Multiplies the default sensor noise (0: none).",
)
@click.option(
    "--precision",
    default=7,
    show_default=True,
    type=click.IntRange(3, 17),
    help="Significant digits in the CSV.",
)
@click.option("--name", default=None, help="Dataset name in the metadata.")
def synth(
    overrides: tuple[str, ...],
    out: Path,
    seed: int,
    duration: float,
    rate: float,
    ramp: float,
    noise_scale: float,
    precision: int,
    name: str | None,
) -> None:
    """Write a synthetic SWT log: simulate DURATION s with the given true parameters, add a
    start-up ramp and sensor noise (white + drift, seeded), resample to RATE Hz."""
    try:
        soil, wheel, rig = build_configs(overrides)
        noise = NoiseModel(scale=noise_scale)
    except (OverrideError, ValueError) as exc:
        raise CLIError(str(exc)) from None
    try:
        log = synthesize_log(
            soil,
            wheel,
            rig,
            duration=duration,
            rate_hz=rate,
            ramp_s=ramp,
            noise=noise,
            seed=seed,
            name=name or out.stem,
        )
    except SyntheticError as exc:
        click.echo(f"error: {exc}", err=True)
        raise SystemExit(1) from None
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    if not out.parent.is_dir():
        raise CLIError(f"--out: directory {out.parent} does not exist")
    write_log(
        out,
        log.t,
        log.F,
        log.T,
        log.z,
        log.metadata,
        Fy=log.Fy,
        normal_force=log.normal_force,
        slip=log.slip,
        precision=precision,
    )
    offset = 40.0 if duration >= 80.0 else duration / 2.0
    try:
        ds = load_log(out, offset=offset)
    except (LogFormatError, ValueError) as exc:  # pragma: no cover - our own output
        raise CLIError(f"written log does not read back: {exc}") from None
    table = Table(title=f"synthetic log {out} ({log.t.size} samples at {rate:g} Hz)")
    table.add_column("response")
    table.add_column(f"steady mean (t >= {offset:g} s)", justify="right")
    table.add_column("standard error", justify="right")
    for resp in RESPONSES:
        if resp.key not in ds.responses:
            continue
        r, unit, scale = ds.responses[resp.key], resp.shown_in, resp.scale
        table.add_row(resp.key, f"{r.mean * scale:.4g} {unit}", f"{r.se * scale:.2g} {unit}")
    Console().print(table)
    click.echo(
        "true: "
        + ", ".join(f"{k}={getattr(soil, k):g}" for k in ("k_c", "k_phi", "n", "phi", "J", "c"))
        + f"; slip={log.metadata['slip']:g}, W={rig.W:g} N; sidecar {out.with_suffix('.json')}"
    )
