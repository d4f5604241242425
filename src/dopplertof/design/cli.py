"""``dopplertof design SCENE… --sensor S --sweep KEY=LO:HI:N … --optimize KEY … -o DIR``.

Renders each scene's response record once (or reads ``--record``, once per scene), then
evaluates the sensor's precision (:mod:`dopplertof.design.search`) for every point of the
sweeps and/or optimises it, the objective averaged over the scenes (each scene's mean over
its moving pixels), and writes into DIR (the scenes: built-in names or files, or with
``--dataset CONFIG --samples N`` the first N scenes of a dataset configuration,
:mod:`dopplertof.dataset`, drawn as ``dopplertof dataset generate --seed`` would):

* ``record.npz``: the record (``--record`` reuses it);
* ``sweep.csv`` and ``sweep_<key>.png``: the objective at every grid point (refused
  variants with the reason), and a plot of it against each swept key;
* ``optimize.csv``: the optimiser's steps;
* ``best_sensor.toml``: the best configuration, a file ``dopplertof render --sensor`` reads;
* ``velocity_crb.exr``, ``depth_crb.exr`` (m/s, m): its per-pixel bounds, and with
  ``--rmse-draws N`` ``velocity_rmse.exr``: what the velocity estimator reaches over N noise
  draws (:func:`~dopplertof.design.achieved_rmse`), side by side.

With several scenes the per-scene files carry the scene's index: ``record_0.npz``,
``velocity_crb_1.exr``, …

While a record renders, its sums are saved beside it (``record.checkpoint.npz``: every
minute and when a signal stops the render); ``--resume`` continues an interrupted run:
the records it finished are read, the unfinished one continues from its checkpoint.
"""

from __future__ import annotations

import contextlib
import csv
import glob
import math
import os
import sys

import click
import numpy as np

from ..clitools import StopOnSignal, fail, given_settings, quiet_option, settings_options
from ..folder import DESIGN_OUTPUTS
from .search import OBJECTIVES, OPTIMIZE_KEYS

OUTPUTS = DESIGN_OUTPUTS
KEY_UNITS = {"modulation_frequency": "Hz", "exposure": "s", "heterodyne": "beat cycles per exposure"}


def _render_options(options: dict, resolution) -> list[str]:
    """The render options given on the command line (a record holds its render: refused
    beside --record)."""
    return sorted([f"--{k.replace('_', '-')}" for k in given_settings(options)] + (["--resolution"] if resolution else []))


