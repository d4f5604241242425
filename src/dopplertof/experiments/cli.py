"""``dopplertof experiment time-sampling | shifts | velocity SCENE``.

Options left out take the normal defaults, or with ``--quick`` the tiny ones (a smoke test
that finishes in seconds). Bad input prints one line ``error: ...`` and exits with status 2.
"""

from __future__ import annotations

import contextlib
import functools
import os

import click

from ..clitools import fail
from ..correlation import MODES
from ..timesampling import METHODS

NORMAL = {"resolution": 64, "spp": 256, "reference_spp": 16384, "h_steps": 11, "phases": 4, "shift_steps": 11}
QUICK = {"resolution": 16, "spp": 16, "reference_spp": 256, "h_steps": 3, "phases": 2, "shift_steps": 3}
QUICK_CORRELATIONS = ("none", "replay")  # the extremes; every mode still runs without --quick


class _ExperimentGroup(click.Group):
    """Unknown experiment names fail in one ``error:`` line, like every other bad input."""

    def resolve_command(self, ctx, args):
        if args and not args[0].startswith("-") and self.get_command(ctx, args[0]) is None:
            fail(f"unknown experiment {args[0]!r}; choose one of {', '.join(self.list_commands(ctx))}")
        return super().resolve_command(ctx, args)


@contextlib.contextmanager
def _one_line_errors():
    from ..backend import BackendError
    from ..scene import SceneError

    try:
        yield
    except (ValueError, SceneError, BackendError, OSError) as exc:
        fail(str(exc))


