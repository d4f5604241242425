"""Command line: ``dopplertof render | scenes | reconstruct | animate | experiment | dataset``.

Errors in the input (a bad scene file, parameter, camera or output folder) print one line,
``error: ...``, and exit with status 2; no traceback (:mod:`dopplertof.clitools`). The
render options are generated from :class:`dopplertof.settings.RenderSettings`, so their
names, types, defaults and help are the settings' own.
"""

from __future__ import annotations

import contextlib
import os
import sys

import click

from . import __version__
from ._startup import release
from .clitools import StopOnSignal, cameras_layer, fail, given_settings, output_folder, quiet_option, settings_options, show_warning
from .settings import DEFAULT_CHECKPOINT_INTERVAL_S

release()  # loaded: Ctrl-C is the command's own again (KeyboardInterrupt)


def scene_description(scene_arg: str, resolution, defines) -> dict:
    """What metadata.json records of the scene: built-in name and arguments, or file and hash."""
    import hashlib

    from .scenes import SCENES

    if scene_arg in SCENES:
        return {"builtin": scene_arg, "resolution": resolution}
    with open(scene_arg, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    return {"path": os.path.abspath(scene_arg), "sha256": digest, "defines": list(defines), "resolution": resolution}


# Commands imported only when used, so that ``dopplertof --help`` answers at once:
# name -> (module, attribute, short help).
_LAZY_COMMANDS = {
    "animate": ("dopplertof.animate", "animate_command", "Render SCENE as a clip: one D-ToF exposure per frame, with velocity."),
    "dataset": ("dopplertof.dataset.cli", "dataset_group", "Datasets for learning: randomized scenes rendered into WebDataset shards."),
    "design": ("dopplertof.design.cli", "design_command", "Sweep and optimise a sensor's parameters on a scene from one render."),
    "experiment": ("dopplertof.experiments.cli", "experiment", "Reproduce the paper's experiments (time sampling, shifts, velocity)."),
    "reconstruct": ("dopplertof.render_folder", "reconstruct_command", "Reconstruct radial velocity (and depth) from a render folder."),
}


class _Group(click.Group):
    """A group whose usage errors are one ``error:`` line (exit 2), like every other error,
    and whose larger commands load on first use."""

    def list_commands(self, ctx):
        return sorted([*super().list_commands(ctx), *_LAZY_COMMANDS])

    def get_command(self, ctx, name):
        if name in _LAZY_COMMANDS and name not in self.commands:
            import importlib

            module, attribute, _ = _LAZY_COMMANDS[name]
            self.add_command(getattr(importlib.import_module(module), attribute), name)
        return super().get_command(ctx, name)

    def format_commands(self, ctx, formatter):
        rows = [(name, _LAZY_COMMANDS[name][2] if name in _LAZY_COMMANDS else self.commands[name].get_short_help_str(60)) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def main(self, *args, **kwargs):
        import warnings

        warnings.showwarning = show_warning
        try:
            return super().main(*args, standalone_mode=False, **kwargs)
        except click.exceptions.Abort:
            click.echo("error: aborted", err=True)
            sys.exit(130)
        except click.ClickException as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":  # a bare group: its help, as click does
                click.echo(exc.ctx.get_help() if exc.ctx else exc.format_message())
                sys.exit(0)
            if isinstance(exc, click.UsageError) and exc.ctx is not None:
                fail(f"{exc.format_message()} (see '{exc.ctx.command_path} --help')")
            fail(exc.format_message())


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="dopplertof", message="%(prog)s %(version)s")
@click.option("--variant", default=None, help="Mitsuba variant: llvm_ad_rgb, llvm_ad_mono, cuda_ad_rgb, cuda_ad_mono (default: cuda if a GPU works, else llvm; env DOPPLERTOF_VARIANT).")
def main(variant):
    """dopplertof: render Doppler time-of-flight measurements of dynamic scenes."""
    if variant:
        from .backend import BackendError, set_variant

        try:
            set_variant(variant)
        except (ValueError, BackendError) as exc:
            fail(str(exc))


@main.command()
def scenes():
    """List the built-in scenes."""
    from .scenes import SCENES

    for name, (_, description) in SCENES.items():
        click.echo(f"{name:20s} {description}")


@main.command()
@click.argument("scene")
@click.option("-o", "--output", "output", default=None, help="Output folder (default: out/<scene name>).")
@click.option("--camera", "camera_specs", multiple=True, help="A camera, e.g. 'h=1,psi=0' or 'h=0,psi=90deg,f=30e6'. Repeatable. Keys (defaults those of dopplertof.Camera): h (default 1: heterodyne), psi (rad or 90deg; 0), f (Hz; 30e6), T (s; default --exposure, else the scene's shutter interval, else 1.5e-3), start (s: when its exposure opens; the shutter's, else 0), waveform (sinusoidal), g1 (0.5), g0 (0.5), low_pass (true).")
@click.option("--sensor", "sensor_spec", default=None, metavar="PRESET|FILE.toml", help="Render a sensor's raw frames instead of --camera: a preset (mlx75027, opt8241, imx556, kinect-v2, dtof-prototype) or a TOML file (dopplertof.sensors.files). Writes raw_electrons.npy, raw_dn.npy and the schedule in metadata.json.")
@click.option("--until-noise", "until_noise", type=float, default=None, metavar="RATIO", help="With --sensor: stop once the Monte Carlo error of the raw frames is at most RATIO x the sensor's own noise in 95% of the pixels (--spp is then the most it may take).")
@click.option("--resolution", default=None, help="Film size in pixels: N (square) or WxH; replaces the scene's.")
@click.option("-D", "defines", multiple=True, metavar="NAME=VALUE", help="Value of $NAME in a scene file (overrides its <default>). Repeatable.")
@click.option("--overwrite", is_flag=True, help="Replace the files of another render in the output folder (only those).")
@click.option("--resume", is_flag=True, help="Continue the interrupted render in the output folder: the same command (same settings and spp) plus --resume.")
@quiet_option
@click.option("--ray", "use_ray", is_flag=True, help="Trace the passes on Ray workers; the result is bit-identical to the local render's.")
@click.option("--address", default=None, help="Ray cluster address (with --ray; default: the running Ray, else a local one).")
@click.option("--workers", type=click.IntRange(min=1), default=None, help="Ray workers, each with CPUs / workers threads (with --ray; default: one per CPU, with a cuda variant one per GPU).")
@click.option("--checkpoint-interval", "checkpoint_interval_s", type=float, default=DEFAULT_CHECKPOINT_INTERVAL_S, show_default=True,
              help="Seconds between checkpoints [s]: the sums are saved after the first pass that ends this long after the last save (0: every pass); a killed render loses at most this much.")
@settings_options()
def render(scene, output, camera_specs, sensor_spec, until_noise, resolution, defines, overwrite, resume, quiet, use_ray, address, workers, checkpoint_interval_s, **options):
    """Render SCENE (an XML file or a built-in scene name) into OUTPUT.

    SIGINT, SIGTERM and SIGHUP stop after the pass in progress: the partial result and a
    checkpoint are written, the exit status is 128 + the signal, and --resume continues
    (with or without --ray). A checkpoint is also saved every --checkpoint-interval
    seconds, so a killed render (SIGKILL) or a full disk loses at most that interval:
    --resume continues from it.
    """
    # First: a signal during start-up then stops the render before its first pass.
    with StopOnSignal() as stop:
        _render(stop, scene, output, camera_specs, sensor_spec, until_noise, resolution, defines, overwrite, resume, quiet, use_ray, address, workers, checkpoint_interval_s, options)


def _render(stop, scene, output, camera_specs, sensor_spec, until_noise, resolution, defines, overwrite, resume, quiet, use_ray, address, workers, checkpoint_interval_s, options):
    from . import folder as out_folder
    from .backend import BackendError
    from .raytools import require_ray
    from .render import CheckpointWriteError, check_film_memory, checked_until_noise, checkpoint_disk_bytes, passes_in_checkpoint, warn_outside_the_shutter
    from .render import render as run_render
    from .scene import SceneError
    from .scenes import open_scene
    from .settings import RenderSettings, checked_checkpoint_interval, scene_layer

    output = output_folder(output, os.path.join("out", os.path.splitext(os.path.basename(scene))[0]))
    checkpoint = os.path.join(output, out_folder.CHECKPOINT)
    result = None
    hold = contextlib.ExitStack()  # the output folder, held while this render writes it
    try:
        checked_checkpoint_interval(checkpoint_interval_s)
        if overwrite and resume:
            raise ValueError("--overwrite and --resume exclude each other")
        for name, value in (("--address", address), ("--workers", workers)):
            if value is not None and not use_ray:
                raise ValueError(f"{name} needs --ray")
        if use_ray:
            require_ray()
        if until_noise is not None:
            if sensor_spec is None:
                raise ValueError("--until-noise compares the render's error with a sensor's noise: give --sensor")
            checked_until_noise(until_noise)  # before the folder is made
        sensor = None
        if sensor_spec is not None:
            from .sensors.files import load_sensor

            if camera_specs:
                raise ValueError("--camera and --sensor exclude each other (a sensor's raw frames are its cameras)")
            sensor = load_sensor(sensor_spec)
        dyn = open_scene(scene, resolution, defines)
        base = scene_layer(dyn, scene)
        cameras = {"cameras": sensor.cameras()} if sensor is not None else cameras_layer(camera_specs, options.get("exposure"), base, dyn)
        layer = {**given_settings(options), **cameras}
        settings = RenderSettings.build(base, layer, where=scene)
        if sensor is None:
            warn_outside_the_shutter(dyn, settings)
        width, height = dyn.resolution
        check_film_memory(width, height, len(settings.cameras), len(settings.windows))
        bytes_needed = out_folder.estimated_bytes(width, height, len(settings.cameras)) + checkpoint_disk_bytes(width, height, settings)
        out_folder.prepare(output, overwrite=overwrite, resume=resume, bytes_needed=bytes_needed, hold=hold)
        if resume and not os.path.isfile(checkpoint):
            click.echo(f"note: no checkpoint in {os.path.abspath(output)}/ to continue: rendering from the start", err=True)
        executor = {"executor": "ray", "address": address, "workers": workers} if use_ray else {}
        # The checkpoint outlives the render until its images are written: a full disk then loses nothing.
        result = run_render(dyn, settings=settings, progress=not quiet, checkpoint=checkpoint, checkpoint_interval_s=checkpoint_interval_s,
                            keep_checkpoint=True, stop=stop, sensor=sensor, until_noise=until_noise, **executor)  # fmt: skip
        if result.info["passes_done"] == 0:
            click.echo("error: interrupted before the first pass finished; nothing written", err=True)
            sys.exit(stop.exit_status)
        metadata = {"scene": scene_description(scene, resolution, defines), "film": [width, height], "command": sys.argv}
        written = out_folder.write_result(result, output, metadata)
        if not result.interrupted and os.path.isfile(checkpoint):
            os.remove(checkpoint)
    except KeyboardInterrupt:  # before the first pass, or a second signal (stop at once)
        kept = passes_in_checkpoint(checkpoint) if os.path.isfile(checkpoint) else None
        if kept:
            click.echo(f"error: stopped at once; the checkpoint {checkpoint!r} keeps {kept} finished pass{'es' if kept > 1 else ''} (continue with --resume)", err=True)
        else:
            click.echo("error: stopped before a pass was saved; nothing written", err=True)
        sys.exit(stop.exit_status)
    except CheckpointWriteError as exc:
        again = "continue with the same command and --resume" if os.path.isfile(checkpoint) else "run the command again"
        fail(f"{exc}; free space, then {again}")
    except (ValueError, SceneError, BackendError, FileNotFoundError) as exc:
        fail(str(exc))
    except OSError as exc:
        kept = f"; the rendered sums are kept in {checkpoint!r}: free space, then write the images with the same command and --resume" if result is not None and os.path.isfile(checkpoint) else ""
        fail(f"cannot write {output!r}: {exc.strerror or exc}{kept}")
    finally:
        hold.close()
    if result.interrupted:
        done = result.info["window_spp"]
        reached = f"{result.spp}" if len(done) == 1 else f"{', '.join(map(str, done))} (per exposure window)"
        partial_errors = ("; its standard errors leave out the spread of the time strata not drawn (they understate the error, "
                          "most at h != 0)") if result.info["stderr_dof"] == 0 and settings.stratified else ""
        kept = ("partial result and checkpoint in", "continue with --resume")
        if "checkpoint_error" in result.info:  # its sums could not be saved: what --resume finds is older, or nothing
            kept = ("partial result in", "its checkpoint could not be written: --resume continues from an earlier one, if kept, else from the start")
        passes = f"after {result.info['passes_done']} of {result.info['passes']} passes, "  # a pass may cover part of the film: its spp is the least pixel's
        click.echo(
            f"{stop.name}: stopped {passes}at {reached} of {settings.spp} spp; {kept[0]} {os.path.abspath(output)}/ ({kept[1]}){partial_errors}", err=True,
        )  # fmt: skip
        sys.exit(stop.exit_status)
    if until_noise is not None:
        stopped = result.info["until_noise"]
        reached = max(stopped["reached"])
        verdict = "reached" if reached <= until_noise else f"not reached within --spp {settings.spp}"
        spp = f"{result.spp} spp" if len(stopped["spp"]) == 1 else f"{', '.join(map(str, stopped['spp']))} spp (per exposure window)"
        click.echo(f"until-noise {until_noise:g} {verdict}: Monte Carlo error {reached:.3g} x the sensor's noise (95% of pixels) at {spp}")
    cameras = "" if result.cameras else " (no D-ToF camera: intensity and ground truth only; give --camera)"
    click.echo(f"rendered {scene} at {result.spp} spp{cameras}; images in {os.path.abspath(output)}/")
    for path in written:
        click.echo(f"  {path}")


if __name__ == "__main__":  # pragma: no cover
    main()