@click.command("design")
@click.argument("scenes", nargs=-1)
@click.option("--sensor", "sensor_spec", required=True, metavar="PRESET|FILE.toml", help="The sensor to design from: a preset or a TOML sensor file.")
@click.option("--sweep", "sweep_specs", multiple=True, metavar="KEY=LO:HI:N", help="A grid of one parameter: modulation_frequency (f, Hz), heterodyne (h), exposure (T, s). Repeatable: every combination.")
@click.option("--optimize", "optimize_keys", multiple=True, type=click.Choice(OPTIMIZE_KEYS), help="Minimise the objective over this parameter from the sensor's own value. Repeatable.")
@click.option("--objective", type=click.Choice(OBJECTIVES), default="velocity_crb", show_default=True, help="Mean Cramér-Rao bound over the moving pixels: velocity (m/s) or depth (m).")
@click.option("--record", "record_paths", multiple=True, help="Use this record (record.npz of an earlier run) instead of rendering one. Once per SCENE, in their order.")
@click.option("--rmse-draws", type=click.IntRange(min=0), default=0, show_default=True, help="Also the velocity estimator's per-pixel RMSE (dopplertof.reconstruct.velocity, method auto) for the best sensor over this many noise draws (0: not computed; else at least 2).")
@click.option("--dataset", "dataset_config", default=None, metavar="CONFIG.toml", help="Design over the scenes of a dataset configuration (dopplertof dataset config) instead of SCENES; with --samples.")
@click.option("--samples", type=click.IntRange(min=1), default=None, help="With --dataset: its first N scenes.")
@click.option("--dataset-seed", type=click.IntRange(min=0), default=0, show_default=True, help="With --dataset: the dataset seed the scenes are drawn with.")
@click.option("-o", "--output", required=True, help="Output folder.")
@click.option("--overwrite", is_flag=True, help="Replace the files of an earlier design run in the output folder.")
@click.option("--resume", is_flag=True, help="Continue the interrupted design run in the output folder: the same command plus --resume (finished records are read, an unfinished one continues from its checkpoint).")
@click.option("--resolution", default=None, help="Film size in pixels: N (square) or WxH; replaces the scene's.")
@click.option("-D", "defines", multiple=True, metavar="NAME=VALUE", help="Value of $NAME in a scene file. Repeatable.")
@quiet_option
@settings_options(exclude=("exposure",))
def design_command(scenes, sensor_spec, sweep_specs, optimize_keys, objective, record_paths, rmse_draws, dataset_config, samples, dataset_seed, output, overwrite, resume, resolution, defines, quiet, **options):
    """Sweep and optimise SENSOR's parameters on SCENES (one or more, or a dataset's: the
    objective averaged over them) from one render of each (its response record)."""
    from ..backend import signals_as_interrupt
    from ..folder import check_writable, held, refuse_other_output
    from ..io import read_record, write_exr, write_record
    from ..render import render
    from ..scene import SceneError
    from ..sensors.files import load_sensor, sensor_toml
    from ..settings import RenderSettings, scene_layer
    from .precision import achieved_rmse, crb
    from .record import by_probes
    from .search import check_moving, optimize, parse_sweep, record_spec, sweep, variant

    written = []
    records_done = False
    stop = StopOnSignal()
    existed = os.path.isdir(output)  # a run that stops with nothing written leaves no folder it made
    hold = contextlib.ExitStack()  # the output folder, held while this run writes it
    try:
        with signals_as_interrupt():  # the sweep and the optimiser stop at once, a render after its pass (stop)
            if not sweep_specs and not optimize_keys:
                raise ValueError("give --sweep KEY=LO:HI:N and/or --optimize KEY")
            scenes = _scene_sources(scenes, dataset_config, samples, dataset_seed, resolution, defines)
            sensor = load_sensor(sensor_spec)
            sweeps = [parse_sweep(s) for s in sweep_specs]
            if len({k for k, _ in sweeps}) != len(sweeps):
                raise ValueError("--sweep: each key once")
            if rmse_draws == 1:
                raise ValueError("--rmse-draws: 0 (none) or at least 2 noise draws, got 1")
            if record_paths and len(record_paths) != len(scenes):
                raise ValueError(f"--record: give one per scene ({len(scenes)} scene(s), {len(record_paths)} record(s))")
            if resume and (overwrite or record_paths):
                raise ValueError(f"--resume continues the records rendered in {output!r}: {'--overwrite' if overwrite else '--record'} excludes it")

            def named(name, index):  # record.npz, or record_<index>.npz for several scenes
                stem, ext = os.path.splitext(name)
                return name if len(scenes) == 1 else f"{stem}_{index}{ext}"

            def checkpoint_of(index):  # record.checkpoint.npz, record_<index>.checkpoint.npz
                return os.path.join(output, _checkpoint_name(named("record.npz", index)))

            per_scene = ("record.npz", "velocity_crb.exr", "depth_crb.exr", "velocity_rmse.exr")
            names = [named(n, i) if n in per_scene else n for n in OUTPUTS for i in (range(len(scenes)) if n in per_scene else (0,))]
            earlier = [name for name in names if os.path.exists(os.path.join(output, name))]
            earlier += sorted(os.path.basename(p) for p in glob.glob(os.path.join(glob.escape(output), "sweep_*.png")))
            earlier += [os.path.basename(checkpoint_of(i)) for i in range(len(scenes)) if os.path.exists(checkpoint_of(i))]
            if earlier and not overwrite and not resume:
                raise ValueError(f"{output!r} holds an earlier design run ({', '.join(earlier)}); choose another folder, --overwrite, or --resume to continue it")
            refuse_other_output(output, "design")
            check_writable(output)  # before the render: an unwritable folder fails first
            hold.enter_context(held(output))
            if overwrite:  # an earlier run's checkpoints would be continued
                for index in range(len(scenes)):
                    if os.path.exists(checkpoint_of(index)):
                        os.remove(checkpoint_of(index))
            if record_paths:
                records = [read_record(path) for path in record_paths]
                rendering = _render_options(options, resolution)
                if rendering:
                    raise ValueError(f"--record: the record holds its render; {', '.join(rendering)} would render another (leave {'them' if len(rendering) > 1 else 'it'} out, or leave out --record)")
                for path, record, (name, load, identity) in zip(record_paths, records, scenes):
                    if identity is None:
                        load()  # its error: no such scene or file
                    _check_record_scene(path, record, name, identity)
            else:
                spec, cameras = record_spec(sensor, sweeps, optimize=optimize_keys)
                records = []
                for index, (scene, load, identity) in enumerate(scenes):
                    dyn = load()
                    settings = RenderSettings.build(scene_layer(dyn, scene), {**given_settings(options), "cameras": cameras}, where=scene)
                    path, checkpoint = os.path.join(output, named("record.npz", index)), checkpoint_of(index)
                    if resume and os.path.exists(path):
                        records.append(_resumed_record(path, read_record(path), scene, identity, spec, settings))
                        continue
                    checkpoint_kept = None if by_probes(settings) else checkpoint  # the paired correlations record through several renders
                    check_writable(output, _record_disk_bytes(spec, dyn.resolution, settings, checkpoint_kept is not None))
                    resuming = f", continuing {os.path.basename(checkpoint)}" if checkpoint_kept and os.path.exists(checkpoint) else ""
                    click.echo(f"rendering the record of {scene}: {spec.frequencies_hz.size} frequencies x {len(spec.beats)} beats, {len(settings.windows)} window(s), {settings.spp} spp{resuming}", err=True)
                    with stop:  # SIGINT, SIGTERM, SIGHUP end the render after its pass in progress
                        record = render(dyn, settings=settings, record=spec, stop=stop, checkpoint=checkpoint_kept, keep_checkpoint=True, progress=not quiet).record
                    if record is None:  # a render stopped early keeps no record (its checkpoint, if any, its sums)
                        raise KeyboardInterrupt
                    record.info["scene"] = identity  # what a later --record is checked against
                    records.append(record)
                    written.append(str(write_record(path, records[-1])))
                    if checkpoint_kept and os.path.exists(checkpoint):
                        os.remove(checkpoint)
            records_done = True
            if stop():  # the signal came during the last pass: the record is whole, stop here
                raise KeyboardInterrupt
            check_moving(records, [name for name, _, _ in scenes])
            unit = "m/s" if objective == "velocity_crb" else "m"
            best = sensor
            if sweeps:
                points = math.prod(len(values) for _, values in sweeps)
                click.echo(f"sweeping {points} point(s) of {' x '.join(k for k, _ in sweeps)} over {len(records)} record(s)", err=True)
                rows = sweep(records, sensor, sweeps, objective)
                written.append(_write_csv(os.path.join(output, "sweep.csv"), rows))
                written += _plots(output, rows, [k for k, _ in sweeps], objective, unit)
                good = [r for r in rows if r["status"] == "ok" and r["objective"] == r["objective"]]
                if not good:
                    raise ValueError("every point of the sweep was refused or has an infinite bound (see sweep.csv)")
                top = min(good, key=lambda r: r["objective"])
                best = variant(sensor, {k: top[k] for k, _ in sweeps})
                click.echo("best of the sweep: " + ", ".join(f"{k}={top[k]:g}" for k, _ in sweeps) + f": mean {objective} {top['objective']:.4g} {unit}")
            if optimize_keys:
                best, history = optimize(records, best, optimize_keys, objective)
                written.append(_write_csv(os.path.join(output, "optimize.csv"), [{**h, "phases": " ".join(f"{p:.6g}" for p in h["phases"])} for h in history]))
                click.echo(f"optimised ({', '.join(optimize_keys)}): mean {objective} {history[0]['objective']:.4g} -> {history[-1]['objective']:.4g} {unit} in {len(history) - 1} step(s); modulation_frequency={best.frames[0].modulation_frequency:g} Hz")
            path = os.path.join(output, "best_sensor.toml")
            with open(path, "w", encoding="utf-8") as f:
                f.write(sensor_toml(best))
            written.append(path)
            for index, record in enumerate(records):
                precision = crb(record, best)
                written += [str(write_exr(os.path.join(output, named(f"{name}.exr", index)), getattr(precision, name))) for name in ("velocity_crb", "depth_crb")]
                values = precision.summary()
                line = f"best sensor{'' if len(records) == 1 else f' on {scenes[index][0]}'}: velocity_crb {values['velocity_crb_median']:.4g} m/s, depth_crb {values['depth_crb_median']:.4g} m (medians over {values['moving_pixels']} moving pixels)"
                if rmse_draws:
                    rmse = achieved_rmse(record, best, draws=rmse_draws)
                    written.append(str(write_exr(os.path.join(output, named("velocity_rmse.exr", index)), rmse)))
                    both = precision.moving & np.isfinite(rmse) & np.isfinite(precision.velocity_crb)  # the same pixels for both medians
                    line += (f"; on the {int(both.sum())} of them where the estimator is determined: velocity_crb "
                             f"{float(np.median(precision.velocity_crb[both])) if both.any() else float('nan'):.4g} m/s, estimator RMSE "
                             f"{float(np.median(rmse[both])) if both.any() else float('nan'):.4g} m/s over {rmse_draws} draws")
                click.echo(line)
    except KeyboardInterrupt as exc:
        kept = f"; kept {', '.join(os.path.basename(w) for w in written)}" if written else "; nothing written"
        if records_done and not record_paths:
            recs = " ".join(f"--record {os.path.join(output, named('record.npz', i))}" for i in range(len(records)))
            rendering = _render_options(options, resolution)
            without = f" and without {', '.join(rendering)}" if rendering else ""  # the record holds its render (refused beside --record)
            click.echo(f"error: interrupted after the record was written{kept}: the same command with {recs} -o ANOTHER_FOLDER{without} sweeps it without rendering", err=True)
        else:
            if records_done:
                click.echo(f"error: interrupted after the records were read{kept}", err=True)
            else:
                checkpoints = _kept_checkpoints(output)
                if checkpoints:
                    passes = f"the rendered passes in {', '.join(map(os.path.basename, checkpoints))}"
                    kept = f"{kept} and {passes}" if written else f"; kept {passes}"
                    click.echo(f"error: interrupted before the record was finished{kept}: continue with the same command and --resume", err=True)
                else:
                    click.echo(f"error: interrupted before the record was finished{kept}", err=True)
        _release(hold, output, existed)
        sys.exit(128 + exc.signum if hasattr(exc, "signum") else stop.exit_status)
    except (ValueError, SceneError, FileNotFoundError) as exc:
        _release(hold, output, existed)
        fail(str(exc))
    except OSError as exc:
        kept = _kept_checkpoints(output)
        kept = f"; the rendered passes are kept in {', '.join(map(os.path.basename, kept))}: free space, then the same command with --resume" if kept else ""
        _release(hold, output, existed)
        fail(f"cannot write {output!r}: {exc.strerror or exc}{kept}")
    hold.close()
    for path in written:
        click.echo(f"  {path}")
    sys.stdout.flush()


