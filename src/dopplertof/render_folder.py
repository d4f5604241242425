"""Velocity from a ``dopplertof render`` output folder, and the ``dopplertof reconstruct`` command.

A render folder holds ``metadata.json`` (its ``cameras``), one
``measurement_<i>_h<h>_psi<deg>deg.exr`` per camera and, from the renderer, the
ground-truth ``velocity.exr``. :func:`reconstruct_folder` reads them, reconstructs the
radial velocity (and the depth where the camera set determines it) with
:func:`dopplertof.reconstruct.velocity`, and writes next to them:

================================  ============================================================
file                              content
================================  ============================================================
``velocity_reconstructed.exr``    radial velocity, m/s, positive receding; NaN where invalid
``velocity_reconstructed.png``    the same with a colourbar
``velocity_valid.png``            mask: white where the velocity was determined
``depth_reconstructed.exr/.png``  distance at mid-exposure, m (only where the set determines it),
                                  modulo c/(2 f_g), or c/(2 |f_1 − f_2|) at two frequencies
``velocity_stderr.exr``           propagated standard error of the velocity, m/s (valid pixels)
``depth_wrapped.png``             mask: white where the true depth (``depth.exr``) is beyond
                                  the unambiguous range c/(2 f_g), so the depth read is wrapped
``velocity_comparison.png``       ground truth next to the reconstruction, one colour range
``velocity_error.json``           error of the reconstruction on its valid pixels, m/s, and
                                  the fraction off by more than 3 standard errors
``reconstruction.json``           method, the validity threshold (m/s) and why, the error
                                  model, the depth range c/(2 f_g) and, against the ground
                                  truth, the fraction of wrapped depths
================================  ============================================================

Cameras that determine depth but not velocity (homodyne only: an AMCW sensor's frames) give
``depth_reconstructed.exr/.png``, ``depth_wrapped.png`` and ``reconstruction.json`` (which
says why there is no velocity) alone.

Validity. A pixel is valid when the estimator determines its velocity and the standard
error propagated from the render's per-camera errors and ``measurement_covariance.npy``
is at most ``max_velocity_stderr`` (m/s; default a tenth of the scene's speed scale, or
0.01 m/s where too few pixels move detectably for one,
:func:`dopplertof.reconstruct.default_max_velocity_stderr`). That error is Monte Carlo only:
multipath (global illumination, silhouettes) biases a pixel beyond it.

Reconstruction method
---------------------
``method=None`` (the default) is ``"auto"`` of :func:`dopplertof.reconstruct.velocity`:
the per-pixel fit for sinusoidal cameras, which estimates the radiance change during the
exposure with the velocity (a box moving 1.5 cm closer in the Cornell box brightens by
≈ 0.5 %, 1/d²), else the homodyne/heterodyne ratio of balanced pairs, blind to that change
to first order (see :mod:`dopplertof.reconstruct`).
"""

from __future__ import annotations

import glob
import json
import math
import os

import click
import numpy as np

from . import io, viz
from .clitools import fail
from . import reconstruct as rc
from .reconstruct.frequencies import beat_range_m
from .modulation import Camera
from .folder import METADATA, RECONSTRUCTION_SUMMARY
from .outputs import MOVING_PIXEL_M_S

METADATA_FILE = METADATA
ERROR_FILE = "velocity_error.json"
SUMMARY_FILE = RECONSTRUCTION_SUMMARY


def resolve_method(cameras, method: str | None = None) -> str:
    """The reconstruction method for ``cameras``, checked before any rendering.

    Parameters
    ----------
    cameras : sequence of :class:`Camera`
    method : {None, "auto", "ratio", "fit"}
        None is ``"auto"`` (module docstring).

    Returns
    -------
    str
        ``"ratio"`` or ``"fit"``: the method :func:`dopplertof.reconstruct.velocity` uses.

    Raises
    ------
    ValueError
        If the camera set cannot determine velocity with that method (cameras that differ
        in f_g or T, only homodyne cameras, too few measurements, unpaired cameras for
        ``"ratio"``, a non-sinusoidal waveform for ``"fit"``); the message says why.
    """
    cameras = list(cameras)
    if not cameras:
        raise ValueError("no cameras: velocity reconstruction needs D-ToF measurements (e.g. h=0 and h=1 at psi=0 and 90deg)")
    # The estimators check the camera set before they look at the data: zeros find every
    # set that cannot work without spending a render on it.
    with np.errstate(all="ignore"):
        return rc.velocity(np.zeros((len(cameras), 1, 1)), cameras, method=method or "auto").method