def _common_options(command):
    options = [
        click.argument("scene"),
        click.option("-o", "--output", default=None, help="Output folder (default out/experiments/<experiment>/<scene>)."),
        click.option("--spp", type=int, default=None, help=f"Paths per pixel of the compared renders (default {NORMAL['spp']}, quick {QUICK['spp']})."),
        click.option("--reference-spp", type=int, default=None, help=f"Paths per pixel of the reference (default {NORMAL['reference_spp']}, quick {QUICK['reference_spp']})."),
        click.option("--resolution", type=int, default=None, help=f"Film size of a built-in scene (default {NORMAL['resolution']}, quick {QUICK['resolution']})."),
        click.option("--seed", type=int, default=0, show_default=True, help="Seed of the compared renders; the reference uses seed + 1."),
        click.option("--max-depth", type=int, default=None, help="Path depth (default: the scene's, else 4)."),
        click.option("--quick", is_flag=True, help="Tiny settings for a smoke test (seconds)."),
        click.option("--cache", default=None, help="Reference cache folder (default $DOPPLERTOF_CACHE, else ~/.cache/dopplertof/references)."),
        click.option("--ray", "use_ray", is_flag=True, help="Render the references on Ray workers (as 'dopplertof render --ray'; the same pixels)."),
        click.option("--address", default=None, help="Ray cluster address (with --ray; default: the running Ray, else a local one)."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def _setting(name, value, quick):
    if value is not None:
        return value
    return (QUICK if quick else NORMAL)[name]


def _prepare(name, scene_arg, output, resolution, quick, cache, max_depth, echo, use_ray=False, address=None):
    """(scene, output folder, cache, max depth) shared by the experiments."""
    from .. import scenes
    from ..folder import check_writable
    from ..raytools import require_ray
    from .common import ReferenceCache, default_cache_dir, open_scene

    if address and not use_ray:
        raise ValueError("--address needs --ray")
    if use_ray:
        require_ray()
    if scene_arg in scenes.SCENES:
        resolution = _setting("resolution", resolution, quick)
    scene = open_scene(scene_arg, resolution)
    folder = output or os.path.join("out", "experiments", name, scene.label)
    cache_folder = cache or default_cache_dir()
    check_writable(folder)  # before any rendering, not when its results are due
    try:
        check_writable(cache_folder)
    except ValueError as exc:
        raise ValueError(f"reference cache: {exc}") from None
    cache = ReferenceCache(cache_folder, {"executor": "ray", "address": address} if use_ray else None)
    width, height = scene.scene.resolution
    echo(f"{name} on {scene.label} ({width}x{height}); output in {os.path.abspath(folder)}/")
    return scene, folder, cache, (max_depth if max_depth is not None else scene.max_depth)


def _estimators(time_samplings, correlations, quick):
    from .common import Estimator

    time_samplings = time_samplings or METHODS
    correlations = correlations or (QUICK_CORRELATIONS if quick else MODES)
    return [Estimator(t, c) for t in dict.fromkeys(time_samplings) for c in dict.fromkeys(correlations)]


def _report(written):
    for path in written:
        click.echo(f"  {path}")


def _experiment_command(name):
    """Register ``name`` on the group with the common options; bad input becomes one error line.

    Use it as the outermost decorator, above the command's own options.
    """

    def wrap(function):
        @functools.wraps(function)
        def run(**kwargs):
            with _one_line_errors():
                function(**kwargs)

        return experiment.command(name)(_common_options(run))

    return wrap


@click.group(cls=_ExperimentGroup)
def experiment():
    """Reproduce the paper's experiments; each writes CSV tables and PNG plots to a folder.

    SCENE is a built-in scene name (see 'dopplertof scenes') or a Mitsuba XML file.
    References are cached, so a rerun does not render them again.
    """


_TIME_SAMPLING_HELP = f"Time sampling to compare; repeatable (default all: {', '.join(METHODS)})."
_CORRELATION_HELP = f"Correlation mode to compare; repeatable (default all: {', '.join(MODES)}; quick: {', '.join(QUICK_CORRELATIONS)})."


def _sweep_settings(h_steps, phases, spp, reference_spp, seed, max_depth, quick):
    """The h grid, ψ offsets and sample counts of a sweep (options, else the defaults)."""
    from .sweeps import SweepSettings, evenly_spaced, phase_offsets

    return SweepSettings(
        evenly_spaced(_setting("h_steps", h_steps, quick), "--h-steps"),
        phase_offsets(_setting("phases", phases, quick)),
        _setting("spp", spp, quick), _setting("reference_spp", reference_spp, quick), seed, max_depth,
    )  # fmt: skip


@_experiment_command("time-sampling")
@click.option("--time-sampling", "time_samplings", multiple=True, help=_TIME_SAMPLING_HELP)
@click.option("--correlation", "correlations", multiple=True, help=_CORRELATION_HELP)
@click.option("--h-steps", type=int, default=None, help=f"Heterodyne ratios h from 0 to 1 (default {NORMAL['h_steps']}, quick {QUICK['h_steps']}).")
@click.option("--phases", type=int, default=None, help=f"Phase offsets ψ = 2πk/N averaged over (default {NORMAL['phases']}, quick {QUICK['phases']}).")
def time_sampling_command(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, time_samplings, correlations, h_steps, phases):
    """Error of every time sampling x correlation versus h, averaged over ψ (paper Fig. 12)."""
    from .sweeps import run_time_sampling

    estimators = _estimators(time_samplings, correlations, quick)
    dyn, folder, cache, max_depth = _prepare("time-sampling", scene, output, resolution, quick, cache, max_depth, click.echo, use_ray, address)
    settings = _sweep_settings(h_steps, phases, spp, reference_spp, seed, max_depth, quick)
    _report(run_time_sampling(dyn, folder, estimators, settings, cache, click.echo))


@_experiment_command("shifts")
@click.option("--time-sampling", "time_samplings", multiple=True, help="antithetic and/or antithetic_mirror; repeatable (default both).")
@click.option("--correlation", default="replay", show_default=True, help=f"Correlation mode ({', '.join(MODES)}).")
@click.option("--shift-steps", type=int, default=None, help=f"Shifts a from 0 to 1 (default {NORMAL['shift_steps']}, quick {QUICK['shift_steps']}).")
@click.option("--h-steps", type=int, default=None, help=f"Heterodyne ratios h from 0 to 1 (default {NORMAL['h_steps']}, quick {QUICK['h_steps']}).")
@click.option("--phases", type=int, default=None, help=f"Phase offsets ψ = 2πk/N averaged over (default {NORMAL['phases']}, quick {QUICK['phases']}).")
def shifts_command(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, time_samplings, correlation, shift_steps, h_steps, phases):
    """Error of antithetic sampling versus the shift a and h (paper Fig. 15)."""
    from .sweeps import evenly_spaced, run_shifts

    methods = list(dict.fromkeys(time_samplings or ("antithetic", "antithetic_mirror")))
    shift_values = evenly_spaced(_setting("shift_steps", shift_steps, quick), "--shift-steps")
    dyn, folder, cache, max_depth = _prepare("shifts", scene, output, resolution, quick, cache, max_depth, click.echo, use_ray, address)
    settings = _sweep_settings(h_steps, phases, spp, reference_spp, seed, max_depth, quick)
    _report(run_shifts(dyn, folder, methods, shift_values, correlation, settings, cache, click.echo))


@_experiment_command("velocity")
@click.option("--time-sampling", "time_samplings", multiple=True, help="Time sampling; repeatable, crossed with --correlation (default: uniform/none, stratified/replay, antithetic/replay).")
@click.option("--correlation", "correlations", multiple=True, help=f"Correlation mode; repeatable ({', '.join(MODES)}).")
@click.option("--signal-electrons", type=float, default=20000.0, show_default=True, help="Photo-electrons of the 99th-percentile pixel per exposure, both taps.")
def velocity_command(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, time_samplings, correlations, signal_electrons):
    """Reconstructed versus ground-truth velocity, with and without sensor noise."""
    from .velocity import DEFAULT_ESTIMATORS, run_velocity

    if time_samplings or correlations:
        estimators = _estimators(time_samplings, correlations or ("replay",), quick)
    else:
        estimators = list(DEFAULT_ESTIMATORS)
    dyn, folder, cache, max_depth = _prepare("velocity", scene, output, resolution, quick, cache, max_depth, click.echo, use_ray, address)
    _report(run_velocity(
        dyn, folder, estimators, _setting("spp", spp, quick), _setting("reference_spp", reference_spp, quick),
        seed, max_depth, signal_electrons, cache, click.echo,
    ))  # fmt: skip
