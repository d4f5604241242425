"""Rendering: the passes of a render, its capture windows, checkpoints and the result.

:func:`render` splits the film × spp into passes (:mod:`dopplertof.passes`) of at most ``lanes_per_pass`` lanes:
ranges of samples of every pixel, and tiles of pixels where the film is larger than a
pass, so the tracing kernel's memory is bounded whatever the film size. Each pass runs one
kernel (:func:`dopplertof.tracing.trace_pass`) and is added, in Float64 on the host, to
per-pixel sums:

* estimates (:data:`~dopplertof.outputs.OUTPUTS` of kind ``estimate``): the sum of the
  group means (a group of correlated samples counts once), and, for the standard errors
  and the cameras' covariance, where the times are stratified the sums of the squares and
  camera products of the differences within the pixel's strata, else the sums, squares
  and camera products of the means of its independent *replicates*
  (:mod:`dopplertof.tracing.lanes`, :class:`~dopplertof.passes.Reducer`);
* ground truth: sums of value × hit and of hits.

Capture schedules: cameras whose exposure windows differ
(:attr:`~dopplertof.settings.RenderSettings.windows`) are rendered window by window, the
schedule of passes once per window with that window's cameras, times and seed
(:func:`~dopplertof.tracing.lanes.window_seed`), each into sums of its own; cameras of one
window share paths, cameras of different windows are independent.

Random numbers depend on (seed, window, pixel, sample index) only, so the result does not
depend on the tiling or the pass split. A render stopped early (Ctrl-C, or ``stop()`` returning
True between passes) returns what the finished passes hold (``result.interrupted``).
With ``checkpoint=PATH`` the sums are saved there while the render runs (after the first
pass that ends ``checkpoint_interval_s`` after the previous save, default 60 s) and when it
stops early, each time atomically (temporary file, fsync, rename: a fault during a save
leaves the previous checkpoint), so a fault that kills the process (SIGKILL, the OOM
killer, a full disk) loses at most that interval; a later call with the same settings
continues from them to a result bit-identical to an uninterrupted render.

Each pass is traced and reduced to per-pixel increments where its scene is
(:class:`~dopplertof.passes.PassTracer`) and added here, in order
(:meth:`~dopplertof.passes.Accumulator.apply`):
with ``executor="ray"`` the passes are traced on Ray workers (:mod:`dopplertof.render_ray`)
and added in the same order, so the result is the same, bit for bit.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import resources
from .backend import signals_held
from .io import NPZ_READ_ERRORS
from .outputs import BY_NAME, ESTIMATES, TRUTH
from .passes import MAX_COVARIANCE_CAMERAS, Accumulator, PassTracer, Reducer, schedule
from .settings import DEFAULT_CHECKPOINT_INTERVAL_S, DEFAULT_EXPOSURE_S, FIELDS, RenderSettings, checked_checkpoint_interval, scene_layer, shutter_interval
from .validation import checked

__all__ = ["render", "RenderResult", "RenderSettings", "DEFAULT_EXPOSURE_S", "CheckpointWriteError"]


@dataclass
class RenderResult:
    """What :func:`render` returns.

    ``maps`` holds every output of :data:`dopplertof.outputs.OUTPUTS` and the standard
    errors of the estimates, each also an attribute: ``intensity`` and ``stderr``
    (H, W, 3) or (H, W) in mono, ``measurements`` and ``measurement_stderr``
    (n_cameras, H, W), ``depth``, ``velocity``, ``point_velocity`` (H, W; NaN where no
    sample hit), ``velocity_3d`` (H, W, 3), ``flow`` (H, W, 2), ``coverage`` (H, W) and
    ``instance_id`` (H, W, int32), and, for 2 to ``MAX_COVARIANCE_CAMERAS`` cameras,
    ``measurement_covariance`` (n_cameras, n_cameras, H, W): the covariance of the
    measurements' means (cameras of one exposure window share paths, so their errors
    correlate; cameras of different windows are independent: 0), which
    :func:`dopplertof.reconstruct.velocity` propagates. Images are float32.

    With a capture schedule (cameras in several exposure windows) the measurements are
    each camera's over its own window, in the order of ``cameras``; the intensity, its
    standard error, the ground truth, ``coverage`` and ``instance_id`` are those of the
    *reference* window, the first camera's (``settings.windows[0]``). ``cameras`` are the
    rendered cameras with their window's ``exposure_start`` filled in.

    Parameters
    ----------
    maps : dict
        Name → array, as above.
    settings : RenderSettings
        The settings rendered.
    spp : int
        Paths per pixel done (less than asked where interrupted).
    interrupted : bool, default False
        The render stopped early (``stop``, a signal).
    info : dict, default {}
        Render time (s), passes, executor, exposure windows ``[[start, T], …]`` (s), and
        ``stderr_dof``: the degrees of freedom the standard errors are estimated from (one per
        stratum of two groups of correlated times, spp/4 for antithetic times; replicates − 1;
        :func:`dopplertof.reconstruct.velocity` needs at least
        :data:`~dopplertof.reconstruct.MIN_STDERR_DOF` to call a pixel valid; 0 for a render
        with stratified times stopped before its last stratum, whose errors leave out the
        spread between the strata it did not draw: at h = 1 they understate the error 100-300×).
    sensor : Sensor or None, default None
        The sensor rendered (``render(..., sensor=)``); its frames' electrons are
        ``maps["raw"]``.
    record : dopplertof.design.Record or None, default None
        The scene's response record (``render(..., record=True)``).

    Examples
    --------
    >>> import dopplertof as dt
    >>> result = dt.render(dt.scenes.cornell_box(resolution=16), spp=8, max_depth=2)   # intensity only
    >>> result.spp, result.intensity.shape, result.depth.shape, result.measurements.shape
    (8, (16, 16, 3), (16, 16), (0, 16, 16))
    """

    maps: dict
    settings: RenderSettings
    spp: int  # paths per pixel done (less than asked where interrupted)
    interrupted: bool = False
    info: dict = field(default_factory=dict)  # render time (s), passes, executor, exposure windows [[start, T], ...] (s), stderr_dof
    sensor: object = None  # the dopplertof.Sensor rendered (render(..., sensor=)); its frames' electrons are maps["raw"]
    record: object = None  # the scene's response record (render(..., record=True)): dopplertof.design.Record

    def __getattr__(self, name):
        maps = self.__dict__.get("maps", {})
        if name in maps:
            return maps[name]
        raise AttributeError(f"RenderResult has no {name!r}")

    @property
    def cameras(self) -> list:
        """The cameras, each with its window's ``exposure_start`` (never None)."""
        return list(self.settings.scheduled_cameras)

    @property
    def seed(self) -> int:
        """The render's seed (``settings.seed``)."""
        return self.settings.seed