def reconstruct(measurements, cameras, method: str | None = None, stderr=None, covariance=None,
                max_velocity_stderr: float | None = None, stderr_dof: int | None = None) -> rc.VelocityResult:
    """:func:`dopplertof.reconstruct.velocity` with the default method of this module.

    Parameters
    ----------
    measurements : array_like, shape (n_cameras, H, W)
    cameras : sequence of n_cameras :class:`Camera`
    method : {None, "auto", "ratio", "fit"}, see :func:`resolve_method`
    stderr, covariance : the measurements' standard errors (n_cameras, H, W) and covariance
        (n_cameras, n_cameras, H, W), optional: propagated to velocity_stderr / depth_stderr
    max_velocity_stderr : float, optional
        Validity threshold on the velocity's standard error, m/s (default: derived from the
        scene, :func:`dopplertof.reconstruct.default_max_velocity_stderr`).
    stderr_dof : int, optional
        Degrees of freedom of ``stderr`` (the render's ``info["stderr_dof"]``); fewer than
        :data:`dopplertof.reconstruct.MIN_STDERR_DOF`: no pixel valid.
    """
    method = resolve_method(cameras, method)
    with np.errstate(all="ignore"):  # invalid pixels come back as NaN with valid == False
        return rc.velocity(measurements, cameras, method=method, measurement_stderr=stderr, measurement_covariance=covariance,
                           max_velocity_stderr=max_velocity_stderr, stderr_dof=stderr_dof)


ERROR_MODEL = "standard errors are Monte Carlo only; multipath bias (global illumination, silhouettes) is not included"


def summary(reconstruction: rc.VelocityResult, depth_truth_m=None) -> dict:
    """What a reconstruction assumed and decided, for ``reconstruction.json`` and the
    command's summary line: method, validity threshold (m/s) and its reason, the error
    model, the unambiguous depth range (m) and, given the true depth (m, NaN where nothing
    is hit), the fraction of the hit pixels whose depth is wrapped (:func:`depth_wrapped`)."""
    info = {
        "method": reconstruction.method,
        "max_velocity_stderr_m_s": reconstruction.max_velocity_stderr_m_s,
        "threshold_reason": reconstruction.threshold_reason,
        "error_model": ERROR_MODEL if reconstruction.velocity_stderr is not None else "no standard errors",
        "depth_range_m": reconstruction.depth_range_m,
        "modulation_frequencies_hz": list(reconstruction.frequencies_hz),
        "valid_fraction_of_image": float(np.mean(reconstruction.valid)),
        "stderr_dof": reconstruction.stderr_dof,
    }
    if depth_truth_m is not None:
        info["depth_wrapped_fraction"] = _wrapped_fraction(depth_truth_m, reconstruction.depth_range_m)
    return info


def errors_from(dof: int) -> str:
    """"its standard errors come from N degree(s) of freedom": why no pixel can be valid
    below :data:`dopplertof.reconstruct.MIN_STDERR_DOF` (``reconstruct``, ``animate``)."""
    return f"its standard errors come from {dof} degree{'' if dof == 1 else 's'} of freedom"


