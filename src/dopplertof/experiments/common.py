"""What the experiments share: the scene, estimators, the reference cache, metrics and CSV.

A *reference* is a high-spp render with the best estimator (antithetic times, replayed
paths). It is stored in a cache folder under a key that hashes everything that determines
its pixels: the scene (built-in name and builder arguments, or the XML file's bytes), the
film size, the cameras, spp, seed, every render setting, the Mitsuba variant, the package
version and a hash of the package's rendering source files (:func:`rendering_source_digest`:
the renderer changes between versions too). A rerun with the same key loads it instead of
rendering it again.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from .. import __version__
from ..io import NPZ_READ_ERRORS
from ..modulation import Camera
from ..outputs import OUTPUTS
from ..render import RenderResult, render
from ..settings import FIELDS, RenderSettings
from ..timesampling import stratifies

CACHE_ENV_VAR = "DOPPLERTOF_CACHE"
N_TIMES = 2
"""Correlated times per group for every estimator (an antithetic pair). Uniform and
stratified sampling also draw pairs, so that the correlation mode means the same thing for
all of them: the second path of a pair replays the first at an independent time."""

DEFAULT_MAX_DEPTH = FIELDS["max_depth"].default
"""Path depth when the scene gives none: the render default."""

SWEEP_CAMERA_LANES = 1 << 27
"""Lanes × cameras per pass of a sweep's renders: every camera keeps a per-lane sum, so a
render of many cameras (220 for four waveforms × 11 h × 5 ψ) at the default 2 M lanes per
pass took 3.4× as long and 2.5× the memory as at 0.5 M (64², 512 spp, measured)."""

SWEEP_REPLICATES = 2
"""Replicates per pixel of the sweeps' renders whose times are not stratified (uniform, or
no further stratification): only the image-average standard error (``stderr_rms``) is
used. Stratified renders (:func:`dopplertof.timesampling.stratifies`) stratify over all
of a pixel's groups whatever this is, and take their standard errors from the strata
(:func:`timed_render` passes it only to the others)."""

_DEFAULT_SHIFT = {"antithetic": 0.5, "antithetic_mirror": 0.0}
"""The original scripts' antithetic shift per method (a = T/2, and the plain mirror 1 − t)."""

Echo = Callable[[str], None]


# ------------------------------------------------------------------------------------ scene


_SCENE_RENDER_SETTINGS = ("rr_depth", "hide_emitters", "exposure_start")
"""Render settings a scene's ``<integrator>`` may fix that the experiments keep as they are."""


@dataclass(frozen=True)
class ExperimentScene:
    """A loaded scene with its name for files and its identity for the reference cache.

    Attributes
    ----------
    label : str
        Short name for output folders and CSV rows (built-in name or file stem).
    scene : DynamicScene
        The loaded scene (:class:`~dopplertof.scene.DynamicScene`).
    identity : dict
        JSON-able description hashed into the cache key.
    base_camera : Camera
        Camera whose modulation settings every experiment camera inherits (from the
        scene's ``<integrator type="dopplertofpath">``, else :class:`Camera` defaults with
        the exposure of the sensor's shutter: :func:`~dopplertof.settings.scene_camera`).
    max_depth : int or None
        Path depth from the scene's integrator; None where it gives none (the commands
        then use :data:`DEFAULT_MAX_DEPTH` or their protocol's).
    render_settings : dict
        ``rr_depth``, ``hide_emitters``, ``exposure_start`` (s) where the scene's
        integrator gives them; passed to every render.
    """

    label: str
    scene: object
    identity: dict
    base_camera: Camera
    max_depth: int | None
    render_settings: dict