def sums_bytes_per_pixel(n_cameras: int) -> int:
    """Bytes per pixel of the Float64 sums and counters of one exposure window with
    ``n_cameras`` cameras: what :class:`~dopplertof.passes.Accumulator` keeps and a checkpoint holds."""
    estimates = 3 + n_cameras
    truth = sum(o.channels for o in TRUTH)
    pairs = n_cameras * (n_cameras - 1) // 2 if 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS else 0
    return 8 * (4 * estimates + truth + 2 * pairs) + 4 * 5  # stratified times: open and closed camera products


def host_bytes_per_pixel(n_cameras: int) -> int:
    """Host memory of the film's Float64 sums and the float32 result, per pixel (bytes)."""
    estimates = 3 + n_cameras
    truth = sum(o.channels for o in TRUTH)
    return sums_bytes_per_pixel(n_cameras) + 4 * (2 * estimates + truth + 6 + n_cameras * n_cameras)


def checkpoint_disk_bytes(width: int, height: int, settings: RenderSettings) -> int:
    """Disk space a render's checkpoint needs at its peak: while a save is under way the
    previous checkpoint and the new one exist side by side (atomic replace)."""
    return 2 * width * height * sum(sums_bytes_per_pixel(len(w.cameras)) for w in settings.windows)


def check_film_memory(width: int, height: int, n_cameras: int, n_windows: int = 1) -> None:
    """ValueError for an empty film, or one whose buffers need more than the available memory
    (each exposure window of a capture schedule keeps sums of its own)."""
    if width < 1 or height < 1:
        raise ValueError(f"the film must be at least 1x1 pixels, got {width}x{height}")
    need = width * height * (host_bytes_per_pixel(n_cameras) + (n_windows - 1) * host_bytes_per_pixel(0))
    available = resources.available_memory_bytes()
    if available is not None and need > available:
        raise ValueError(f"a {width}x{height} film with {n_cameras} camera(s) needs about {need / 2**30:.1f} GiB of memory for its buffers; {available / 2**30:.1f} GiB are available")