def describe_summary(info: dict) -> str:
    """One line for :func:`summary` (and the ground-truth checks, when present)."""
    parts = []
    dof = info.get("stderr_dof")
    if dof == 0:
        parts.append("no pixel can be valid: the render stopped early, and with stratified times its standard errors leave out "
                     "the spread between the strata it did not draw (resume it to complete them)")
    elif dof is not None and dof < rc.MIN_STDERR_DOF:
        parts.append(f"no pixel can be valid: {errors_from(dof)}, and a valid pixel "
                     f"needs {rc.MIN_STDERR_DOF} (render more paths per pixel: one degree per two groups of correlated times, spp/4 for antithetic "
                     "times; replicates − 1 where the times are not stratified)")
    if info["max_velocity_stderr_m_s"] is not None:
        parts.append(f"valid where the velocity's standard error ≤ {info['max_velocity_stderr_m_s']:.3g} m/s "
                     f"({info['threshold_reason']}); {info['error_model']}")
    else:
        parts.append(info["threshold_reason"])
    if "off_by_3_stderr_fraction" in info and math.isfinite(info["off_by_3_stderr_fraction"]):
        moving = info.get("off_by_3_stderr_fraction_moving", math.nan)
        of_moving = f" ({100 * moving:.1f}% of those that move)" if math.isfinite(moving) else ""
        parts.append(f"{100 * info['off_by_3_stderr_fraction']:.1f}% of valid pixels are off by > 3 standard errors{of_moving}")
    formula = "c/(2 f_g)" if len(info["modulation_frequencies_hz"]) < 2 else "c/(2 |f_1 − f_2|), two frequencies"
    depth = f"depth modulo {info['depth_range_m']:.4g} m ({formula})"
    if "depth_wrapped_fraction" in info:
        depth += f", wrapped on {100 * info['depth_wrapped_fraction']:.1f}% of the pixels that hit a surface (ground truth)"
    parts.append(depth)
    return "; ".join(parts)


def velocity_error(reconstruction: rc.VelocityResult, ground_truth_m_s, note: str | None = None) -> dict:
    """Error of a reconstructed velocity map against ground truth, on its valid pixels.

    Parameters
    ----------
    reconstruction : VelocityResult
    ground_truth_m_s : array_like, shape (H, W)
        Ground-truth radial velocity, m/s; NaN where the camera ray hits nothing.
    note : str, optional
        Why the comparison measures no error (:func:`ground_truth_note`), kept as ``note``.

    Returns
    -------
    dict
        ``valid_fraction`` (of the pixels with ground truth), ``n_valid``, and over those
        pixels ``median_abs_error_m_s``, ``mean_abs_error_m_s``, ``rmse_m_s`` and
        ``off_by_3_stderr_fraction`` (|error| > 3 ``velocity_stderr``), also over the valid
        pixels that move (|truth| > :data:`dopplertof.outputs.MOVING_PIXEL_M_S`: static walls whose velocity is
        exactly 0 would dilute it), ``off_by_3_stderr_fraction_moving`` (NaN when no pixel is
        valid, or without standard errors).
    """
    truth = np.asarray(ground_truth_m_s, dtype=np.float64)
    seen = np.isfinite(truth)
    valid = reconstruction.valid & seen
    error = reconstruction.velocity[valid] - truth[valid]
    n_seen = int(seen.sum())

    def stat(f):
        return float(f(error)) if error.size else math.nan

    sigma = reconstruction.velocity_stderr
    off = np.abs(error) > 3.0 * sigma[valid] if sigma is not None else np.zeros(0)
    off_moving = off[np.abs(truth[valid]) > MOVING_PIXEL_M_S] if off.size else off
    out = {
        "valid_fraction": float(valid.sum() / n_seen) if n_seen else 0.0,
        # the calibration of velocity_stderr: ≈ 0.3 % for Gaussian errors where the model holds
        "off_by_3_stderr_fraction": float(off.mean()) if off.size else math.nan,
        "off_by_3_stderr_fraction_moving": float(off_moving.mean()) if off_moving.size else math.nan,
        "n_valid": int(valid.sum()),
        "median_abs_error_m_s": stat(lambda e: np.median(np.abs(e))),
        "mean_abs_error_m_s": stat(lambda e: np.mean(np.abs(e))),
        "rmse_m_s": stat(lambda e: np.sqrt(np.mean(e * e))),
    }
    if note is not None:
        out["note"] = note
    return out


def describe_error(error: dict) -> str:
    """One line for :func:`velocity_error`'s result."""
    if not error["n_valid"]:
        return "no valid pixel"
    note = f" (not an error: {error['note']})" if "note" in error else ""
    return (
        f"velocity error on {100 * error['valid_fraction']:.0f}% valid pixels: "
        f"median {error['median_abs_error_m_s']:.3g} m/s, RMSE {error['rmse_m_s']:.3g} m/s{note}"
    )


