"""``dopplertof dataset generate | config | verify | info``.

Bad input (configuration, arguments, an unwritable or foreign folder) prints one line
``error: …`` and exits with status 2; ``verify`` exits 1 when a shard is bad; an interrupted
``generate`` (Ctrl-C, SIGTERM, SIGHUP) keeps its finished shards and exits with 128 + the
signal (130, 143, 129).
"""

from __future__ import annotations

import os
import signal
import sys

import click

from ..clitools import fail as _fail
from ..clitools import quiet_option
from .execute import AUTO
from .generate import DEFAULT_SHARD_SIZE


def _workers(ctx, param, value: str):
    """``--workers`` (a click callback): ``auto`` as it is, else an integer
    (:func:`~dopplertof.dataset.generate` checks its range)."""
    if value == AUTO:
        return value
    try:
        return int(value)
    except ValueError:
        raise click.BadParameter(f"{value!r} is neither an integer nor {AUTO!r}") from None


@click.group("dataset")
def dataset_group():
    """Datasets for learning: randomized scenes rendered into WebDataset shards."""


@dataset_group.command("generate")
@click.option("-o", "--output", required=True, help="Dataset folder (created; a rerun resumes it).")
@click.option("--samples", type=int, required=True, help="Number of samples.")
@click.option("--seed", type=int, default=0, show_default=True, help="Dataset seed: sample i depends only on (seed, i).")
@click.option("--config", "config_path", default=None, help="TOML file overriding the defaults ('dopplertof dataset config --print').")
@click.option("--resolution", type=int, default=None, help="Override render.resolution (pixels).")
@click.option("--spp", type=int, default=None, help="Override render.spp (paths per pixel).")
@click.option("--shard-size", type=int, default=DEFAULT_SHARD_SIZE, show_default=True, help="Samples per shard.")
@click.option("--workers", default=AUTO, show_default=True, metavar="N|auto", callback=_workers,
              help="Local worker processes (spawned), or 'auto': one per CPU, at most one per shard and as many as the available memory holds at 1 GiB + 2 KiB a pixel each (1 with a cuda variant).")
@click.option("--ray", "use_ray", is_flag=True, help="Render on Ray: one task per shard (one actor per GPU with a cuda variant).")
@click.option("--address", default=None, help="Ray cluster address (with --ray; default: a local Ray).")
@click.option("--shards", "shard_range", default=None, help="Only shards a:b (b excluded), e.g. one Slurm array task.")
@quiet_option
def generate_command(output, samples, seed, config_path, resolution, spp, shard_size, workers, use_ray, address, shard_range, quiet):
    """Generate (or resume) a dataset in OUTPUT."""
    from ..backend import BackendError
    from .generate import generate

    if address and not use_ray:
        _fail("--address needs --ray")
    try:
        result = generate(output, samples, seed, config_path, resolution=resolution, spp=spp, shard_size=shard_size, workers=workers,
                          ray=use_ray, address=address, shards_range=shard_range, progress=not quiet)
    except (ValueError, BackendError) as exc:
        _fail(str(exc))
    except OSError as exc:  # a full disk or a folder that became unwritable while shards are written
        _fail(f"cannot write {output!r}: {exc.strerror or exc}; the finished shards are kept: fix it, then run the same command again to resume")
    except KeyboardInterrupt as exc:
        from .shards import read_manifest

        m = read_manifest(output) or {"shards_done": 0, "shards": []}
        click.echo(f"interrupted: {m['shards_done']} of {len(m['shards'])} shards done in {output}; run the same command again to resume",
                   err=True)
        sys.exit(128 + getattr(exc, "signum", signal.SIGINT))  # as every command: 130, 143, 129
    m = result["manifest"]
    click.echo(f"{len(result['generated'])} shards generated, {len(result['skipped'])} already complete; "
               f"{m['shards_done']}/{len(m['shards'])} shards ({m['samples_done']} samples) in {os.path.abspath(output)}"
               f"{'' if m['complete'] else ' (incomplete)'}; {result['wall_s']:.1f} s"
               + (f" on {result['executor']}" if result["executor"] else ""))
    if m["missing_fields"]:
        click.echo(f"note: fields not written (the renderer lacks them): {', '.join(m['missing_fields'])}")


@dataset_group.command("config")
@click.option("--print", "print_", is_flag=True, help="Print the default configuration (TOML, commented).")
@click.option("--markdown", is_flag=True, help="Print the configuration keys as a Markdown table.")
@click.option("--check", "check_path", default=None, help="Validate a TOML file and print the full configuration it gives.")
def config_command(print_, markdown, check_path):
    """The dataset configuration: defaults, documentation, validation."""
    from . import config

    if check_path:
        try:
            cfg = config.load_config(check_path)
        except ValueError as exc:
            _fail(str(exc))
        import json

        click.echo(json.dumps(cfg, indent=1))
    elif markdown:
        click.echo(config.markdown_table())
    elif print_:
        click.echo(config.default_toml(), nl=False)
    else:
        _fail("say what to do: --print, --markdown or --check FILE")


@dataset_group.command("verify")
@click.argument("folder")
def verify_command(folder):
    """Check every shard of FOLDER against its manifest (exit 1 naming the bad shards)."""
    from .shards import verify

    try:
        report = verify(folder)
    except ValueError as exc:
        _fail(str(exc))
    unwritten = f"; {len(report['unwritten'])} not written yet (the dataset is incomplete)" if report["unwritten"] else ""
    if report["bad"] or report["unwritten"]:  # exit 1: not a complete, sound dataset (a gate for scripts)
        for name, status in sorted(report["bad"].items()):
            click.echo(f"{name}: {status}")
        click.echo(f"{len(report['bad'])} bad shard(s), {len(report['ok'])} ok{unwritten}; rerun 'dopplertof dataset generate' with the same "
                   f"arguments to {'regenerate them' if report['bad'] else 'finish it'}", err=True)
        sys.exit(1)
    click.echo(f"ok: {len(report['ok'])} shards match the manifest")


@dataset_group.command("info")
@click.argument("folder")
@click.option("--sheet", default=None, help="Contact sheet PNG (default FOLDER/contact_sheet.png; 'none' for none).")
@click.option("--sheet-samples", type=int, default=4, show_default=True, help="Samples on the contact sheet.")
@click.option("--max-samples", type=int, default=None, help="Summarise only the first N samples.")
def info_command(folder, sheet, sheet_samples, max_samples):
    """Counts, ranges and histograms of the ground truth, and a contact sheet."""
    from .summary import summarize

    if sheet is None:
        sheet = os.path.join(folder, "contact_sheet.png")
    elif sheet.lower() == "none":
        sheet = None
    try:
        report = summarize(folder, sheet=sheet, sheet_samples=sheet_samples, max_samples=max_samples)
    except ValueError as exc:
        _fail(str(exc))
    for line in report["lines"]:
        click.echo(line)
    if report["sheet_error"]:
        _fail(report["sheet_error"])