# A rough rate for the warning below: DESIGN §3 measures about 3e6 paths/s for the D-ToF
# tracer on 2 CPU cores (stock path 4.8e6, ours 1.59x slower); a GPU is faster.
ROUGH_PATHS_PER_SECOND = 3e6
LONG_RENDER_S = 24 * 3600.0


def warn_if_long(width: int, height: int, spp: int, n_windows: int = 1) -> None:
    """Warn when the render would take more than a day at :data:`ROUGH_PATHS_PER_SECOND`:
    an spp of 1e9 is almost surely a mistake."""
    paths = float(width) * height * spp * n_windows
    seconds = paths / ROUGH_PATHS_PER_SECOND
    if seconds > LONG_RENDER_S:
        warnings.warn(
            f"spp={spp} on a {width}x{height} film{f' in {n_windows} exposure windows' if n_windows > 1 else ''} is {paths:.3g} paths: "
            f"about {seconds / 86400:.3g} days at {ROUGH_PATHS_PER_SECOND:.0e} paths/s (2 CPU cores)", stacklevel=3,
        )  # fmt: skip


# ----------------------------------------------------------------------------------------
# Checkpoints


def checked_until_noise(ratio) -> float:
    """``until_noise`` (:func:`render`) as a float, else ValueError: a ratio > 0."""
    ratio = checked("until_noise", ratio, "float")
    if not ratio > 0:
        raise ValueError(f"until_noise={ratio!r}: must be > 0")
    return ratio


def fingerprint(scene, settings: RenderSettings, record=None) -> str:
    """What a checkpoint must match to be continued: the settings, the film, the scene and
    the response record's grid (a :class:`~dopplertof.design.RecordSpec`, if any), as JSON
    text (the checkpoint keeps it, and its hash)."""
    key = {"settings": settings.as_dict(), "film": list(scene.resolution), "scene": scene.identity(), "motions": len(scene.motions())}
    if record is not None:
        key["record"] = record.as_dict()
    return json.dumps(key, sort_keys=True, default=str)


def _digest(key: str) -> str:
    return hashlib.sha256(key.encode()).hexdigest()


def _differences(stored_key: str, key: str) -> str:
    """What differs between two :func:`fingerprint` texts, as ``"spp: 64 in the checkpoint,
    128 now"`` items (empty where the stored one cannot be read: older checkpoints)."""
    from .differences import differences

    try:
        old, new = json.loads(stored_key), json.loads(key)
        old = {**old.pop("settings", {}), **old}
        new = {**new.pop("settings", {}), **new}
    except (ValueError, AttributeError, TypeError):
        return ""
    items = differences(old, new, "in the checkpoint")
    return "; ".join(items[:3]) + ("; …" if len(items) > 3 else "")


def _checkpoint_names(accs: list) -> list[tuple[str, Accumulator, str]]:
    """(name in the file, accumulator, name in its state) of every array: a single window's
    under their own names, a schedule's prefixed with their window (``w1.group_sum``)."""
    prefix = (lambda k: "") if len(accs) == 1 else (lambda k: f"w{k}.")
    return [(prefix(k) + name, acc, name) for k, acc in enumerate(accs) for name in acc.state]




def warn_outside_the_shutter(scene, settings: RenderSettings) -> None:
    """Warn where a window of ``settings`` opens before or closes after the scene file's
    shutter interval: cameras given with their own T and start (a ``dopplertof.Camera``'s
    T defaults to 1.5 ms; the command line's ``--camera`` without T takes the shutter's)
    expose when the file does not."""
    shutter = shutter_interval(scene)
    if shutter is None:
        return
    open_s, length_s = shutter
    close_s = open_s + length_s
    slack = 1e-6 * length_s
    for w in settings.windows:
        before, after = w.start_s < open_s - slack, w.start_s + w.exposure_s > close_s + slack
        if before or after:
            side = " and ".join(s for s, outside in (("open before", before), ("close after", after)) if outside)
            warnings.warn(f"the cameras expose {w.start_s:g} to {w.start_s + w.exposure_s:g} s: they {side} the scene's shutter "
                          f"({open_s:g} to {close_s:g} s); to expose for the shutter give exposure_start={open_s:g} and "
                          f"exposure={length_s:g} (Camera(...), or --camera ...,start={open_s:g},T={length_s:g}); "
                          f"a dopplertof.Camera's own T defaults to {DEFAULT_EXPOSURE_S:g} s", stacklevel=3)
            return