def write_reconstruction(folder: str, reconstruction: rc.VelocityResult, ground_truth_m_s=None,
                         vmax_m_s: float | None = None, depth_truth_m=None, ground_truth_note: str | None = None) -> list[str]:
    """Write the files of the module table into ``folder``; returns their paths.

    ``ground_truth_m_s`` (H, W, m/s) adds the comparison figure and ``velocity_error.json``;
    ``depth_truth_m`` (H, W, m; NaN where nothing is hit) adds ``depth_wrapped.png``;
    ``ground_truth_note`` (:func:`ground_truth_note`) goes into ``velocity_error.json``;
    ``vmax_m_s`` fixes the colour range of the velocity pictures (default:
    :func:`dopplertof.viz.auto_vmax` of the ground truth if given, else of the
    reconstruction).
    """
    os.makedirs(folder, exist_ok=True)
    written = []

    def path(name):
        written.append(os.path.join(folder, name))
        return written[-1]

    velocity = reconstruction.velocity.astype(np.float32)
    io.write_exr(path("velocity_reconstructed.exr"), velocity)
    if vmax_m_s is None:  # the true range when known: noisy outliers then saturate, not the boxes
        vmax_m_s = viz.auto_vmax(velocity if ground_truth_m_s is None else ground_truth_m_s)
    viz.save_velocity_png(path("velocity_reconstructed.png"), velocity, vmax=vmax_m_s,
                          title=f"reconstructed ({reconstruction.method})")
    viz.save_png(path("velocity_valid.png"), np.where(reconstruction.valid, 255, 0).astype(np.uint8))
    for name in ("velocity_stderr", "depth_stderr"):
        error = getattr(reconstruction, name)
        if error is not None and np.isfinite(error).any():
            io.write_exr(path(f"{name}.exr"), error.astype(np.float32))
    if np.isfinite(reconstruction.depth).any():
        depth = reconstruction.depth.astype(np.float32)
        io.write_exr(path("depth_reconstructed.exr"), depth)
        viz.comparison_figure(path("depth_reconstructed.png"), {"reconstructed depth": depth}, signed=False, unit="m")
    if ground_truth_m_s is not None:
        viz.comparison_figure(
            path("velocity_comparison.png"),
            {"ground truth": ground_truth_m_s, f"reconstructed ({reconstruction.method})": velocity},
            vmax=vmax_m_s, unit="m/s", title="radial velocity",
        )
        io.write_json(path(ERROR_FILE), velocity_error(reconstruction, ground_truth_m_s, ground_truth_note))
    if depth_truth_m is not None:
        _write_wrapped(path("depth_wrapped.png"), depth_truth_m, reconstruction.depth_range_m)
    files = [os.path.basename(f) for f in written] + [SUMMARY_FILE]  # what a new render of the folder removes (folder.prepare)
    io.write_json(path(SUMMARY_FILE), {**summary(reconstruction, depth_truth_m), "files": files})
    return written


def write_depth(folder: str, depth_m, cameras, depth_truth_m=None, no_velocity: str = "") -> tuple[list[str], dict]:
    """Write the depth of cameras that give no velocity (``depth_reconstructed.exr/.png``,
    against the ground truth ``depth_wrapped.png``, and ``reconstruction.json``); (paths,
    the summary written)."""
    os.makedirs(folder, exist_ok=True)
    written = [os.path.join(folder, name) for name in ("depth_reconstructed.exr", "depth_reconstructed.png")]
    depth = np.asarray(depth_m, dtype=np.float32)
    io.write_exr(written[0], depth)
    viz.comparison_figure(written[1], {"reconstructed depth": depth}, signed=False, unit="m")
    frequencies = sorted({float(c.modulation_frequency) for c in cameras})
    ranges = [rc.ambiguity_range_m(f) for f in frequencies]
    depth_range_m = ranges[0] if len(ranges) == 1 else beat_range_m(*ranges)  # two frequencies: unwrapped (rc.depth)
    info = {"method": "depth only", "no_velocity": no_velocity, "depth_range_m": depth_range_m, "modulation_frequencies_hz": frequencies}
    if depth_truth_m is not None:
        info["depth_wrapped_fraction"] = _wrapped_fraction(depth_truth_m, depth_range_m)
        written.append(os.path.join(folder, "depth_wrapped.png"))
        _write_wrapped(written[-1], depth_truth_m, depth_range_m)
    written.append(os.path.join(folder, SUMMARY_FILE))
    io.write_json(written[-1], info)
    return written, info