def _release(hold, folder: str, existed: bool) -> None:
    """Let go of the output folder (``hold``), and remove it if this run made it and left
    it empty (a refused or stopped run)."""
    hold.close()
    if not existed and os.path.isdir(folder) and not os.listdir(folder):
        os.rmdir(folder)


def _record_disk_bytes(spec, resolution, settings, checkpointed: bool) -> int:
    """Disk space a record needs while it renders (bytes): the record file and, with a
    checkpoint, the render's checkpoint with the record's Float64 sums (about twice the
    record's complex64 size), twice while a save replaces the previous one."""
    from ..render import checkpoint_disk_bytes

    width, height = resolution
    record = spec.bytes_per_pixel(len(settings.windows)) * width * height
    return record + (checkpoint_disk_bytes(width, height, settings) + 4 * record if checkpointed else 0)


def _checkpoint_name(record_name: str) -> str:
    """The checkpoint of the record file ``record_name`` while it renders."""
    return record_name[: -len(".npz")] + ".checkpoint.npz"


def _kept_checkpoints(folder: str) -> list[str]:
    """The records' checkpoints in ``folder`` (an interrupted run's rendered passes)."""
    return sorted(glob.glob(os.path.join(glob.escape(folder), _checkpoint_name("record*.npz"))))


def _resumed_record(path, record, name, identity, spec, settings):
    """The finished ``record`` at ``path`` that ``--resume`` reads instead of rendering it;
    ValueError where it is of another scene, grid or render than the command asks for."""
    _check_record_scene(path, record, name, identity)
    asked = settings.replace(cameras=()).as_dict()
    if record.spec.as_dict() != spec.as_dict() or record.settings.as_dict() != asked:
        raise ValueError(f"--resume: {path} was rendered by another command (other sweeps or render settings); remove it, or give that command")
    return record