def _checkpoint_lanes_per_pass(path, settings: RenderSettings) -> int | None:
    """The checkpoint's ``lanes_per_pass`` where it is at most ``settings``' (else None): the
    sums are per pass, so a render continues the checkpoint's passes (``until_noise`` lowers
    the pass size, and a render resumed with it would otherwise be refused)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            stored = json.loads(str(data["fingerprint_text"]))["settings"]["lanes_per_pass"]
    except (*NPZ_READ_ERRORS, KeyError, ValueError, TypeError):
        return None  # no checkpoint yet, or one that _load_checkpoint explains
    return stored if isinstance(stored, int) and 0 < stored <= settings.lanes_per_pass else None


def _check_checkpoint_path(path) -> None:
    """ValueError where ``path`` cannot hold a checkpoint, before any rendering (not at its
    first save, a checkpoint interval later): empty, a folder, in a folder that does not
    exist or that cannot be written."""
    name = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(name)) if name else ""
    if not name or os.path.isdir(name):
        raise ValueError(f"checkpoint={name!r} must name a file")
    if not os.path.isdir(folder):
        raise ValueError(f"checkpoint={name!r}: its folder {folder!r} does not exist (or is a file)")
    if not os.access(folder, os.W_OK):
        raise ValueError(f"checkpoint={name!r}: its folder {folder!r} cannot be written")


def _load_checkpoint(path, accs: list, key: str):
    try:
        with np.load(path, allow_pickle=False) as data:
            stored = {name: data[name] for name in data.files}
    except NPZ_READ_ERRORS as exc:
        why = "not a checkpoint (numpy refuses to read it)" if "allow_pickle" in str(exc) else str(exc)  # numpy's advice to unpickle is no advice here
        raise ValueError(f"{path}: the checkpoint cannot be read ({why}); remove that file to render from the start") from None
    if str(stored.get("fingerprint")) != _digest(key):
        differences = _differences(str(stored.get("fingerprint_text", "")), key)
        raise ValueError(
            f"{path}: the checkpoint belongs to a render with other settings or another scene"
            f"{f' ({differences})' if differences else ''}; remove it or render into another folder"
        )
    for name_in_file, acc, name in _checkpoint_names(accs):
        if name_in_file not in stored or stored[name_in_file].shape != acc.state[name].shape:
            raise ValueError(f"{path}: the checkpoint is damaged ({name_in_file!r} missing or of another shape)")
        acc.state[name] = stored[name_in_file]


class CheckpointWriteError(OSError):
    """A checkpoint could not be written (a full disk, say); the one before it, if any, is intact.

    ``str()`` says what was lost and what is kept; ``errno`` is the failed write's.
    """

    def __str__(self):
        return self.strerror


def save_checkpoint(path, accs: list, key: str):
    """Write the accumulators (one per exposure window) atomically (temporary name, fsync,
    rename: :func:`dopplertof.io.atomic_path`)."""
    from .io import atomic_path

    arrays = {stored: acc.state[name] for stored, acc, name in _checkpoint_names(accs)}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, fingerprint=np.array(_digest(key)), fingerprint_text=np.array(key), **arrays)


def passes_in_checkpoint(path) -> int | None:
    """Passes done that the checkpoint at ``path`` holds (all windows).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    int or None
        None where there is no readable checkpoint.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            return sum(int(data[name][0]) for name in data.files if name.rpartition(".")[2] == "passes_done")
    except NPZ_READ_ERRORS:
        return None


def _save_or_explain(path, accs: list, key: str, total_passes: int):
    """:func:`save_checkpoint`, or a :class:`CheckpointWriteError` saying what the kept one holds."""
    try:
        save_checkpoint(path, accs, key)
    except OSError as exc:
        kept = passes_in_checkpoint(path)
        what = "no earlier checkpoint is kept" if kept is None else f"the checkpoint of {kept} of {total_passes} passes is kept"
        raise CheckpointWriteError(exc.errno, f"cannot write the checkpoint {os.fspath(path)!r} ({exc.strerror or exc}); {what}") from exc


# ----------------------------------------------------------------------------------------
# Capture schedules