def _wrapped_fraction(depth_truth_m, depth_range_m: float) -> float:
    """The fraction of the pixels that hit a surface whose depth is wrapped (:func:`depth_wrapped`)."""
    hit = np.isfinite(np.asarray(depth_truth_m, dtype=np.float64))
    return float(depth_wrapped(depth_truth_m, depth_range_m)[hit].mean()) if hit.any() else 0.0


def _write_wrapped(path: str, depth_truth_m, depth_range_m: float) -> None:
    """``depth_wrapped.png``: white where :func:`depth_wrapped`."""
    viz.save_png(path, np.where(depth_wrapped(depth_truth_m, depth_range_m), 255, 0).astype(np.uint8))


def depth_wrapped(depth_truth_m, depth_range_m: float) -> np.ndarray:
    """Where a true distance (m) is at least the unambiguous range c/(2 f_g): the depth read
    there is the distance minus a multiple of the range (a pixel that hits nothing, NaN, is not)."""
    truth = np.asarray(depth_truth_m, dtype=np.float64)
    return np.isfinite(truth) & (truth >= depth_range_m)


def _measurement_file(folder: str, index: int) -> str:
    # The file name also carries h and ψ as write_result formats them; the index is enough.
    found = [p for p in glob.glob(os.path.join(glob.escape(folder), f"measurement_{index}_h*.exr"))
             if not p.endswith("_stderr.exr")]
    if len(found) != 1:
        what = "no" if not found else f"{len(found)}"
        raise ValueError(f"{folder}: {what} measurement file for camera {index} (measurement_{index}_h*.exr)")
    return found[0]


def _check_unchanged(folder: str, metadata: dict) -> None:
    """ValueError naming the files of ``folder`` whose SHA-256 is not what the render
    recorded (``metadata.json``'s ``sha256``; a render older than it records none): random
    bytes in a measurement's EXR were read as measurements."""
    recorded = metadata.get("sha256")
    if not isinstance(recorded, dict):
        return
    changed = [name for name, digest in recorded.items() if os.path.isfile(os.path.join(folder, name)) and io.sha256_file(os.path.join(folder, name)) != digest]
    if changed:
        raise ValueError(f"{folder}: {', '.join(changed)} changed since the render wrote {'them' if len(changed) > 1 else 'it'} "
                         f"(SHA-256 in {METADATA_FILE}); render again, or restore {'them' if len(changed) > 1 else 'it'}")


