"""``dopplertof experiment time-sampling | shifts | velocity | paper-fig12 | paper-fig9 | paper-fig15 SCENE``.

Options left out take the normal defaults (for the ``paper-*`` commands the original
scripts' protocol, :mod:`.paper`), or with ``--quick`` the tiny ones (a smoke test that
finishes in seconds). Bad input prints one line ``error: ...`` and exits with status 2.
"""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import sys

import click

from ..clitools import fail, output_folder
from ..correlation import MODES
from ..timesampling import METHODS

NORMAL = {"resolution": 64, "spp": 256, "reference_spp": 16384, "h_steps": 11, "phases": 4, "shift_steps": 11}
QUICK = {"resolution": 16, "spp": 16, "reference_spp": 256, "h_steps": 3, "phases": 2, "shift_steps": 3}
QUICK_CORRELATIONS = ("none", "replay")  # the extremes; every mode still runs without --quick
VELOCITY_DEFAULTS = (NORMAL, {**QUICK, "spp": 64, "reference_spp": 1024})
"""``experiment velocity``'s settings and smoke test: 64 spp, the fewest at which antithetic
renders' errors have the 15 degrees of freedom a valid pixel needs
(:data:`~dopplertof.reconstruct.MIN_STDERR_DOF`; at 16 spp every compared estimator had
none, and only the reference had numbers)."""
PAPER = {"resolution": 64, "spp": 1024, "reference_spp": 131072, "h_steps": 11, "phase_steps": 11, "shift_steps": 11}
"""The original scripts' protocol (:mod:`.paper`; their films were 256², built-in scenes here default to 64²)."""
PAPER_QUICK = {"resolution": 16, "spp": 16, "reference_spp": 256, "h_steps": 3, "phase_steps": 5, "shift_steps": 3}
"""The paper commands' smoke test (5 phases, so that ψ and ψ + π both occur)."""


class _ExperimentGroup(click.Group):
    """Unknown experiment names fail in one ``error:`` line, like every other bad input."""

    def resolve_command(self, ctx, args):
        if args and not args[0].startswith("-") and self.get_command(ctx, args[0]) is None:
            fail(f"unknown experiment {args[0]!r}; choose one of {', '.join(self.list_commands(ctx))}")
        return super().resolve_command(ctx, args)


@contextlib.contextmanager
def _one_line_errors():
    """Bad input becomes one ``error:`` line (exit 2); SIGINT, SIGTERM and SIGHUP one line
    saying what is kept (exit 128 + the signal)."""
    from ..backend import BackendError, signals_as_interrupt
    from ..scene import SceneError

    try:
        with signals_as_interrupt():
            yield
    except (ValueError, SceneError, BackendError, OSError) as exc:
        fail(str(exc))
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", signal.SIGINT)
        click.echo(f"{signal.Signals(signum).name}: stopped; no table was written; a reference already rendered is cached, "
                   "and one stopped part way keeps its passes there: the same command again continues, rendering neither again", err=True)
        sys.exit(128 + signum)


_DEPTH_HELP = "Path depth (default: the scene's, else the render default 5)."


