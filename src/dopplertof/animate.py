"""Animations: a clip of a dynamic scene, one D-ToF exposure per frame, with reconstructed velocity.

The scene's motion is defined over the whole clip (keyframe times in seconds); frame ``i``
renders the exposure [i/fps, i/fps + T] (T the cameras' exposure) with
:func:`dopplertof.render` at ``exposure_start = i/fps`` and seed ``seed + i``, then
reconstructs the radial velocity from its measurements
(:mod:`dopplertof.render_folder`). The default cameras are homodyne and heterodyne
(h = 0 and 1) at ψ = 0 and 90°, which determine velocity and depth.

Output folder:

==========================  ====================================================================
path                        content
==========================  ====================================================================
``animation.json``          the clip's settings; a rerun into the folder must match them
``frame_0000/`` …           one ``dopplertof render`` folder per frame (intensity, depth, ground
                            truth ``velocity``, measurements, metadata.json) plus the files of
                            :mod:`dopplertof.render_folder` (``velocity_reconstructed`` …)
``frame_0000/done.json``    written last: the frame is complete (its time and velocity error)
``summary.csv``             per frame: time (s), valid fraction, velocity error (m/s)
``velocity.gif``            per frame: ground truth (left) | reconstructed (right), one colour
                            range for the whole clip (blue approaching, red receding, grey none)
==========================  ====================================================================

Resuming: a rerun skips the frames that have ``done.json`` and renders the others, so an
interrupted run (Ctrl-C, SIGKILL, a full disk) continues where it stopped; the frame being
rendered then continues from its ``checkpoint.npz`` (saved every 60 s of rendering and
when stopped, removed once the frame is done), bit-identical to an uninterrupted frame.
``frames`` may change between runs (a longer clip extends a shorter one), the other
settings may not, unless ``overwrite=True`` deletes the old frames.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import re
import shutil
import time
import warnings

import click
import numpy as np

from .clitools import StopOnSignal, cameras_layer, fail, given_settings, output_folder, quiet_option, settings_options

from . import io, viz
from .differences import differences
from .folder import ANIMATION_SETTINGS
from .modulation import Camera
from .reconstruct import MIN_STDERR_DOF
from .render_folder import describe_error, errors_from, ground_truth_note, reconstruct, resolve_method, velocity_error, write_reconstruction

DEFAULT_FPS = 30.0
DEFAULT_CAMERAS = tuple((h, psi) for h in (0.0, 1.0) for psi in (0.0, math.pi / 2))
"""(heterodyne h, phase ψ in rad) of the default cameras."""

SETTINGS_FILE = ANIMATION_SETTINGS
DONE_FILE = "done.json"
SUMMARY_FILE = "summary.csv"
GIF_FILE = "velocity.gif"
GIF_MIN_PANEL_PX = 256  # small renders are enlarged (nearest neighbour) to stay visible
_FRAME_DIR = re.compile(r"frame_\d{4,}$")
_SUMMARY_COLUMNS = ("frame", "time_s", "valid_fraction", "median_abs_error_m_s", "mean_abs_error_m_s", "rmse_m_s")


def default_cameras(base: Camera | None = None) -> list[Camera]:
    """Homodyne and heterodyne cameras at ψ = 0 and 90°, with the other parameters of ``base``.

    Parameters
    ----------
    base : Camera or None, default None
        None: :class:`Camera`'s defaults.

    Returns
    -------
    list of Camera
    """
    base = base or Camera()
    return [dataclasses.replace(base, heterodyne=h, phase=psi) for h, psi in DEFAULT_CAMERAS]


def check_frames_and_fps(frames, fps) -> tuple[int, float]:
    """``frames`` as a positive int and ``fps`` as a finite float the clip's GIF can play
    (>= 1 / :data:`dopplertof.viz.GIF_MAX_FRAME_S`, a frame every 655.35 s), else ValueError.

    Parameters
    ----------
    frames : int
        Frames of the clip, > 0.
    fps : float, frames per second
        Finite, at least 1 / :data:`dopplertof.viz.GIF_MAX_FRAME_S`.

    Returns
    -------
    tuple of (int, float)

    Raises
    ------
    ValueError
        ``frames`` or ``fps`` out of range or of the wrong type, naming it.
    """
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames <= 0:
        raise ValueError(f"frames must be a positive integer, got {frames!r}")
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.number)) or not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a finite number of frames per second > 0, got {fps!r}")
    if 1.0 / fps > viz.GIF_MAX_FRAME_S:
        raise ValueError(f"fps must be >= {1.0 / viz.GIF_MAX_FRAME_S:.4g} frames per second (the clip's GIF holds a frame for at most {viz.GIF_MAX_FRAME_S} s), got {fps!r}")
    return int(frames), float(fps)


def frame_count(duration_s: float, fps: float) -> int:
    """Frames whose exposure opens during a clip of ``duration_s`` seconds (at least 1).

    Parameters
    ----------
    duration_s : float, s
        Length of the clip.
    fps : float, frames per second
        As for :func:`check_frames_and_fps`.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        A bad ``fps``.
    """
    _, fps = check_frames_and_fps(1, fps)
    return max(1, math.ceil(duration_s * fps - 1e-9))


def motion_duration(scene) -> float | None:
    """End (s) of the last keyframe of a scene's motions (bodies, camera, lights); None if
    none is bounded.

    Parameters
    ----------
    scene : DynamicScene

    Returns
    -------
    float or None
        Seconds.
    """
    ends = [motion.time_range()[1] for motion in scene.motions()]
    ends = [t for t in ends if math.isfinite(t)]
    return max(ends) if ends else None


def frame_folder(output: str, index: int) -> str:
    """The folder of frame ``index`` (from 0) of the clip in ``output``: ``output/frame_0000``, …

    Parameters
    ----------
    output : str
        The clip's folder.
    index : int
        The frame, from 0.

    Returns
    -------
    str
    """
    return os.path.join(output, f"frame_{index:04d}")


def is_done(output: str, index: int) -> bool:
    """True when frame ``index`` of the clip in ``output`` is finished: its ``done.json``,
    written last, exists.

    Parameters
    ----------
    output : str
        The clip's folder.
    index : int
        The frame, from 0.

    Returns
    -------
    bool
    """
    return os.path.isfile(os.path.join(frame_folder(output, index), DONE_FILE))


def _jsonable(value):
    """JSON round trip, so stored and new settings compare alike (tuples become lists ...)."""
    return json.loads(json.dumps(value, default=lambda v: v.item() if hasattr(v, "item") else str(v)))


def _existing_frames(output: str) -> list[str]:
    if not os.path.isdir(output):
        return []
    return sorted(name for name in os.listdir(output) if _FRAME_DIR.match(name))


def _prepare_output(output: str, settings: dict, overwrite: bool) -> None:
    """Create ``output`` for ``settings``; refuse an unusable folder or one holding a different clip."""
    from .folder import check_writable, refuse_other_output

    refuse_other_output(output, "animation")
    check_writable(output)
    settings_path = os.path.join(output, SETTINGS_FILE)
    if overwrite:
        for name in _existing_frames(output):
            shutil.rmtree(os.path.join(output, name))
        for name in (SETTINGS_FILE, SUMMARY_FILE, GIF_FILE):
            if os.path.exists(os.path.join(output, name)):
                os.remove(os.path.join(output, name))
    elif os.path.isfile(settings_path):
        stored = io.read_json(settings_path)
        ignore = {"frames"}  # a longer clip extends a shorter one
        differ = differences({k: v for k, v in stored.items() if k not in ignore}, {k: v for k, v in settings.items() if k not in ignore})
        if differ:
            changes = "; ".join(differ)
            raise ValueError(f"{output} holds an animation with other settings ({changes}); "
                             "use another folder, or --overwrite to replace it")
    elif _existing_frames(output):
        raise ValueError(f"{output} has frame folders but no {SETTINGS_FILE}; use another folder, or --overwrite to replace them")
    io.write_json(settings_path, settings)


def _write_done(folder: str, summary: dict) -> None:
    # Atomic: a Ctrl-C while writing leaves either no marker or a whole one.
    temporary = os.path.join(folder, DONE_FILE + ".tmp")
    io.write_json(temporary, summary)
    os.replace(temporary, os.path.join(folder, DONE_FILE))


class AnimationStopped(Exception):
    """:func:`render_animation` stopped before its last frame (its ``stop()`` or a Ctrl-C)."""


def _render_frame(scene, index, fps, settings, method, folder, progress, stop):
    from .folder import CHECKPOINT, write_result
    from .render import render

    start_s = index / fps
    cameras = list(settings.cameras)
    os.makedirs(folder, exist_ok=True)
    # The frame's sums are saved as it renders and kept until done.json: a stopped or killed
    # run continues the frame where its checkpoint left it.
    checkpoint = os.path.join(folder, CHECKPOINT)
    frame_settings = settings.replace(seed=settings.seed + index, exposure_start=start_s)
    result = render(scene, settings=frame_settings, progress=progress, checkpoint=checkpoint, keep_checkpoint=True, stop=stop)
    if result.interrupted:  # a frame must be whole
        raise AnimationStopped(f"stopped in frame {index}; the frames before it are done, a rerun resumes there")
    write_result(result, folder, {"frame": index, "time_s": start_s})
    reconstruction = reconstruct(result.measurements, cameras, method, result.measurement_stderr, result.maps.get("measurement_covariance"),
                                 stderr_dof=result.info["stderr_dof"])
    note = ground_truth_note(result.info["light_sources_in_motion"])
    write_reconstruction(folder, reconstruction, result.velocity, ground_truth_note=note)
    summary = {"frame": index, "time_s": start_s, "exposure_s": cameras[0].exposure, "stderr_dof": result.info["stderr_dof"],
               **velocity_error(reconstruction, result.velocity, note)}
    _write_done(folder, summary)
    os.remove(checkpoint)
    return summary


def _gif_frame(truth, reconstructed, vmax):
    """Ground truth | reconstructed, coloured, enlarged to at least GIF_MIN_PANEL_PX wide."""
    scale = max(1, math.ceil(GIF_MIN_PANEL_PX / truth.shape[1]))
    left, right = (np.kron(viz.signed_to_rgb8(v, vmax=vmax), np.ones((scale, scale, 1), np.uint8))
                   for v in (truth, reconstructed))
    gap = np.full((left.shape[0], max(2, scale), 3), 255, np.uint8)
    return np.concatenate([left, gap, right], axis=1)


def write_clip_files(output: str, frames: int, fps: float) -> list[str]:
    """``summary.csv`` and ``velocity.gif`` from the finished frames 0 … frames−1.

    Parameters
    ----------
    output : str
        The clip's folder.
    frames : int
        Frames of the clip.
    fps : float, frames per second
        Playback rate of the GIF.

    Returns
    -------
    list of str
        The paths written.
    """
    done = [i for i in range(frames) if is_done(output, i)]
    summaries = [io.read_json(os.path.join(frame_folder(output, i), DONE_FILE)) for i in done]
    summary_path = os.path.join(output, SUMMARY_FILE)
    with open(summary_path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=_SUMMARY_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(summaries)
    written = [summary_path]
    if done:
        maps = [(io.read_exr(os.path.join(frame_folder(output, i), "velocity.exr")),
                 io.read_exr(os.path.join(frame_folder(output, i), "velocity_reconstructed.exr"))) for i in done]
        vmax = viz.auto_vmax([truth for truth, _ in maps])  # one range for the clip: colours compare across frames
        gif_path = os.path.join(output, GIF_FILE)
        viz.write_gif(gif_path, [_gif_frame(truth, rec, vmax) for truth, rec in maps], fps)
        written.append(gif_path)
    return written


def render_animation(scene, output: str, *, frames: int, fps: float = DEFAULT_FPS, settings=None,
                     method: str | None = None, scene_label: str | None = None, overwrite: bool = False,
                     progress: bool = False, log=print, stop=None) -> list[dict]:
    """Render a clip frame by frame into ``output`` (module docstring), resuming a previous run.

    Parameters
    ----------
    scene : DynamicScene
        Its keyframe times are seconds of the clip.
    output : str
        Output folder.
    frames : int
        Number of frames, > 0.
    fps : float
        Frames per second, > 0: frame ``i`` opens its exposure at i/fps seconds.
    settings : :class:`~dopplertof.settings.RenderSettings` or dict, optional
        The settings of every frame, or a dict of setting names on top of the defaults
        (default: the defaults with :func:`default_cameras`); anything else is a TypeError;
        frame ``i`` uses seed ``settings.seed + i`` and opens its exposure at i/fps. The
        cameras must determine velocity (see
        :func:`dopplertof.render_folder.resolve_method`); checked before rendering.
    method : {None, "auto", "ratio", "fit"}
        Velocity reconstruction, see :func:`dopplertof.render_folder.resolve_method`.
    scene_label : str, optional
        Identifies the scene in ``animation.json`` (default ``scene.source``).
    overwrite : bool
        Delete the frames of a previous clip in ``output`` instead of refusing other settings
        (a bool, else ValueError).
    progress : bool
        A progress bar per frame (a bool, else ValueError).
    log : callable
        Receives one line per frame.
    stop : callable, optional
        Passed to :func:`dopplertof.render`: True stops the frame in progress
        (:class:`AnimationStopped`).

    Returns
    -------
    list of dict
        The summary of every frame (also in ``summary.csv``).

    Raises
    ------
    ValueError
        Bad frames/fps, a camera set that cannot determine velocity, cameras with an
        ``exposure_start`` of their own, or ``output`` holding a clip with other settings.
    AnimationStopped
        When ``stop()`` returned True (or a Ctrl-C came) in a frame, after the finished
        frames are safe; the frame in progress is dropped and a rerun resumes there.
    KeyboardInterrupt
        On Ctrl-C before a frame's first pass finished, after the finished frames are safe.
    """
    from .settings import RenderSettings
    from .validation import checked

    frames, fps = check_frames_and_fps(frames, fps)
    overwrite, progress = checked("overwrite", overwrite, "bool"), checked("progress", progress, "bool")
    if isinstance(settings, dict):
        settings = RenderSettings.build(settings)
    elif settings is not None and not isinstance(settings, RenderSettings):
        raise TypeError(f"settings must be a dopplertof.RenderSettings or a dict of setting names, got {type(settings).__name__}")
    settings = settings or RenderSettings(cameras=default_cameras())
    if not settings.cameras:
        settings = settings.replace(cameras=default_cameras())
    scheduled = [c.label() for c in settings.cameras if c.exposure_start is not None]
    if scheduled:
        raise ValueError(f"an animation opens every camera's exposure at its frame's time (i/fps); cameras {', '.join(scheduled)} "
                         "set their own exposure_start (a capture schedule), which animate does not take")
    method = resolve_method(list(settings.cameras), method)
    longest_s = max(c.exposure for c in settings.cameras)
    if frames > 1 and longest_s > 1.0 / fps:
        warnings.warn(f"each frame's exposure ({longest_s:g} s) is longer than the time between frames (1/fps = {1.0 / fps:g} s): "
                      "the frames' exposures overlap, and they see the same motion", stacklevel=2)
    width, height = scene.resolution
    record = _jsonable({
        "scene": scene_label or scene.source, "scene_identity": scene.identity(), "resolution": [width, height], "frames": frames, "fps": fps,
        "method": method, **{k: v for k, v in settings.as_dict().items() if k != "exposure_start"},
    })
    _prepare_output(output, record, overwrite)
    beyond = [name for name in _existing_frames(output) if int(name.split("_")[1]) >= frames]
    if beyond:  # finished work is kept, but it is not part of this clip
        log(f"note: {len(beyond)} frame folder{'' if len(beyond) == 1 else 's'} beyond frame {frames - 1} "
            f"({beyond[0]} … {beyond[-1]}) from a longer clip stay in {output}, outside {SUMMARY_FILE} and {GIF_FILE}; "
            f"--frames {int(beyond[-1].split('_')[1]) + 1} takes {'it' if len(beyond) == 1 else 'them'} back in")
    summaries = []
    for index in range(frames):
        folder = frame_folder(output, index)
        head = f"frame {index + 1}/{frames} (t = {index / fps:.6g} s)"
        if is_done(output, index):
            summaries.append(io.read_json(os.path.join(folder, DONE_FILE)))
            log(f"{head}: done in an earlier run, skipped")
            continue
        started = time.perf_counter()
        summary = _render_frame(scene, index, fps, settings, method, folder, progress, stop)
        summaries.append(summary)
        dof = summary["stderr_dof"]
        too_few = dof < MIN_STDERR_DOF
        why = f" ({errors_from(dof)}, a valid pixel needs {MIN_STDERR_DOF}: more --spp)" if too_few else ""
        log(f"{head}: rendered in {time.perf_counter() - started:.1f} s; {describe_error(summary)}{why}")
    write_clip_files(output, frames, fps)
    return summaries


@click.command("animate")
@click.argument("scene")
@click.option("--frames", type=int, default=None,
              help="Number of frames (default: the scene's motion length × fps, at least 1).")
@click.option("--fps", type=float, default=DEFAULT_FPS, show_default=True,
              help="Frames per second: frame i exposes [i/fps, i/fps + T].")
@click.option("--resolution", default=None, help="Film size in pixels: N (square) or WxH; replaces the scene's.")
@click.option("-D", "defines", multiple=True, metavar="NAME=VALUE", help="Value of $NAME in a scene file. Repeatable.")
@click.option("-o", "--output", default=None, help="Output folder (default: out/<scene>-animation).")
@click.option("--camera", "camera_specs", multiple=True,
              help="A camera as in 'dopplertof render' (repeatable; default h=0 and h=1 at psi=0 and 90deg, with the scene's first camera's f, T and waveform).")
@click.option("--method", type=click.Choice(["auto", "ratio", "fit"]), default=None,
              help="Velocity reconstruction (default: auto, the fit for sinusoidal cameras, else the ratio).")
@click.option("--overwrite", is_flag=True, help="Replace a clip with other settings in the output folder.")
@quiet_option
@settings_options(exclude=("exposure_start",))
def animate_command(scene, frames, fps, resolution, defines, output, camera_specs, method, overwrite, quiet, **options):
    """Render SCENE as a clip: one D-ToF exposure per frame, with reconstructed velocity and a GIF.

    Frame i uses seed + i. An interrupted run (Ctrl-C, SIGTERM, SIGHUP) resumes where it
    stopped when run again with the same options.
    """
    from . import scenes
    from .backend import BackendError
    from .scene import SceneError
    from .settings import RenderSettings, scene_camera, scene_layer

    output = output_folder(output, os.path.join("out", f"{os.path.splitext(os.path.basename(scene))[0]}-animation"))
    stop = StopOnSignal()
    try:
        check_frames_and_fps(1 if frames is None else frames, fps)  # before the scene loads
        dyn = scenes.open_scene(scene, resolution, defines)
        base = scene_layer(dyn, scene)
        base.pop("exposure_start", None)  # each frame sets its own
        if camera_specs:
            cameras = cameras_layer(camera_specs, options.get("exposure"), base, dyn)
        else:  # the scene's camera (or shutter) gives f_g, T and the waveform of the default set
            defaults = default_cameras(scene_camera(base))
            if options.get("exposure") is not None:
                defaults = [dataclasses.replace(c, exposure=options["exposure"]) for c in defaults]
            cameras = {"cameras": defaults}
        settings = RenderSettings.build(base, given_settings(options), cameras, where=scene)
        if frames is None:
            duration = scenes.clip_duration(scene) if scene in scenes.SCENES else motion_duration(dyn)
            if duration is None:
                raise ValueError(f"{scene}: its motion has no end (or nothing moves); give --frames")
            frames = frame_count(duration, fps)
        label = scene if scene in scenes.SCENES else os.path.abspath(scene)
        with stop:
            render_animation(dyn, output, frames=frames, fps=fps, settings=settings, method=method, scene_label=label,
                             overwrite=overwrite, progress=not quiet, log=click.echo, stop=stop)
    except (ValueError, SceneError, BackendError, FileNotFoundError) as exc:
        fail(str(exc))
    except OSError as exc:
        fail(f"cannot write {output!r}: {exc.strerror or exc}")
    except (KeyboardInterrupt, AnimationStopped):
        click.echo(f"interrupted: the finished frames are in {os.path.abspath(output)}/; "
                   "run the same command again to resume", err=True)
        raise SystemExit(stop.exit_status) from None
    click.echo(f"animation of {scene}: {frames} frame{'' if frames == 1 else 's'} in {os.path.abspath(output)}/ "
               f"({GIF_FILE}: ground truth | reconstructed velocity; {SUMMARY_FILE}; frame_*/)")