def read_render_folder(folder: str):
    """Cameras, measurements and ground truth of a ``dopplertof render`` output folder.

    Returns
    -------
    cameras : list of :class:`Camera`
    measurements : ndarray, shape (n_cameras, H, W)
    ground_truth_m_s : ndarray, shape (H, W), or None when ``velocity.exr`` is absent
    stderr : ndarray, shape (n_cameras, H, W), or None (no ``*_stderr.exr``)
    covariance : ndarray, shape (n_cameras, n_cameras, H, W), or None (no
        ``measurement_covariance.npy``)

    Raises
    ------
    ValueError
        If ``folder`` is not a render folder, has no cameras, or its files are missing or
        inconsistent.
    """
    metadata_path = os.path.join(folder, METADATA_FILE)
    if not os.path.isdir(folder):
        raise ValueError(f"{folder}: no such folder")
    if not os.path.isfile(metadata_path):
        raise ValueError(f"{folder}: not a 'dopplertof render' output folder (no {METADATA_FILE})")
    try:
        metadata = io.read_json(metadata_path)
        cameras = [Camera(**c) for c in metadata.get("cameras", [])]
    except (TypeError, AttributeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{metadata_path}: cannot read its cameras ({exc})") from None
    except ValueError as exc:
        raise ValueError(f"{metadata_path}: {exc}") from None
    if isinstance(metadata.get("sensor"), dict) and "frame_cameras" in metadata["sensor"]:
        cameras = cameras[: metadata["sensor"]["frame_cameras"]]  # the rest measure a sensor's mean light
    if not cameras:
        raise ValueError(f"{folder}: the render has no D-ToF camera; render with e.g. --camera h=0,psi=0 --camera h=0,psi=90deg --camera h=1,psi=0 --camera h=1,psi=90deg")
    _check_unchanged(folder, metadata)
    images = [io.read_exr(_measurement_file(folder, i)) for i in range(len(cameras))]
    shapes = {m.shape for m in images}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise ValueError(f"{folder}: measurement images must be single-channel and of one size, got shapes {sorted(shapes)}")
    truth_path = os.path.join(folder, "velocity.exr")
    truth = io.read_exr(truth_path) if os.path.isfile(truth_path) else None
    if truth is not None and truth.shape != images[0].shape:
        raise ValueError(f"{truth_path}: shape {truth.shape} differs from the measurements' {images[0].shape}")
    stderr_paths = [_measurement_file(folder, i)[: -len(".exr")] + "_stderr.exr" for i in range(len(cameras))]
    covariance_path = os.path.join(folder, "measurement_covariance.npy")
    # The errors are all there or all absent (a render without them): a part would judge validity from the rest alone.
    written = set(metadata.get("files", ())) if isinstance(metadata.get("files"), list) else set()
    expected = [p for p in stderr_paths + [covariance_path] if os.path.basename(p) in written]
    if not written:
        expected = stderr_paths if any(os.path.isfile(p) for p in stderr_paths) else []
    missing = [os.path.basename(p) for p in expected if not os.path.isfile(p)]
    if missing:
        raise ValueError(f"{folder}: {', '.join(missing)} missing (the render wrote {'them' if len(missing) > 1 else 'it'}: the standard errors judge which pixels are valid); restore {'them' if len(missing) > 1 else 'it'} or render again")
    stderr = np.stack([io.read_exr(p) for p in stderr_paths]) if all(os.path.isfile(p) for p in stderr_paths) else None
    covariance = io.read_npy(covariance_path)[: len(cameras), : len(cameras)] if os.path.isfile(covariance_path) else None
    return cameras, np.stack(images), truth, stderr, covariance


def read_depth_truth(folder: str):
    """The render's ground-truth depth (m, NaN where nothing is hit: coverage 0), or None."""
    depth_path, coverage_path = (os.path.join(folder, f"{n}.exr") for n in ("depth", "coverage"))
    if not os.path.isfile(depth_path):
        return None
    depth = io.read_exr(depth_path).astype(np.float64)
    if os.path.isfile(coverage_path):
        depth = np.where(io.read_exr(coverage_path) > 0, depth, np.nan)
    return depth


def ground_truth_note(light_sources_in_motion: list) -> str | None:
    """Why the comparison with the ground truth is no error measure where light sources move
    (:meth:`~dopplertof.scene.DynamicScene.light_sources_in_motion`), else None."""
    if not light_sources_in_motion:
        return None
    return (f"the ground truth is the motion of the camera rays' hits, and light sources move here "
            f"({', '.join(light_sources_in_motion)}): the measured dL/dt also holds their motion (and a path straight from "
            f"a moving emitter is one-way, half a round trip), so the difference is not an error of the reconstruction")


def read_render_info(folder: str) -> tuple[int | None, list]:
    """What ``metadata.json``'s ``render`` says of the render's errors and lights: the
    degrees of freedom of its standard errors (``stderr_dof``) and its lights that move on
    their own and emitting moving bodies (``light_sources_in_motion``); None and [] where
    a render older than them does not say."""
    info = io.read_json(os.path.join(folder, METADATA_FILE)).get("render", {})
    dof, lights = info.get("stderr_dof"), info.get("light_sources_in_motion")
    return (dof if isinstance(dof, int) and not isinstance(dof, bool) else None), (lights if isinstance(lights, list) else [])


def reconstruct_folder(folder: str, output: str | None = None, method: str | None = None,
                       max_velocity_stderr: float | None = None):
    """Reconstruct the velocity of a render folder and write the maps.

    Parameters
    ----------
    folder : str
        A ``dopplertof render`` output folder.
    output : str, optional
        Where to write (default: ``folder``).
    method : {None, "auto", "ratio", "fit"}, see :func:`resolve_method`.
    max_velocity_stderr : float, optional. Validity threshold, m/s (see :func:`reconstruct`).

    Cameras that cannot give velocity but determine depth (homodyne at two phases or more:
    an AMCW sensor's frames) give the depth alone (:func:`write_depth`).

    Returns
    -------
    (VelocityResult, or None for depth alone; list of written paths; dict: :func:`summary`
    with, against the ground truth, :func:`velocity_error` and ``depth_wrapped_fraction``,
    or for depth alone ``no_velocity``, why, and the depth range)

    Raises
    ------
    ValueError
        ``folder`` is not a usable render folder, or ``output`` cannot be written (a file,
        under a file, read-only: :func:`dopplertof.folder.check_writable`), before any work.
    """
    from .folder import check_writable

    cameras, measurements, truth, stderr, covariance = read_render_folder(folder)
    check_writable(output or folder)
    depth_truth = read_depth_truth(folder)
    stderr_dof, light_sources_in_motion = read_render_info(folder)
    try:
        result = reconstruct(measurements, cameras, method, stderr, covariance, max_velocity_stderr, stderr_dof)
    except ValueError as no_velocity:
        try:
            depth_m = rc.depth(measurements, cameras)
        except ValueError:
            raise no_velocity from None
        written, info = write_depth(output or folder, depth_m, cameras, depth_truth, str(no_velocity))
        return None, written, info
    note = ground_truth_note(light_sources_in_motion)
    written = write_reconstruction(output or folder, result, truth, depth_truth_m=depth_truth, ground_truth_note=note)
    info = summary(result, depth_truth)
    if truth is not None:
        info.update(velocity_error(result, truth, note))
    return result, written, info


def parse_speed(text: str) -> float:
    """A speed in m/s from the command line: ``0.5`` or ``0.5m/s``; finite and > 0."""
    number = str(text).strip()
    number = number[: -len("m/s")].strip() if number.endswith("m/s") else number
    try:
        value = float(number)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"--max-velocity-stderr must be a speed > 0 in m/s (e.g. 0.5 or 0.5m/s), got {text!r}")
    return value