def _check_record_scene(path, record, name, identity) -> None:
    """ValueError where the record at ``path`` was rendered from another scene than
    ``name`` (its ``identity``: :func:`_scene_sources`); a record that does not say (written
    by an older version) is taken as it is."""
    recorded = record.info.get("scene")
    if recorded is not None and recorded != identity:
        raise ValueError(f"--record {path}: rendered from {_describe_identity(recorded)}, not {name} ({_describe_identity(identity)}); render the record of {name} (leave out --record)")


def _describe_identity(identity: dict) -> str:
    if "builtin" in identity:
        return f"the built-in scene {identity['builtin']!r}"
    if "dataset" in identity:
        return f"sample {identity['key']!r} of the dataset {identity['dataset']!r} (seed {identity['seed']})"
    defines = f" with -D {' -D '.join(identity['defines'])}" if identity["defines"] else ""
    return f"{identity['path']} (sha256 {identity['sha256'][:12]}…){defines}"


def _scene_sources(scenes, dataset_config, samples, dataset_seed, resolution, defines) -> list:
    """[(name, load, identity)] of the design's scenes: SCENES (built-in names or files) or
    the first ``samples`` scenes of a dataset configuration, ``load()`` building each,
    ``identity`` what a record of it keeps (built-in name; file, hash and ``-D`` values;
    dataset, seed and sample); ValueError for a contradictory choice."""
    from ..cli import scene_description
    from ..scenes import SCENES, open_scene, parse_resolution

    if dataset_config is None:
        if samples is not None:
            raise ValueError("--samples applies to --dataset")
        if not scenes:
            raise ValueError("give SCENE (one or more) or --dataset CONFIG.toml --samples N")
        out = []
        for scene in scenes:
            identity = None  # no such scene: loading it says so
            if scene in SCENES or os.path.isfile(scene):
                identity = {k: v for k, v in scene_description(scene, resolution, defines).items() if k != "resolution"}  # the film is the record's own
            out.append((scene, lambda scene=scene: open_scene(scene, resolution, defines), identity))
        return out
    from ..backend import ensure_variant
    from ..dataset.config import load_config
    from ..dataset.randomize import build_scene
    from ..dataset.sample import make_record

    if scenes or defines:
        raise ValueError("give SCENE… or --dataset, not both (-D applies to scene files)")
    if samples is None:
        raise ValueError("--dataset needs --samples N (how many of its scenes)")
    config = load_config(dataset_config)
    size = parse_resolution(resolution)
    if isinstance(size, tuple) and size[0] != size[1]:
        raise ValueError(f"--resolution {resolution!r}: dataset scenes are square; give one number")
    size = config["render"]["resolution"] if size is None else (size if isinstance(size, int) else size[0])
    variant, out = ensure_variant(), []
    for index in range(samples):
        record = make_record(config, dataset_seed, index, variant)  # the scene of sample i, as the dataset draws it
        identity = {"dataset": os.path.abspath(dataset_config), "seed": dataset_seed, "key": record["key"]}
        out.append((record["key"], lambda scene=record["scene"]: build_scene(scene, size), identity))
    return out