def open_scene(scene_arg: str, resolution: int | None) -> ExperimentScene:
    """Load a built-in scene by name or a Mitsuba XML file, as ``dopplertof render`` does.

    Parameters
    ----------
    scene_arg : str
        A built-in scene name (:data:`dopplertof.scenes.SCENES`) or the path of a Mitsuba
        XML file.
    resolution : int or None
        Film size in pixels (square); replaces a file's film size too. None: the scene's.

    Returns
    -------
    ExperimentScene

    Raises
    ------
    ValueError
        An unknown scene or a missing file.
    SceneError
        Bad ``<integrator>`` parameters or a bad scene file.
    """
    from .. import scenes
    from ..settings import scene_camera, scene_layer

    dyn = scenes.open_scene(scene_arg, resolution)
    width, height = dyn.resolution
    if scene_arg in scenes.SCENES:
        identity = {"builtin": scene_arg, "kwargs": {"resolution": resolution}}
        label = scene_arg
    else:
        identity = {"file_sha256": hashlib.sha256(Path(scene_arg).read_bytes()).hexdigest()}
        label = Path(scene_arg).stem
    identity["film"] = [width, height]
    settings = scene_layer(dyn, scene_arg)
    base = scene_camera(settings)
    max_depth = settings.get("max_depth")
    kept = {k: settings[k] for k in _SCENE_RENDER_SETTINGS if k in settings}
    return ExperimentScene(label, dyn, identity, base, max_depth, kept)


def camera_grid(base: Camera, h_values: Sequence[float], phases_rad: Sequence[float]) -> list[Camera]:
    """One camera per (h, ψ), h-major: ``cams[i * len(phases) + j]`` has h_i and ψ_j.

    Parameters
    ----------
    base : Camera
        The camera every other parameter comes from.
    h_values : sequence of float
        Heterodyne ratios h (beat cycles per exposure).
    phases_rad : sequence of float
        Phase offsets ψ (rad).

    Returns
    -------
    list of Camera
        ``len(h_values) * len(phases_rad)`` cameras.
    """
    return [dataclasses.replace(base, heterodyne=float(h), phase=float(p)) for h in h_values for p in phases_rad]


# ------------------------------------------------------------------------------- estimators


@dataclass(frozen=True)
class Estimator:
    """A time sampling and a correlation mode; the shift defaults to the method's usual one,
    per-interval stratification (``stratify_intervals``) to the render default (on).

    Parameters
    ----------
    time_sampling : str
        A :class:`~dopplertof.RenderSettings` ``time_sampling`` (``uniform``,
        ``stratified``, ``antithetic``, ``antithetic_mirror``).
    correlation : str
        A :class:`~dopplertof.RenderSettings` ``correlation`` mode (``none``, ``pixel``,
        ``replay``, ``reconnection``, ``adaptive``).
    shift : float or None, units of T, default None
        The antithetic shift in [0, 1]; None: 0.5 (0 for ``antithetic_mirror``).
    stratify_intervals : bool or None, default None
        Stratify each time interval; None: the render default (on).

    Raises
    ------
    ValueError
        An unknown method or mode, or a shift outside [0, 1].
    """

    time_sampling: str
    correlation: str
    shift: float | None = None
    stratify_intervals: bool | None = None

    def __post_init__(self):
        self.render_settings()  # validates the names and the shift now, not after a long render

    @property
    def antithetic_shift(self) -> float:
        """The antithetic shift in units of T: ``shift`` if given, else the original scripts'
        default for the time sampling (0.5; 0 for ``antithetic_mirror``)."""
        return self.shift if self.shift is not None else _DEFAULT_SHIFT.get(self.time_sampling, 0.5)

    @property
    def shift_label(self):
        """The shift (units of T) for the antithetic methods, "" for those that ignore it."""
        return self.antithetic_shift if self.time_sampling in _DEFAULT_SHIFT else ""

    @property
    def stratified(self) -> bool:
        """Whether the times are stratified over the pixel's groups: the setting resolved, for
        a time sampling that has strata (:func:`~dopplertof.timesampling.stratifies`; uniform
        and analytic times have none)."""
        return stratifies(self.time_sampling, FIELDS["stratify_intervals"].default if self.stratify_intervals is None else self.stratify_intervals)

    @property
    def label(self) -> str:
        """``time_sampling/correlation`` (and ``/no further stratification`` where a time
        sampling with strata has them off), the estimator's name in tables and plots."""
        off = self.stratify_intervals is False and stratifies(self.time_sampling, True)
        return f"{self.time_sampling}/{self.correlation}" + ("/no further stratification" if off else "")

    def render_settings(self) -> dict:
        """Render settings (:class:`~dopplertof.settings.RenderSettings` fields) of this estimator.

        Returns
        -------
        dict

        Raises
        ------
        ValueError
            An unknown method or mode, or a shift outside [0, 1].
        """
        settings = {"time_sampling": self.time_sampling, "n_times": N_TIMES, "correlation": self.correlation}
        if self.time_sampling in _DEFAULT_SHIFT:
            settings["antithetic_shift"] = self.antithetic_shift
        if self.stratify_intervals is not None:
            settings["stratify_intervals"] = self.stratify_intervals
        RenderSettings.build(settings)  # validates the combination now
        return settings