def _merge_windows(finished: list[dict], windows, n_cameras: int, shape: tuple[int, int]) -> dict:
    """One result's maps from the windows' (:meth:`Accumulator.finish` of each): every
    camera's measurement and error from its window, in the cameras' order; everything else
    from the reference window; the covariance block-diagonal (windows are independent)."""
    if len(finished) == 1:
        return finished[0]
    maps = dict(finished[0])
    for o in ESTIMATES:
        if o.channels != "cameras":
            continue
        for name in (o.name, o.stderr_name):
            merged = np.empty((n_cameras, *shape), np.float32)
            for window, window_maps in zip(windows, finished):
                merged[list(window.indices)] = window_maps[name]
            maps[name] = merged
    maps.pop("measurement_covariance", None)
    errors = maps[BY_NAME["measurements"].stderr_name]
    if 2 <= n_cameras <= MAX_COVARIANCE_CAMERAS and np.isfinite(errors).any():
        covariance = np.zeros((n_cameras, n_cameras, *shape), np.float32)
        for i in range(n_cameras):
            covariance[i, i] = errors[i].astype(np.float64) ** 2
        for window, window_maps in zip(windows, finished):
            if "measurement_covariance" in window_maps:
                idx = np.array(window.indices)
                covariance[idx[:, None], idx[None, :]] = window_maps["measurement_covariance"]
        maps["measurement_covariance"] = covariance
    return maps


# ----------------------------------------------------------------------------------------
# Stopping when the Monte Carlo error is below the sensor's noise


def _noise_ratio_reached(acc, window, sensor, shape) -> float | None:
    """The ``until_noise`` ratio the frames of ``window`` reach now
    (:mod:`dopplertof.design.convergence`); None while tiles of the film differ in samples."""
    import copy

    from .design.convergence import noise_ratio, quantile

    samples = acc.state["samples"]
    if samples.min() != samples.max():
        return None
    n_cameras = len(sensor.cameras())
    maps = copy.deepcopy(acc).finish(*shape, len(window.cameras))  # finish consumes the sums
    measurements, errors = np.zeros((n_cameras, *shape)), np.zeros((n_cameras, *shape))
    measurements[list(window.indices)] = maps["measurements"]
    errors[list(window.indices)] = maps[BY_NAME["measurements"].stderr_name]
    frames = [i for i in range(len(sensor.frames)) if i in window.indices]
    return quantile(noise_ratio(sensor, measurements, errors, frames))


# ----------------------------------------------------------------------------------------
# render()

EXECUTORS = ("local", "ray")


def _traced_locally(scene, settings, passes, grid=None):
    tracer = PassTracer(scene, settings, grid)
    for p in passes:
        yield tracer(p)