@click.command("reconstruct")
@click.argument("folder")
@click.option("-o", "--output", default=None, help="Output folder (default: FOLDER).")
@click.option("--method", type=click.Choice(["auto", "ratio", "fit"]), default=None,
              help="Estimator (default: auto, the fit for sinusoidal cameras, else the ratio).")
@click.option("--max-velocity-stderr", "max_velocity_stderr", default=None, metavar="M/S",
              help="Valid pixels: velocity standard error at most this, m/s (e.g. 0.5 or 0.5m/s; "
                   "default a tenth of the scene's speed scale, 0.01 where nothing moves detectably).")
def reconstruct_command(folder, output, method, max_velocity_stderr):
    """Reconstruct radial velocity (and depth) from the measurements in FOLDER, the output of 'dopplertof render'."""

    try:
        limit = None if max_velocity_stderr is None else parse_speed(max_velocity_stderr)
        result, written, info = reconstruct_folder(folder, output, method, limit)
    except (ValueError, FileNotFoundError) as exc:
        fail(str(exc))
    except OSError as exc:  # the disk filled, or the folder went away, while writing
        fail(f"cannot write {output or folder!r}: {exc.strerror or exc}")
    if result is None:
        click.echo(f"reconstructed the depth of {folder} (modulo {info['depth_range_m']:.4g} m) and no velocity: {info['no_velocity']}")
    else:
        error = f"; {describe_error(info)}" if "n_valid" in info else ""
        click.echo(f"reconstructed velocity ({result.method}) of {folder}{error}; {describe_summary(info)}")
    for path in written:
        click.echo(f"  {path}")