REFERENCE_ESTIMATOR = Estimator("antithetic", "replay")


def sweep_lanes_per_pass(n_cameras: int) -> int:
    """Lanes per pass of a render of ``n_cameras`` cameras (:data:`SWEEP_CAMERA_LANES`).

    Parameters
    ----------
    n_cameras : int
        Cameras of the render.

    Returns
    -------
    int
        Between 2¹⁶ and the render default.
    """
    return max(1 << 16, min(FIELDS["lanes_per_pass"].default, SWEEP_CAMERA_LANES // max(n_cameras, 1)))


def reference_seed(seed: int) -> int:
    """The reference's seed: never the seed of the renders it judges.

    Parameters
    ----------
    seed : int
        The seed of the renders judged, in [0, 2³²).

    Returns
    -------
    int
        ``seed + 1`` modulo 2³².
    """
    return (seed + 1) % (1 << 32)


def check_spp(name: str, spp: int) -> int:
    """spp must be a positive multiple of the :data:`N_TIMES` paths of a group.

    Parameters
    ----------
    name : str
        The option or parameter named in the error.
    spp : int
        Samples per pixel.

    Returns
    -------
    int
        ``spp``, unchanged.

    Raises
    ------
    ValueError
        ``spp`` is not an int, not positive or not a multiple of :data:`N_TIMES`.
    """
    if isinstance(spp, bool) or not isinstance(spp, int) or spp <= 0 or spp % N_TIMES:
        raise ValueError(f"{name} must be a positive multiple of {N_TIMES} (paths of an antithetic pair), got {spp!r}")
    return spp


def timed_render(scene: ExperimentScene, cameras, estimator: Estimator, spp: int, seed: int, max_depth: int, progress=False, replicates=None, lanes_per_pass=None,
                 checkpoint=None, **executor):  # fmt: skip
    """(RenderResult, wall seconds) of one render.

    Parameters
    ----------
    scene : ExperimentScene
    cameras : list of Camera
    estimator : Estimator
        Its time sampling and correlation mode.
    spp : int
        Samples per pixel.
    seed : int
        Seed of the replayable random numbers, in [0, 2³²).
    max_depth : int
        Path depth.
    progress : bool, default False
        Show a progress bar.
    replicates, lanes_per_pass : int or None, default None
        The render's (None: the render default); ``replicates`` only where the estimator's
        times are not stratified (the others take their errors from their strata).
    checkpoint : str or Path or None, default None
        The render's checkpoint (:func:`~dopplertof.render.render`): an interrupted render
        keeps its passes there, and the next call continues them.
    **executor
        :func:`~dopplertof.render.render`'s ``executor``, ``address``, ``workers``.

    Returns
    -------
    tuple of (RenderResult, float)
        The result and the wall time in seconds.

    Raises
    ------
    KeyboardInterrupt
        The render was interrupted.
    """
    start = time.perf_counter()
    if estimator.stratified:
        replicates = None  # stratified times take their standard errors from their strata
    given = {"replicates": replicates, "lanes_per_pass": lanes_per_pass, "checkpoint": None if checkpoint is None else str(checkpoint)}
    extra = {k: v for k, v in given.items() if v is not None}
    result = render(
        scene.scene, cameras=cameras, spp=spp, seed=seed, max_depth=max_depth, progress=progress,
        **scene.render_settings, **estimator.render_settings(), **extra, **executor,
    )  # fmt: skip
    if result.interrupted:
        raise KeyboardInterrupt
    return result, time.perf_counter() - start


# ---------------------------------------------------------------------------------- cache


PACKAGE_DIR = Path(__file__).resolve().parent.parent
"""The ``dopplertof`` package folder."""

_NOT_RENDERING = {"cli.py", "clitools.py", "folder.py", "animate.py", "render_folder.py", "viz.py", "io.py", "sensor.py"}
"""Package modules that only read, post-process or show renders; with the ``experiments``
and ``reconstruct`` subpackages they cannot change a render's pixels. Everything else
(integrator, render, scene, motion, modulation, time sampling, correlation, loader, scenes,
and any new module) can."""
_NOT_RENDERING_PACKAGES = {"experiments", "reconstruct"}


def rendering_source_files(package_dir: Path = PACKAGE_DIR) -> list[Path]:
    """The package's ``*.py`` files that can change a render, sorted by relative path.

    Parameters
    ----------
    package_dir : path, default :data:`PACKAGE_DIR`
        The ``dopplertof`` package folder.

    Returns
    -------
    list of Path
    """
    package_dir = Path(package_dir)
    relative = {path: path.relative_to(package_dir) for path in package_dir.rglob("*.py")}
    kept = [path for path, rel in relative.items() if rel.as_posix() not in _NOT_RENDERING and rel.parts[0] not in _NOT_RENDERING_PACKAGES]
    return sorted(kept, key=lambda path: relative[path].as_posix())


def rendering_source_digest(package_dir: Path = PACKAGE_DIR) -> str:
    """SHA-256 (hex) over the relative paths and bytes of :func:`rendering_source_files`.

    Parameters
    ----------
    package_dir : path, default :data:`PACKAGE_DIR`
        The ``dopplertof`` package folder.

    Returns
    -------
    str
        64 hex digits.
    """
    digest = hashlib.sha256()
    for path in rendering_source_files(package_dir):
        name = path.relative_to(package_dir).as_posix().encode()
        content = path.read_bytes()
        # lengths first: no two file sets hash the same concatenation
        digest.update(b"%d:%s%d:" % (len(name), name, len(content)))
        digest.update(content)
    return digest.hexdigest()


def default_cache_dir() -> Path:
    """``$DOPPLERTOF_CACHE``, else ``$XDG_CACHE_HOME/dopplertof/references`` (``~/.cache``).

    Returns
    -------
    Path
    """
    if os.environ.get(CACHE_ENV_VAR):
        return Path(os.environ[CACHE_ENV_VAR])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "dopplertof" / "references"


_ARRAY_FIELDS = tuple(name for o in OUTPUTS for name in (o.name, o.stderr_name) if name)
_OPTIONAL_ARRAY_FIELDS = ("measurement_covariance",)  # 2 to MAX_COVARIANCE_CAMERAS cameras; older caches lack it


class ReferenceCache:
    """Reference renders stored as ``<key>.npz`` in ``folder`` (created on first store).

    Parameters
    ----------
    folder : str or path
        The cache folder.
    executor : dict or None, default None
        How a reference missing from the cache is rendered, as
        :func:`~dopplertof.render.render`'s ``executor``, ``address``, ``workers`` (e.g.
        ``{"executor": "ray"}``); the key leaves it out, the pixels being the same.
    """

    def __init__(self, folder, executor: dict | None = None):
        self.folder = Path(folder)
        self.executor = dict(executor or {})

    @staticmethod
    def key(scene: ExperimentScene, cameras, spp: int, seed: int, max_depth: int, estimator: Estimator, replicates=None) -> str:
        """SHA-256 of everything that determines the reference's pixels.

        Parameters
        ----------
        scene : ExperimentScene
        cameras : list of Camera
        spp : int
            Samples per pixel.
        seed : int
            Seed, in [0, 2³²).
        max_depth : int
            Path depth.
        estimator : Estimator
        replicates : int or None, default None
            Replicates per pixel (None: the render default).

        Returns
        -------
        str
            64 hex digits.
        """
        import mitsuba as mi

        settings = estimator.render_settings()
        description = {
            "scene": scene.identity,
            "cameras": [dataclasses.asdict(c) for c in cameras],
            "spp": spp,
            "seed": seed,
            "max_depth": max_depth,
            "replicates": replicates,
            "scene_settings": scene.render_settings,
            "estimator": settings,
            "variant": mi.variant(),
            "version": __version__,
            "source": rendering_source_digest(),
        }
        return hashlib.sha256(json.dumps(description, sort_keys=True).encode()).hexdigest()

    def path(self, key: str, checkpoint: bool = False) -> Path:
        """The cache file of the reference with cache key ``key``: ``<folder>/<key>.npz``;
        with ``checkpoint``, where it keeps its passes while it renders
        (``<folder>/<key>.checkpoint.npz``: an interrupted reference continues from it).

        Parameters
        ----------
        key : str
            A cache key (:meth:`key`).
        checkpoint : bool, default False
            The checkpoint's path, not the reference's.

        Returns
        -------
        Path
        """
        return self.folder / f"{key}{'.checkpoint' if checkpoint else ''}.npz"

    def load(self, key: str, cameras) -> RenderResult | None:
        """The cached render, or None if there is none (or it cannot be read).

        Parameters
        ----------
        key : str
            A cache key (:meth:`key`).
        cameras : list of Camera
            The cameras the reference was rendered with (the file keeps only their images).

        Returns
        -------
        RenderResult or None
        """
        try:
            with np.load(self.path(key), allow_pickle=False) as data:
                meta = json.loads(str(data["meta"]))
                arrays = {name: data[name] for name in _ARRAY_FIELDS}
                arrays.update({name: data[name] for name in _OPTIONAL_ARRAY_FIELDS if name in data.files})
        except NPZ_READ_ERRORS:  # a truncated or damaged file is rendered again
            return None
        settings = RenderSettings.build({**meta["settings"], "cameras": list(cameras)})
        info = {"stderr_dof": meta["stderr_dof"]} if "stderr_dof" in meta else {}
        return RenderResult(maps=arrays, settings=settings, spp=meta["spp"], info=info)

    def store(self, key: str, result: RenderResult) -> Path:
        """Write atomically, so that an interrupted write never leaves a readable bad file.

        Parameters
        ----------
        key : str
            A cache key (:meth:`key`).
        result : RenderResult
            The reference render.

        Returns
        -------
        Path
            The cache file written.
        """
        self.folder.mkdir(parents=True, exist_ok=True)
        final = self.path(key)
        partial = final.with_name(f"{key}.{os.getpid()}.partial.npz")
        meta = json.dumps({"spp": result.spp, "settings": result.settings.as_dict(), **{k: result.info[k] for k in ("stderr_dof",) if k in result.info}})
        arrays = {name: getattr(result, name) for name in _ARRAY_FIELDS}
        arrays.update({name: result.maps[name] for name in _OPTIONAL_ARRAY_FIELDS if name in result.maps})
        np.savez_compressed(partial, meta=np.array(meta), **arrays)
        os.replace(partial, final)
        return final


def reference_render(scene: ExperimentScene, cameras, spp: int, seed: int, max_depth: int, cache: ReferenceCache, echo: Echo, replicates=None, lanes_per_pass=None) -> RenderResult:
    """The high-spp reference of ``cameras``: from the cache, else rendered and stored.

    Parameters
    ----------
    scene : ExperimentScene
    cameras : list of Camera
    spp : int
        Samples per pixel of the reference.
    seed : int
        The seed of the renders it judges (the reference uses :func:`reference_seed`).
    max_depth : int
        Path depth.
    cache : ReferenceCache
    echo : callable
        Called with one line of progress text.
    replicates, lanes_per_pass : int or None, default None
        As for :func:`timed_render`; the pass split does not change the pixels, so the
        cache key leaves it out.

    Returns
    -------
    RenderResult

    Raises
    ------
    KeyboardInterrupt
        The reference render was interrupted; its passes are kept in the cache
        (:meth:`ReferenceCache.path`), and the next call continues them.
    """
    seed = reference_seed(seed)
    key = cache.key(scene, cameras, spp, seed, max_depth, REFERENCE_ESTIMATOR, replicates)
    cached = cache.load(key, cameras)
    if cached is not None:
        echo(f"reference: loaded from cache {cache.path(key)}")
        return cached
    checkpoint = cache.path(key, checkpoint=True)
    resumed = " (continuing its checkpoint)" if checkpoint.is_file() else ""
    echo(f"reference: rendering {REFERENCE_ESTIMATOR.label} at {spp} spp (seed {seed}){resumed} ...")
    cache.folder.mkdir(parents=True, exist_ok=True)
    result, seconds = timed_render(
        scene, cameras, REFERENCE_ESTIMATOR, spp, seed, max_depth, progress=sys.stderr.isatty(), replicates=replicates, lanes_per_pass=lanes_per_pass,
        checkpoint=checkpoint, **cache.executor,
    )  # fmt: skip
    path = cache.store(key, result)
    echo(f"reference: rendered in {seconds:.1f} s, cached as {path}")
    return result


# -------------------------------------------------------------------------------- metrics


def image_errors(image: np.ndarray, reference: np.ndarray) -> dict:
    """Error of an image against a reference, as the original ``main_plot.py`` computed it.

    Parameters
    ----------
    image, reference : array_like, same shape

    Returns
    -------
    dict
        ``mae``, ``rmse`` (units of the images), ``relative_mae`` and ``relative_rmse``
        (divided by mean |reference|; NaN if the reference is zero everywhere) and ``psnr_db``
        (data range max − min of the reference; +inf for an exact match).
    """
    image = np.asarray(image, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    difference = image - reference
    mae = float(np.mean(np.abs(difference)))
    rmse = float(np.sqrt(np.mean(difference * difference)))
    scale = float(np.mean(np.abs(reference)))
    data_range = float(np.max(reference) - np.min(reference))
    with np.errstate(divide="ignore", invalid="ignore"):
        return {
            "mae": mae,
            "rmse": rmse,
            "relative_mae": mae / scale if scale > 0 else math.nan,
            "relative_rmse": rmse / scale if scale > 0 else math.nan,
            "psnr_db": float(20.0 * np.log10(data_range / rmse)) if rmse > 0 else math.inf,
        }


def rms(values: np.ndarray) -> float:
    """Root mean square, e.g. of a standard-error image (the RMSE that noise alone gives).

    Parameters
    ----------
    values : array_like

    Returns
    -------
    float
    """
    values = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.mean(values * values)))


# ------------------------------------------------------------------------------------ CSV


def write_csv(path: Path, rows: list[dict], columns: Sequence[str]) -> Path:
    """Rows as CSV with a header; floats with 9 significant digits.

    Parameters
    ----------
    path : Path
        The file written (its folder is created).
    rows : list of dict
        One dict per row, holding every column.
    columns : sequence of str
        The header, in order.

    Returns
    -------
    Path
        ``path``.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([f"{row[c]:.9g}" if isinstance(row[c], float) else row[c] for c in columns])
    return path


def mean_over(rows: list[dict], group_by: Sequence[str], metrics: Sequence[str]) -> list[dict]:
    """Rows averaged over everything not in ``group_by``: ``<metric>_mean`` and ``<metric>_std``.

    Groups keep the order of their first row. Infinite values (an exact PSNR) stay infinite.

    Parameters
    ----------
    rows : list of dict
    group_by : sequence of str
        The columns that identify a group.
    metrics : sequence of str
        The columns averaged.

    Returns
    -------
    list of dict
        One row per group: the ``group_by`` columns, ``count``, and ``<metric>_mean`` and
        ``<metric>_std`` (the std NaN where a value is not finite).
    """
    groups: dict[tuple, list[dict]] = {}
    for row in rows:
        groups.setdefault(tuple(row[g] for g in group_by), []).append(row)
    summary = []
    for key, members in groups.items():
        out = dict(zip(group_by, key))
        out["count"] = len(members)
        for metric in metrics:
            values = np.array([m[metric] for m in members], dtype=np.float64)
            with np.errstate(invalid="ignore"):
                out[f"{metric}_mean"] = float(np.mean(values))
                out[f"{metric}_std"] = float(np.std(values)) if np.all(np.isfinite(values)) else math.nan
        summary.append(out)
    return summary
