"""A render's output folder: checked before rendering, written atomically, metadata last.

=====================  ==================================================================
file                   content
=====================  ==================================================================
``<output>.exr``       one float32 EXR per output of :data:`dopplertof.outputs.OUTPUTS`
                       (and ``stderr.exr``); per camera ``measurement_<i>_h<h>_psi<deg>deg``
                       ``.exr`` with its ``_stderr.exr``
``*.png``              previews (diverging colour maps with a symmetric range for signed
                       images)
``measurement_``       the covariance of the cameras' means (n, n, H, W), 2 to 8 cameras
``covariance.npy``
``checkpoint.npz``     the Float64 sums of an interrupted render (``--resume`` continues)
``raw_electrons.npy``  with a sensor (``--sensor``): its raw frames' taps (frames, taps, H,
                       W), e⁻ before noise (NaN in windows an interrupted render has not
                       traced); ``raw_dn.npy`` the same read out (DN, seeded with the
                       render's seed), once every frame has samples; ``metadata.json``
                       keeps the sensor and the schedule of its frames (``"sensor"``)
``metadata.json``      written last: scene, film, settings, cameras, spp done and asked,
                       versions, variant, device, render time, command line, the files
                       and their SHA-256 (``reconstruct`` refuses a file changed since)
=====================  ==================================================================

Every file is written under a temporary name and renamed (:func:`dopplertof.io.atomic_path`),
so a fault never leaves a partial file under a file's name; the temporary files a killed
process leaves are removed when the folder is next prepared. A folder holding another
render's files is refused unless ``overwrite``, which removes exactly the files that
render's ``metadata.json`` (or checkpoint) names and nothing else.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import sys
import tempfile

import numpy as np

from .outputs import OUTPUTS

METADATA = "metadata.json"
RAW_ELECTRONS = "raw_electrons.npy"  # a sensor's frames: (frames, taps, H, W) e⁻ before noise
RAW_DN = "raw_dn.npy"  # the same read out (noise chain, seed = the render's), DN
CHECKPOINT = "checkpoint.npz"
# Files by which output_kind knows the other commands' folders. They are kept here, below
# the commands that write them, which take the names from here: this module imports none
# of them.
ANIMATION_SETTINGS = "animation.json"  # dopplertof animate: the clip's settings
DESIGN_OUTPUTS = ("record.npz", "sweep.csv", "optimize.csv", "best_sensor.toml", "velocity_crb.exr", "depth_crb.exr", "velocity_rmse.exr")
RECONSTRUCTION_SUMMARY = "reconstruction.json"  # dopplertof reconstruct, in a render's folder
_PREVIEWS = {"intensity": "save_intensity_png", "signed": "save_signed_png", "velocity": "save_velocity_png"}


def measurement_stem(index: int, camera) -> str:
    """The file stem of camera ``index``'s measurement in a render folder, e.g.
    ``measurement_2_h1_psi90deg`` (ψ in degrees).

    Parameters
    ----------
    index : int
        The camera's position in the render's cameras, from 0.
    camera : Camera
        Its ``heterodyne`` and ``phase`` (rad) name the file.

    Returns
    -------
    str
    """
    return f"measurement_{index}_h{camera.heterodyne:g}_psi{math.degrees(camera.phase):g}deg"


def _reconstruction_files(folder: str) -> list[str]:
    """The files of a reconstruction of the render in ``folder`` (its
    ``reconstruction.json`` lists them): stale once the render changes."""
    try:
        with open(os.path.join(folder, RECONSTRUCTION_SUMMARY), encoding="utf-8") as f:
            return [*json.load(f).get("files", []), RECONSTRUCTION_SUMMARY]
    except (OSError, ValueError):
        return []


def _remove_files(folder: str, names) -> None:
    """Remove the files ``names`` of ``folder`` (only files directly in it)."""
    for name in names:
        path = os.path.join(folder, name)
        if os.path.isfile(path) and os.path.dirname(os.path.abspath(path)) == folder:
            os.remove(path)


def _owned_files(folder: str) -> list[str]:
    """The files of the render in ``folder`` (from its metadata), checkpoint and
    reconstruction included."""
    files = []
    if os.path.isfile(os.path.join(folder, METADATA)):
        files = [*(read_metadata(folder) or {}).get("files", []), METADATA]
    files += _reconstruction_files(folder)
    if os.path.isfile(os.path.join(folder, CHECKPOINT)):
        files.append(CHECKPOINT)
    return files


OUTPUT_KINDS = {  # what each command leaves in its output folder, as its messages name it
    "render": "a render",
    "experiment": "an experiment's tables",
    "dataset": "a dataset",
    "animation": "an animation",
    "design": "a design study",
}


def output_kind(folder: str) -> str | None:
    """Which command's output ``folder`` holds (a key of :data:`OUTPUT_KINDS`), known by a
    file only that command writes; None for an empty, missing or foreign folder.

    Parameters
    ----------
    folder : str

    Returns
    -------
    str or None
    """
    from .dataset.shards import MANIFEST

    if not os.path.isdir(folder):
        return None
    names = set(os.listdir(folder))
    if MANIFEST in names:
        return "dataset"
    if ANIMATION_SETTINGS in names or any(name.startswith("frame_") and os.path.isdir(os.path.join(folder, name)) for name in names):
        return "animation"
    if names & set(DESIGN_OUTPUTS) or any(re.fullmatch(r"record(_\d+)?(\.checkpoint)?\.npz", name) for name in names):  # record_<i>: one per scene
        return "design"
    if METADATA in names:
        return "experiment" if "experiment" in (read_metadata(folder) or {}) else "render"
    return "render" if CHECKPOINT in names else None


def refuse_other_output(folder: str, own: str) -> None:
    """ValueError where ``folder`` holds another command's output than ``own`` (a key of
    :data:`OUTPUT_KINDS`): the two would mix, and one command's ``--overwrite`` would not
    know the other's files. Each command decides itself what to do with its own kind.

    Parameters
    ----------
    folder : str
    own : str

    Raises
    ------
    ValueError
        Naming the folder and what it holds.
    """
    kind = output_kind(folder)
    if kind is not None and kind != own:
        raise ValueError(f"output folder {folder!r} holds {OUTPUT_KINDS[kind]}; {OUTPUT_KINDS[own]} would mix with it: use another folder")


def check_writable(folder: str, bytes_needed: int = 0) -> str:
    """Create ``folder`` and make sure files can be written there; its absolute path.

    ValueError for a path that is a file or lies under one, a folder that cannot be
    written (read-only, no permission) and one without ``bytes_needed`` free bytes.

    Parameters
    ----------
    folder : str
        The folder (created with its parents).
    bytes_needed : int, bytes, default 0
        Free space the folder's file system must have.

    Returns
    -------
    str
        The absolute path.

    Raises
    ------
    ValueError
        As above, naming the folder.
    """
    parts = os.path.abspath(folder)
    probe = parts
    while probe and not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if os.path.exists(parts) and not os.path.isdir(parts):
        raise ValueError(f"output {folder!r} exists and is not a folder")
    if probe != parts and not os.path.isdir(probe):
        raise ValueError(f"output {folder!r} lies under {probe!r}, which is a file")
    created = not os.path.exists(parts)
    try:
        os.makedirs(parts, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=parts, prefix=".write-test-"):
            pass
    except OSError as exc:
        raise ValueError(f"output folder {folder!r} is not writable ({exc.strerror or exc})") from None
    free = shutil.disk_usage(parts).free
    if bytes_needed and free < bytes_needed:
        if created:
            os.rmdir(parts)  # a refused command leaves no empty folder behind
        raise ValueError(f"output folder {folder!r} has {free / 1e6:.1f} MB free; this render writes about {bytes_needed / 1e6:.1f} MB")
    return parts


def prepare(folder: str, *, overwrite: bool = False, resume: bool = False, bytes_needed: int = 0, hold=None) -> None:
    """Check (and create) a render's output folder before any rendering; ValueError if
    unusable (:func:`check_writable`) or holding another render (its ``metadata.json``
    or checkpoint), unless ``overwrite`` (which removes that render's files) or
    ``resume`` (which continues its checkpoint).

    Parameters
    ----------
    folder : str
        The output folder.
    overwrite : bool, default False
        Remove another render's files (only those) found there.
    resume : bool, default False
        Continue the checkpoint found there.
    bytes_needed : int, bytes, default 0
        Free space the render's files need.
    hold : contextlib.ExitStack, optional
        Takes the folder's hold (:func:`held`) as soon as the folder exists, before
        anything in it is removed (another process's half-written files, or with
        ``overwrite`` its render); it lasts until the stack is closed.

    Raises
    ------
    ValueError
        An unusable folder, one another process holds, or one holding another render
        (without ``overwrite`` or ``resume``).
    """
    from .io import remove_stale_partials

    refuse_other_output(folder, "render")
    parts = check_writable(folder, bytes_needed)
    if hold is not None:
        hold.enter_context(held(parts))
    remove_stale_partials(parts)  # a killed render's half-written files: no one's data
    owned = _owned_files(parts)
    if not owned:
        return
    if resume and os.path.isfile(os.path.join(parts, CHECKPOINT)):
        _remove_files(parts, _reconstruction_files(parts))  # a reconstruction of the part rendered so far
        return
    if not overwrite:
        if CHECKPOINT in owned and METADATA not in owned:
            what = "an interrupted render (continue it with --resume)"
        elif resume and (read_metadata(parts) or {}).get("interrupted") is True:
            what = "an interrupted render whose checkpoint is gone (nothing to resume from)"
        elif resume:
            what = "a finished render (nothing to resume: its checkpoint goes when a render completes)"
        else:
            what = "another render's files"
        raise ValueError(f"output folder {folder!r} holds {what}; use --overwrite (overwrite=True) to replace them, or another folder")
    _remove_files(parts, owned)


def read_metadata(folder: str) -> dict | None:
    """The ``metadata.json`` of ``folder`` as a dict; None where there is none, or it is
    not a JSON object.

    Parameters
    ----------
    folder : str

    Returns
    -------
    dict or None
    """
    try:
        with open(os.path.join(folder, METADATA), encoding="utf-8") as f:
            metadata = json.load(f)
    except (OSError, ValueError):
        return None
    return metadata if isinstance(metadata, dict) else None


LOCK = ".dopplertof.lock"


@contextlib.contextmanager
def held(folder: str):
    """Hold ``folder`` for one command while it writes there: a second process that asks
    for it meanwhile gets a ValueError (two renders into one folder both reported success
    and left files of each). An exclusive ``flock`` on ``DIR/.dopplertof.lock``, which the
    kernel releases when the process ends, however it ends; a no-op where flock is
    unavailable.

    Parameters
    ----------
    folder : str
        An existing folder.

    Raises
    ------
    ValueError
        Another process holds it.
    """
    try:
        import fcntl
    except ImportError:  # not POSIX
        yield
        return
    path = os.path.join(folder, LOCK)
    with open(path, "a+b") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ValueError(f"output folder {folder!r} is being written by another dopplertof process; wait for it to finish, or choose another folder") from None
        try:
            yield
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.remove(path)  # before the lock goes, so the next holder makes its own


def estimated_bytes(width: int, height: int, n_cameras: int) -> int:
    """About what :func:`write_result` writes (EXR float32 before compression, PNGs).

    Parameters
    ----------
    width, height : int
        Film size in pixels.
    n_cameras : int
        Cameras rendered.

    Returns
    -------
    int
        Bytes.
    """
    channels = 3 + 3 + 2 * n_cameras + 1 + 1 + 1 + 3 + 2 + 1 + 1
    return width * height * (channels * 4 + (3 + n_cameras + 1) * 3) + (1 << 16)


def write_result(result, folder: str, metadata: dict | None = None) -> list[str]:
    """Write a :class:`~dopplertof.render.RenderResult` (module table); returns the paths.

    ``metadata`` (scene, command line, …) is merged into ``metadata.json``, which is
    written last and lists the files.

    Parameters
    ----------
    result : RenderResult
    folder : str
        The output folder (prepared by :func:`prepare`).
    metadata : dict or None, default None
        Extra JSON-able entries of ``metadata.json``.

    Returns
    -------
    list of str
        The paths written.

    Raises
    ------
    OSError
        A file could not be written (a full disk, …); the files written before stay.
    """
    from . import io, viz

    written: list[str] = []

    def path(name):
        written.append(name)
        return os.path.join(folder, name)

    for o in OUTPUTS:
        if o.channels == "cameras":
            for i, cam in enumerate(result.cameras):
                stem = measurement_stem(i, cam)
                io.write_exr(path(f"{stem}.exr"), result.measurements[i])
                io.write_exr(path(f"{stem}_stderr.exr"), result.measurement_stderr[i])
                viz.save_signed_png(path(f"{stem}.png"), result.measurements[i], colorbar=True, title=cam.label())
            if "measurement_covariance" in result.maps:
                io.write_npy(path("measurement_covariance.npy"), result.measurement_covariance)
            continue
        image = getattr(result, o.name)
        channels = [f"{o.name}.{c}" for c in o.components] if o.components else None
        io.write_exr(path(f"{o.name}.exr"), image.astype(np.float32), channels)
        if o.stderr_name:
            io.write_exr(path(f"{o.stderr_name}.exr"), getattr(result, o.stderr_name))
        if o.preview in _PREVIEWS:
            getattr(viz, _PREVIEWS[o.preview])(path(f"{o.name}.png"), image)
    sensor = getattr(result, "sensor", None)
    if sensor is not None:  # dopplertof.sensors: the raw frames' electrons and digital numbers
        from .sensors.files import sensor_record

        io.write_npy(path(RAW_ELECTRONS), result.raw)
        complete = bool(np.isfinite(result.raw).all())  # an interrupted schedule: later windows empty
        if complete:
            io.write_npy(path(RAW_DN), sensor.read_out(result, seed=result.seed))
        metadata = {**(metadata or {}), "sensor": {**sensor_record(sensor, result.cameras[: len(sensor.frames)]), "readout_seed": result.seed if complete else None}}
    meta = {
        **(metadata or {}),
        "spp": result.spp,
        "spp_requested": result.settings.spp,
        "seed": result.seed,
        "interrupted": result.interrupted,
        "settings": result.settings.as_dict(),
        "cameras": [c.as_dict() for c in result.cameras],
        "render": result.info,
        "versions": versions(),
        "files": written + ([CHECKPOINT] if result.interrupted and os.path.isfile(os.path.join(folder, CHECKPOINT)) else []),
        # what reading the folder checks its files against: a changed or damaged file is not read as data
        "sha256": {name: io.sha256_file(os.path.join(folder, name)) for name in written},
    }
    io.write_json(os.path.join(folder, METADATA), meta)
    return [os.path.join(folder, name) for name in written + [METADATA]]


def save(result, folder, *, overwrite: bool = False) -> list[str]:
    """Write a :class:`~dopplertof.render.RenderResult` rendered from Python into ``folder``
    as ``dopplertof render`` writes its output folder (:func:`prepare`, then
    :func:`write_result` while the folder is held), which ``dopplertof reconstruct FOLDER``
    and the other commands then read.

    Parameters
    ----------
    result : RenderResult
    folder : str or path
        The output folder (created if needed).
    overwrite : bool, default False
        Replace another render's files found there (only those).

    Returns
    -------
    list of str
        The paths written.

    Raises
    ------
    ValueError
        An unusable folder, one another process holds, or one holding another render
        (without ``overwrite``).
    OSError
        A file could not be written (a full disk, …); the files written before stay.
    """
    folder = os.fspath(folder)
    height, width = result.maps["coverage"].shape
    with contextlib.ExitStack() as hold:
        prepare(folder, overwrite=overwrite, bytes_needed=estimated_bytes(width, height, len(result.cameras)), hold=hold)
        return write_result(result, folder)


def versions() -> dict:
    """Package, Mitsuba and Dr.Jit versions, the variant and the device.

    Returns
    -------
    dict
    """
    import drjit as dr
    import mitsuba as mi

    from . import __version__

    variant = mi.variant()
    device = "cpu (LLVM)"
    if variant and variant.startswith("cuda"):
        device = "cuda"
    return {"dopplertof": __version__, "mitsuba": mi.__version__, "drjit": dr.__version__, "numpy": np.__version__, "python": sys.version.split()[0], "variant": variant, "device": device}