def render(
    scene, cameras=None, *, settings: RenderSettings | None = None, progress=False, checkpoint=None,
    checkpoint_interval_s=DEFAULT_CHECKPOINT_INTERVAL_S, keep_checkpoint=False, stop=None,
    executor="local", address=None, workers=None, sensor=None, record=None, until_noise=None, **overrides,
) -> RenderResult:  # fmt: skip
    """Render the intensity, ground truth and D-ToF measurements of a dynamic scene.

    Parameters
    ----------
    scene : DynamicScene, from :func:`dopplertof.load_scene` (a file or dict) or
        :func:`dopplertof.scenes.build`.
    cameras : list of :class:`~dopplertof.Camera`, optional. Replaces the scene's. Cameras
        with different exposure windows (``exposure_start``, ``exposure``) form a capture
        schedule: each window is traced on its own, with its own random streams
        (:class:`RenderResult` says which maps refer to which window).
    settings : :class:`RenderSettings` or dict, optional. A RenderSettings: the settings
        to start from, replacing the scene's. A dict of setting names (``{"spp": 4}``):
        applied on top of the scene's own, as ``**overrides`` are. By default the scene's
        own (:func:`dopplertof.settings.scene_layer`: its ``<integrator>`` cameras and
        settings, its sampler's ``sample_count``, its sensor's shutter). Anything else is
        a TypeError.
    **overrides
        Any :class:`RenderSettings` field (``spp``, ``seed``, ``max_depth``,
        ``time_sampling``, ``correlation``, …), applied on top.
    progress : bool. Show a progress bar (a bool: ``"no"`` is a ValueError).
    checkpoint : path, optional. Continue from this checkpoint if it exists (same
        settings, else ValueError; its passes, where they hold at most ``lanes_per_pass``
        lanes, not this render's pass size); save the sums there while rendering (see
        ``checkpoint_interval_s``) and if the render stops early; remove it when the render
        is complete (unless ``keep_checkpoint``).
    checkpoint_interval_s : float, seconds, default 60. With ``checkpoint``: a save follows
        the first pass that ends at least this long after the previous save (0: every
        pass), so a killed process loses at most this much rendering (plus a pass).
    keep_checkpoint : bool, default False. With ``checkpoint``: also save the sums of a
        complete render and leave them, for a caller that removes the checkpoint once the
        result is safely written (resuming a complete checkpoint renders nothing). Where
        this last save (or an interrupted render's) cannot be written (a full disk), the
        result is returned all the same, with a warning and ``info["checkpoint_error"]``.
    stop : callable, optional. Called before every pass; when it returns True the render
        stops there and returns what the finished passes hold: ``result.interrupted`` is
        True and ``result.spp`` the paths per pixel done, 0 (every estimate NaN, nothing
        checkpointed) where it stopped before the first pass. A stop never raises.
    executor : ``"local"`` (default) or ``"ray"``. ``"ray"`` traces the passes on Ray
        workers (:mod:`dopplertof.render_ray`), each rebuilding the scene from its file or
        built-in name (a scene loaded from a dict cannot be: ValueError), and adds them here
        in pass order: the result is bit-identical to the local render's.
    address : str, optional. With ``"ray"``: the cluster (``ray.init(address=…)``); default
        the running Ray, else a new local one.
    workers : int, optional. With ``"ray"``: workers, each with the cluster's CPUs / workers
        Dr.Jit threads (default one per CPU; with a ``cuda_*`` variant, one per GPU).
    sensor : :class:`dopplertof.Sensor`, optional. Render its raw frames (instead of
        ``cameras``): the measurements are those of ``sensor.cameras()`` and the result's
        ``raw`` (frames, taps, H, W) the noiseless electrons of every frame and tap
        (:mod:`dopplertof.sensors.frames`); ``sensor.read_out(result, seed=)`` adds the noise.
    record : True, dict or :class:`dopplertof.design.RecordSpec`, optional. Also keep the
        scene's response record of every exposure window (``result.record``), from which
        :func:`dopplertof.design.evaluate` reads out any sensor in its band
        (:mod:`dopplertof.design.record`). Rendered locally; a ``checkpoint`` holds its
        sums beside the render's (not for the paired correlations, which record through
        several renders of probe cameras). A render stopped early has no record (None: its
        checkpoint continues it), and a Ctrl-C while a record's further frequencies are
        traced again, after the render's passes, raises KeyboardInterrupt.
    until_noise : float, optional. With ``sensor``: stop a window's passes once the Monte
        Carlo standard error of its raw frames is at most this many times the sensor's own
        noise in 95 % of its pixels (:mod:`dopplertof.design.convergence`); ``spp`` is
        then the most it may take, ``result.spp`` what it took and ``result.info["until_noise"]``
        the ratio reached and the spp of each window, and the (spp, ratio) after each pass.
        A pass then holds at most spp / ``replicates`` samples of each pixel (one replicate;
        with stratified times a few strata), ``lanes_per_pass`` lowered to it where larger
        (as ``result.settings`` says), so that the ratio is checked as the render goes.

    Returns
    -------
    RenderResult

    Raises
    ------
    KeyboardInterrupt
        Only a Ctrl-C (SIGINT) that leaves nothing to return: before the first pass
        finished, or half-way through adding a pass with no checkpoint to fall back to;
        otherwise the render returns the finished passes as for ``stop``.
    CheckpointWriteError
        A checkpoint could not be written (full disk, ...): the render stops there; the
        message says which earlier checkpoint is kept.

    Examples
    --------
    >>> import math, dopplertof as dt
    >>> scene = dt.scenes.cornell_box(resolution=16)
    >>> cameras = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    >>> result = dt.render(scene, cameras=cameras, spp=16, max_depth=3)
    >>> result.measurements.shape, result.intensity.shape, result.velocity.shape
    ((4, 16, 16), (16, 16, 3), (16, 16))
    """
    import time

    from .backend import ensure_variant
    from .tracing.lanes import window_seed

    ensure_variant()
    if not hasattr(scene, "static"):
        from .loader import loaded_scene_hint

        given = "; give it to dopplertof.load_scene first" if isinstance(scene, (dict, str, os.PathLike)) else loaded_scene_hint(scene)
        raise ValueError(f"render() takes a scene from dopplertof.load_scene(...) or dopplertof.scenes.build(...), got {type(scene).__name__}{given}")
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    if executor != "ray" and (address is not None or workers is not None):
        raise ValueError("address and workers apply to executor='ray'")
    progress = checked("progress", progress, "bool")
    if stop is not None and not callable(stop):
        raise TypeError(f"stop must be a callable returning True to stop, got {stop!r}")
    if sensor is not None:
        from .sensors import Sensor

        if not isinstance(sensor, Sensor):
            raise ValueError(f"sensor must be a dopplertof.Sensor, got {sensor!r}")
        if cameras is not None or "cameras" in overrides:
            raise ValueError("give cameras or sensor, not both (a sensor's raw frames are its cameras)")
        cameras = sensor.cameras()
    checkpoint_interval_s = checked_checkpoint_interval(checkpoint_interval_s)
    if checkpoint is not None:
        _check_checkpoint_path(checkpoint)
    keep_checkpoint = checked("keep_checkpoint", keep_checkpoint, "bool")
    callers_cameras = cameras is not None and sensor is None
    if cameras is not None:
        overrides["cameras"] = cameras
    if isinstance(settings, RenderSettings):
        layers = [{f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}]
    elif settings is None or isinstance(settings, dict):
        layers = [scene_layer(scene), settings or {}]
    else:
        raise TypeError(f"settings must be a dopplertof.RenderSettings or a dict of setting names, got {type(settings).__name__}")
    settings = RenderSettings.build(*layers, overrides)
    if callers_cameras:
        warn_outside_the_shutter(scene, settings)
    resumed_lanes = None if checkpoint is None else _checkpoint_lanes_per_pass(checkpoint, settings)
    asked_lanes = settings.lanes_per_pass
    if until_noise is not None:
        until_noise = checked_until_noise(until_noise)
        if sensor is None:
            raise ValueError(f"until_noise={until_noise!r}: needs a sensor (sensor=...)")
        # The ratio is checked after each pass: a pass of a large share of the render (on a
        # small film, one pass may hold all of it) would check too late to save anything.
        # (No smaller than the setting allows: a tiny film checks after a few spp.)
        pass_lanes = max(math.prod(scene.resolution) * max(settings.group_size, settings.spp // settings.replicates),
                         FIELDS["lanes_per_pass"].metadata["minimum"])
        settings = dataclasses.replace(settings, lanes_per_pass=min(settings.lanes_per_pass, pass_lanes))
    if resumed_lanes is not None:
        if resumed_lanes != asked_lanes:  # (the result depends on the passes; until_noise's own smaller passes are not asked for)
            warnings.warn(f"resuming {os.fspath(checkpoint)!r} in its own passes of {resumed_lanes} lanes, not {asked_lanes}", stacklevel=2)
        settings = dataclasses.replace(settings, lanes_per_pass=resumed_lanes)
    if record is not None and record is not False:
        from .design.record import as_spec, by_probes, first_grid
        from .design.record import check_memory as check_record_memory

        record = as_spec(record)
        if executor != "local":
            raise ValueError("record: a response record is rendered locally (executor='local')")
        if checkpoint is not None and by_probes(settings):
            raise ValueError(f"record: a response record of the {settings.correlation!r} correlation is rendered as several renders of probe cameras, without a checkpoint (checkpoint=None)")
        check_record_memory(record, *scene.resolution, len(settings.windows), by_probes(settings))
        grid = first_grid(record, settings)  # the render's own passes accumulate it
    else:
        record = grid = None

    width, height = scene.resolution
    n_pixels = width * height
    windows = settings.windows
    check_film_memory(width, height, len(settings.cameras), len(windows))
    warn_if_long(width, height, settings.spp, len(windows))
    # Each window traces its cameras over its own times, with its own random streams.
    window_settings = [
        dataclasses.replace(settings, cameras=w.cameras, exposure_start=w.start_s, seed=window_seed(settings.seed, k)) for k, w in enumerate(windows)
    ]  # fmt: skip
    key = None if checkpoint is None else fingerprint(scene, settings, record)  # only a checkpoint is matched against it

    def saved_sums():
        """The sums of the checkpoint, else zeros."""
        accs = [Accumulator(n_pixels, *Reducer.layout(ws), record_channels=0 if grid is None else grid.channels) for ws in window_settings]
        if checkpoint is not None and os.path.exists(checkpoint):
            _load_checkpoint(checkpoint, accs, key)
        return accs

    accs = saved_sums()
    passes = schedule(n_pixels, settings.spp, settings.group_size, settings.lanes_per_pass)

    def passes_done():
        return [int(acc.state["passes_done"][0]) for acc in accs]

    saved = sum(passes_done()) if checkpoint is not None and os.path.exists(checkpoint) else None
    last_save_s = time.monotonic()

    def save(due: bool):
        """Save the sums if they changed since the last save (and, unless ``due``, the interval passed)."""
        nonlocal saved, last_save_s
        done = sum(passes_done())
        if checkpoint is None or done == saved or not (due or time.monotonic() - last_save_s >= checkpoint_interval_s):
            return
        with signals_held():  # a signal is delivered once the checkpoint is whole
            _save_or_explain(checkpoint, accs, key, len(passes) * len(windows))
        saved, last_save_s = done, time.monotonic()

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(passes) * len(windows), initial=sum(passes_done()), unit="pass", desc="render", leave=False)
    interrupted = False
    reached = {}  # window index -> [(spp, until_noise ratio reached)] after each pass
    start = time.perf_counter()
    try:
        for index, (acc, done) in enumerate(zip(accs, passes_done())):
            if interrupted:
                break
            if done == len(passes):
                continue
            if executor == "ray":
                from .render_ray import traced_on_ray

                traced = traced_on_ray(scene, window_settings[index], passes[done:], address=address, workers=workers)
            else:
                traced = _traced_locally(scene, window_settings[index], passes[done:], grid)
            try:
                for p in passes[done:]:
                    if stop is not None and stop():
                        interrupted = True
                        break
                    acc.apply(p, next(traced))
                    if bar is not None:
                        bar.update(1)
                    save(due=False)
                    if until_noise is not None:
                        value = _noise_ratio_reached(acc, windows[index], sensor, (height, width))
                        if value is not None:
                            reached.setdefault(index, []).append((int(acc.state["samples"].min()), value))
                            if value <= until_noise:
                                break
            finally:
                traced.close()  # a Ray render's workers stop here
    except KeyboardInterrupt:
        interrupted = True
        if any(acc.applying for acc in accs):  # stopped at once while adding a pass: back to the last checkpoint
            accs = saved_sums()
        if sum(passes_done()) == 0:
            raise  # a Ctrl-C with nothing to return
    finally:
        if bar is not None:
            bar.close()
    done = sum(passes_done())
    checkpoint_error = None
    if done and (interrupted or keep_checkpoint):
        try:
            save(due=True)
        except CheckpointWriteError as exc:  # (a full disk) the sums in hand are returned all the same
            checkpoint_error = str(exc)
            warnings.warn(f"{exc}; the result is returned without it", stacklevel=2)
    elif checkpoint is not None and os.path.exists(checkpoint):
        os.remove(checkpoint)
    window_spp = [int(acc.state["samples"].min()) for acc in accs]  # a stopped schedule's windows differ
    spp_done = min(window_spp)
    info = {"render_seconds": time.perf_counter() - start, "passes": len(passes) * len(windows), "passes_done": done,
            "executor": executor, "windows": [[w.start_s, w.exposure_s] for w in windows], "window_spp": window_spp,
            "light_sources_in_motion": scene.light_sources_in_motion()}  # fmt: skip
    if checkpoint_error is not None:
        info["checkpoint_error"] = checkpoint_error
    if until_noise is not None:
        info["until_noise"] = {"ratio": until_noise, "reached": [reached[k][-1][1] if k in reached else float("inf") for k in range(len(windows))],
                               "spp": window_spp, "history": [reached.get(k, []) for k in range(len(windows))]}  # fmt: skip
    # finish consumes the sums: what the record needs of each window is taken first
    recorded = [(acc.state.get("record_sum"), acc.state["samples"].copy(), int(acc.state["passes_done"][0])) for acc in accs]
    finished = [acc.finish(height, width, len(w.cameras)) for w, acc in zip(windows, accs)]
    # A stratified render stopped before its last stratum (interrupted, or by until_noise):
    # its errors leave out the spread between the strata it did not draw (at h = 1,
    # 100-300x the error it states).
    incomplete = settings.stratified and spp_done < settings.spp
    info["stderr_dof"] = 0 if incomplete else min(acc.stderr_dof for acc in accs)
    maps = _merge_windows(finished, windows, len(settings.cameras), (height, width))
    if sensor is not None:
        maps["raw"] = sensor.raw(maps["measurements"])
    result = RenderResult(maps=maps, settings=settings, spp=spp_done, interrupted=interrupted, info=info, sensor=sensor)
    if record is not None and not interrupted:  # an interrupted render returns what it has, without a record
        from .design.record import record_scene

        result.record = record_scene(scene, settings, record, (window_settings, recorded, passes, maps))
    return result