def _write_csv(path, rows) -> str:
    names = list(dict.fromkeys(k for r in rows for k in r if k != "status"))
    names += ["status"] if any("status" in r for r in rows) else []  # last, whichever row comes first
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=names)
        writer.writeheader()
        writer.writerows(rows)
    return path


def _plots(output, rows, keys, objective, unit) -> list[str]:
    """The objective (the mean bound over the moving pixels) and the median bound against
    each swept key, the other keys at their best point's values: a few pixels with little
    modulated light dominate the mean, the median shows the typical pixel."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    good = [r for r in rows if r["status"] == "ok" and r["objective"] == r["objective"]]
    if not good:
        return []
    top = min(good, key=lambda r: r["objective"])
    written = []
    for key in keys:
        line = sorted((r[key], r["objective"], r[f"{objective}_median"]) for r in good if all(r[k] == top[k] for k in keys if k != key))
        figure = Figure(figsize=(5, 3.5))
        FigureCanvasAgg(figure)
        axes = figure.add_subplot()
        axes.plot([x for x, _, _ in line], [y for _, y, _ in line], "o-", label="mean")
        axes.plot([x for x, _, _ in line], [y for _, _, y in line], "s--", label="median")
        axes.set_xlabel(f"{key} ({KEY_UNITS[key]})")
        axes.set_ylabel(f"{objective} ({unit})")
        held = [f"{k} = {top[k]:g} {KEY_UNITS[k].split(' ')[0]}" for k in keys if k != key]
        if held:  # where the other keys are held: the best point's values
            axes.set_title(f"at {', '.join(held)} (the best point)", fontsize=9)
        axes.legend()
        axes.set_yscale("log")
        axes.grid(True, alpha=0.3)
        figure.tight_layout()
        path = os.path.join(output, f"sweep_{key}.png")
        figure.savefig(path, dpi=100)
        written.append(path)
    return written