def _common_options(command, defaults=(NORMAL, QUICK), depth_help=_DEPTH_HELP):
    normal, quick = defaults
    options = [
        click.argument("scene"),
        click.option("-o", "--output", default=None, help="Output folder (default out/experiments/<experiment>/<scene>)."),
        click.option("--spp", type=int, default=None, help=f"Paths per pixel of the compared renders (default {normal['spp']}, quick {quick['spp']})."),
        click.option("--reference-spp", type=int, default=None, help=f"Paths per pixel of the reference (default {normal['reference_spp']}, quick {quick['reference_spp']})."),
        click.option("--resolution", type=int, default=None, help=f"Film size of a built-in scene (default {normal['resolution']}, quick {quick['resolution']})."),
        click.option("--seed", type=int, default=0, show_default=True, help="Seed of the compared renders; the reference uses seed + 1."),
        click.option("--max-depth", type=int, default=None, help=depth_help),
        click.option("--quick", is_flag=True, help="Tiny settings for a smoke test (seconds)."),
        click.option("--cache", default=None, help="Reference cache folder (default $DOPPLERTOF_CACHE, else ~/.cache/dopplertof/references)."),
        click.option("--ray", "use_ray", is_flag=True, help="Render the references on Ray workers (as 'dopplertof render --ray'; the same pixels)."),
        click.option("--address", default=None, help="Ray cluster address (with --ray; default: the running Ray, else a local one)."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def _setting(name, value, quick, defaults=(NORMAL, QUICK)):
    if value is not None:
        return value
    return defaults[1 if quick else 0][name]


def _prepare(name, scene_arg, output, resolution, quick, cache, max_depth, echo, use_ray=False, address=None, defaults=(NORMAL, QUICK), default_depth=None):
    """(scene, output folder, cache, max depth) shared by the experiments; ``default_depth``:
    a function of the scene giving its depth when neither the option nor the scene does
    (default the render's)."""
    from .. import scenes
    from ..folder import check_writable, held, refuse_other_output
    from ..raytools import require_ray
    from .common import DEFAULT_MAX_DEPTH, ReferenceCache, default_cache_dir, open_scene

    if address and not use_ray:
        raise ValueError("--address needs --ray")
    if use_ray:
        require_ray()
    if scene_arg in scenes.SCENES:
        resolution = _setting("resolution", resolution, quick, defaults)
    scene = open_scene(scene_arg, resolution)
    folder = output_folder(output, os.path.join("out", "experiments", name, scene.label))
    cache_folder = cache or default_cache_dir()
    refuse_other_output(folder, "experiment")  # an experiment's own earlier tables it replaces
    _refuse_another_experiment(folder, _METADATA_NAMES.get(name, name))
    check_writable(folder)  # before any rendering, not when its results are due
    _HELD.enter_context(held(folder))  # until the command ends (_experiment_command)
    try:
        check_writable(cache_folder)
    except ValueError as exc:
        raise ValueError(f"reference cache: {exc}") from None
    cache = ReferenceCache(cache_folder, {"executor": "ray", "address": address} if use_ray else None)
    width, height = scene.scene.resolution
    echo(f"{name} on {scene.label} ({width}x{height}); output in {os.path.abspath(folder)}/")
    if max_depth is None:
        max_depth = default_depth(scene) if default_depth else scene.max_depth if scene.max_depth is not None else DEFAULT_MAX_DEPTH
    return scene, folder, cache, max_depth


# The output folders this process's experiment command holds while it writes them
# (:func:`dopplertof.folder.held`), let go when the command ends.
_HELD = contextlib.ExitStack()
# The experiment a command writes into metadata.json, where it is not the command's name.
_METADATA_NAMES = {"paper-fig15": "shifts"}


def _refuse_another_experiment(folder: str, own: str) -> None:
    """ValueError where ``folder`` holds another experiment's tables: this one would replace
    its results.csv and metadata.json and leave its plots (a mixed folder)."""
    from ..folder import read_metadata

    earlier = (read_metadata(folder) or {}).get("experiment")
    if isinstance(earlier, str) and earlier != own:
        raise ValueError(f"{folder!r} holds the {earlier!r} experiment's tables; this one ({own!r}) would replace them and leave its plots: choose another folder")


def _estimators(time_samplings, correlations, quick):
    from .common import Estimator

    time_samplings = time_samplings or METHODS
    correlations = correlations or (QUICK_CORRELATIONS if quick else MODES)
    return [Estimator(t, c) for t in dict.fromkeys(time_samplings) for c in dict.fromkeys(correlations)]


def _report(written):
    for path in written:
        click.echo(f"  {path}")


# Options every experiment checks before it loads a scene or writes anything: the least value.
_LEAST = {"spp": 1, "reference_spp": 1, "resolution": 1, "h_steps": 2, "phases": 1, "shift_steps": 2, "phase_steps": 1}


def _check_counts(options: dict) -> None:
    """Counts below their least value, ``--max-depth`` not >= 1 or -1, and a signal that is
    not > 0 are refused before a scene loads or a folder is made (some were refused after
    the first renders, under a line announcing the run)."""
    for name, least in _LEAST.items():
        value = options.get(name)
        if value is not None and value < least:
            raise ValueError(f"--{name.replace('_', '-')} must be an integer >= {least}, got {value}")
    depth = options.get("max_depth")
    if depth is not None and depth != -1 and depth < 1:
        raise ValueError(f"--max-depth must be >= 1 or -1 (unbounded), got {depth}")
    if options.get("signal_electrons") is not None:
        from .velocity import check_signal_electrons

        check_signal_electrons(options["signal_electrons"])


def _experiment_command(name, defaults=(NORMAL, QUICK), depth_help=_DEPTH_HELP):
    """Register ``name`` on the group with the common options; bad input becomes one error line.

    Use it as the outermost decorator, above the command's own options.
    """

    def wrap(function):
        @functools.wraps(function)
        def run(**kwargs):
            with _one_line_errors(), _HELD:
                _check_counts(kwargs)
                function(**kwargs)

        return experiment.command(name)(_common_options(run, defaults, depth_help))

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


@_experiment_command("velocity", defaults=VELOCITY_DEFAULTS)
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
    dyn, folder, cache, max_depth = _prepare("velocity", scene, output, resolution, quick, cache, max_depth, click.echo, use_ray, address, defaults=VELOCITY_DEFAULTS)
    _report(run_velocity(
        dyn, folder, estimators, _setting("spp", spp, quick, VELOCITY_DEFAULTS), _setting("reference_spp", reference_spp, quick, VELOCITY_DEFAULTS),
        seed, max_depth, signal_electrons, cache, click.echo,
    ))  # fmt: skip


# ---------------------------------------------------------------------------- the paper's figures

_PAPER_DEPTH_HELP = "Path depth (default: the scene's, else 4 for the Cornell boxes and 8 for other scenes, as the original scripts)."


def _paper_settings(scene_arg, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, h_steps, phase_steps, name, waveforms=()):
    """(scene, folder, cache, SweepSettings) of a ``paper-*`` command: the original protocol's
    ω_r and ψ grids (ψ = 2π·linspace(0, 1, N)), spp and depth, unless given."""
    from .paper import protocol_max_depth, protocol_phases
    from .sweeps import SweepSettings, evenly_spaced

    defaults = (PAPER, PAPER_QUICK)
    h_values = evenly_spaced(_setting("h_steps", h_steps, quick, defaults), "--h-steps")
    phases = protocol_phases(_setting("phase_steps", phase_steps, quick, defaults))
    dyn, folder, cache, max_depth = _prepare(name, scene_arg, output, resolution, quick, cache, max_depth, click.echo, use_ray, address, defaults, protocol_max_depth)
    settings = SweepSettings(
        h_values, phases, _setting("spp", spp, quick, defaults), _setting("reference_spp", reference_spp, quick, defaults), seed, max_depth,
        waveforms=tuple(waveforms),
    )  # fmt: skip
    return dyn, folder, cache, settings


_H_STEPS_HELP = f"Heterodyne ratios ω_r from 0 to 1 (default {PAPER['h_steps']}, quick {PAPER_QUICK['h_steps']})."
_PHASE_STEPS_HELP = f"Phases ψ = 2π·linspace(0, 1, N) averaged over (default {PAPER['phase_steps']}, quick {PAPER_QUICK['phase_steps']})."


@_experiment_command("paper-fig12", (PAPER, PAPER_QUICK), _PAPER_DEPTH_HELP)
@click.option("--time-sampling", "time_samplings", multiple=True, help=f"Time sampling; repeatable (default all: {', '.join(METHODS)}).")
@click.option("--correlation", "correlations", multiple=True, help="Correlation mode; repeatable (default none and replay: the original's depths 0 and 16).")
@click.option("--h-steps", type=int, default=None, help=_H_STEPS_HELP)
@click.option("--phase-steps", type=int, default=None, help=_PHASE_STEPS_HELP)
def paper_fig12_command(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, time_samplings, correlations, h_steps, phase_steps):
    """The paper's Figure 12: RMSE and PSNR of each time sampling, with and without path correlation, versus ω_r."""
    from .paper import fig12_estimators, run_fig12

    estimators = fig12_estimators(time_samplings, correlations)
    dyn, folder, cache, settings = _paper_settings(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, h_steps, phase_steps, "paper-fig12")
    _report(run_fig12(dyn, folder, estimators, settings, cache, click.echo))


@_experiment_command("paper-fig9", (PAPER, PAPER_QUICK), _PAPER_DEPTH_HELP)
@click.option("--waveform", "waveforms", multiple=True, help="Waveform; repeatable (default all four: sinusoidal, rectangular, triangular, trapezoidal).")
@click.option("--h-steps", type=int, default=None, help=_H_STEPS_HELP)
@click.option("--phase-steps", type=int, default=None, help=_PHASE_STEPS_HELP)
def paper_fig9_command(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, waveforms, h_steps, phase_steps):
    """The paper's Figure 9: each waveform's RMSE versus ω_r, with and without further stratification."""
    from ..modulation import WAVEFORMS
    from .paper import run_fig9

    unknown = [w for w in waveforms if w not in WAVEFORMS]
    if unknown:
        raise ValueError(f"unknown --waveform {unknown[0]!r}; choose one of {', '.join(WAVEFORMS)}")
    dyn, folder, cache, settings = _paper_settings(
        scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, h_steps, phase_steps, "paper-fig9", dict.fromkeys(waveforms),
    )  # fmt: skip
    _report(run_fig9(dyn, folder, settings, cache, click.echo))


@_experiment_command("paper-fig15", (PAPER, PAPER_QUICK), _PAPER_DEPTH_HELP)
@click.option("--shift-steps", type=int, default=None, help=f"Shifts a from 0 to 1 (default {PAPER['shift_steps']}, quick {PAPER_QUICK['shift_steps']}).")
@click.option("--h-steps", type=int, default=None, help=_H_STEPS_HELP)
@click.option("--phase-steps", type=int, default=None, help=_PHASE_STEPS_HELP)
def paper_fig15_command(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, shift_steps, h_steps, phase_steps):
    """The paper's Figure 15: RMSE of antithetic and mirrored sampling (replayed paths) over the shift a and ω_r."""
    from .paper import FIG15_METHODS
    from .sweeps import evenly_spaced, run_shifts

    shifts = evenly_spaced(_setting("shift_steps", shift_steps, quick, (PAPER, PAPER_QUICK)), "--shift-steps")
    dyn, folder, cache, settings = _paper_settings(scene, output, spp, reference_spp, resolution, seed, max_depth, quick, cache, use_ray, address, h_steps, phase_steps, "paper-fig15")
    _report(run_shifts(dyn, folder, FIG15_METHODS, shifts, "replay", settings, cache, click.echo))

