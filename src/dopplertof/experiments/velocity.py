"""Reconstructed versus ground-truth radial velocity, with and without sensor noise.

Each estimator renders homodyne and heterodyne (h = 1) cameras at ψ = 0 and 90° (the
original ``main_animation.py``); :func:`dopplertof.reconstruct.velocity` turns them into a
velocity map (homodyne/heterodyne ratio, fused over both phases), which is compared with
the render's ground truth ``RenderResult.velocity`` on the moving pixels. The high-spp
reference goes through the same steps: its error is what the reconstruction model itself
leaves (multipath, changing attenuation), the floor under every estimator's.

With ``noise = sensor`` the measurements first go through :class:`dopplertof.sensor.
SensorModel` (shot, read and ADC noise of a 2-tap pixel). Its signal level is set by
``signal_electrons``: the photo-electrons (both taps together) that the 99th-percentile
brightest pixel of the reference collects in one exposure.

Writes ``results.csv`` (one row per estimator and noise setting), per estimator
``velocity_<name>.png`` (ground truth, reconstructed, reconstructed with sensor noise) and
``velocity_error_<name>.png`` (both errors), and ``metadata.json``.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Sequence

import numpy as np

from .. import io, reconstruct, viz
from ..outputs import MOVING_PIXEL_M_S
from ..reconstruct.errors import covariance_from_errors
from ..sensor import SensorModel, luminance
from .common import (
    REFERENCE_ESTIMATOR,
    Echo,
    Estimator,
    ExperimentScene,
    ReferenceCache,
    check_spp,
    reference_render,
    reference_seed,
    timed_render,
    write_csv,
)

DEFAULT_ESTIMATORS = (Estimator("uniform", "none"), Estimator("stratified", "replay"), Estimator("antithetic", "replay"))
"""The three heterodyne estimators of the original ``main_animation.py``."""

COLUMNS = (
    "scene", "estimator", "time_sampling", "correlation", "spp", "noise",
    "moving_pixels", "valid_fraction", "mae_m_s", "rmse_m_s", "bias_m_s", "median_abs_error_m_s",
    "relative_mae", "static_pixels", "static_rmse_m_s", "max_velocity_stderr_m_s",
)  # fmt: skip
"""Errors in m/s over the moving pixels where the reconstruction is valid: its standard error,
propagated from the render's and the sensor's, within ``max_velocity_stderr_m_s``, one
threshold for every row: the default of :func:`dopplertof.reconstruct.velocity` on the
noiseless reference (a tenth of the scene's speed scale; a noisy map gives none, and each
row's own default left the noisy estimators nothing valid to compare); ``valid_fraction``
of the moving pixels are; ``relative_mae`` = MAE / mean |ground
truth|; ``static_rmse_m_s``: the velocity reconstructed on valid static pixels (should be 0)."""


def velocity_cameras(base) -> list:
    """Homodyne and heterodyne (h = 1) at ψ = 0 and 90°, in matched pairs.

    Parameters
    ----------
    base : Camera
        The camera every other parameter comes from.

    Returns
    -------
    list of Camera
        Four cameras: (h = 0, ψ = 0), (h = 1, ψ = 0), (h = 0, ψ = 90°), (h = 1, ψ = 90°).
    """
    return [dataclasses.replace(base, heterodyne=h, phase=psi) for psi in (0.0, math.pi / 2) for h in (0.0, 1.0)]


def velocity_errors(estimate: np.ndarray, truth: np.ndarray) -> dict:
    """Error statistics of a velocity map against the ground truth.

    Parameters
    ----------
    estimate : ndarray, m/s
        Reconstructed radial velocity, NaN where there is no estimate.
    truth : ndarray, m/s, same shape
        Ground-truth radial velocity, NaN where unknown.

    Returns
    -------
    dict
        ``moving_pixels``, ``valid_fraction``, ``mae_m_s``, ``rmse_m_s``, ``bias_m_s``,
        ``median_abs_error_m_s``, ``relative_mae``, ``static_pixels``,
        ``static_rmse_m_s``. Statistics of an empty pixel set are NaN.
    """
    known = np.isfinite(truth)
    moving = known & (np.abs(truth) > MOVING_PIXEL_M_S)
    static = known & ~moving
    valid = moving & np.isfinite(estimate)
    error = (estimate - truth)[valid]
    static_estimate = estimate[static & np.isfinite(estimate)]

    def stat(fn, values):
        return float(fn(values)) if values.size else math.nan

    mae = stat(lambda e: np.mean(np.abs(e)), error)
    return {
        "moving_pixels": int(moving.sum()),
        "valid_fraction": float(valid.sum() / moving.sum()) if moving.any() else math.nan,
        "mae_m_s": mae,
        "rmse_m_s": stat(lambda e: np.sqrt(np.mean(e * e)), error),
        "bias_m_s": stat(np.mean, error),
        "median_abs_error_m_s": stat(lambda e: np.median(np.abs(e)), error),
        "relative_mae": mae / float(np.mean(np.abs(truth[valid]))) if error.size else math.nan,
        "static_pixels": int(static.sum()),
        "static_rmse_m_s": stat(lambda v: np.sqrt(np.mean(v * v)), static_estimate),
    }


def _luminance(intensity: np.ndarray) -> np.ndarray:
    return luminance(intensity) if intensity.ndim == 3 else np.asarray(intensity, dtype=np.float64)


def check_signal_electrons(signal_electrons: float) -> None:
    """Refuse a signal that is not a finite number > 0 (photo-electrons).

    Parameters
    ----------
    signal_electrons : float
    """
    if not (math.isfinite(signal_electrons) and signal_electrons > 0):
        raise ValueError(f"signal electrons must be a finite number > 0, got {signal_electrons!r}")


def sensor_for(reference, camera, signal_electrons: float) -> SensorModel:
    """A 2-tap sensor whose 99th-percentile pixel collects ``signal_electrons`` e⁻ per exposure.

    Read noise and ADC depth are :class:`SensorModel`'s defaults; above the default full
    well, the full well and the conversion gain grow with ``signal_electrons`` (same
    DN range), so that the signal level, not saturation, sets the noise.

    Parameters
    ----------
    reference : RenderResult
        The reference render whose intensity sets the brightness.
    camera : Camera
        Its exposure and g₀.
    signal_electrons : float, e⁻
        Finite, > 0.

    Returns
    -------
    SensorModel

    Raises
    ------
    ValueError
        ``signal_electrons`` is not a finite number > 0, or the reference is black.
    """
    check_signal_electrons(signal_electrons)
    bright = float(np.percentile(_luminance(reference.intensity), 99))
    if not bright > 0:
        raise ValueError("the reference image is black: no light reaches the camera, so there is no velocity to measure")
    default = SensorModel(electrons_per_unit=1.0)
    full_well = max(default.full_well_e, float(signal_electrons))
    return SensorModel(
        # both taps together collect κ T g0 I (dopplertof.sensor): solve for κ at I = bright
        electrons_per_unit=signal_electrons / (camera.exposure * camera.g0 * bright),
        full_well_e=full_well,
        gain_e_per_dn=default.gain_e_per_dn * full_well / default.full_well_e,
    )


def run_velocity(
    scene: ExperimentScene,
    folder,
    estimators: Sequence[Estimator],
    spp: int,
    reference_spp: int,
    seed: int,
    max_depth: int,
    signal_electrons: float,
    cache: ReferenceCache,
    echo: Echo,
) -> list[Path]:
    """Velocity maps and their errors for each estimator and the reference.

    Parameters
    ----------
    scene : ExperimentScene
    folder : str or path
        Output folder (created).
    estimators : sequence of Estimator
    spp : int
        Samples per pixel of each estimator's render (a multiple of :data:`N_TIMES`).
    reference_spp : int
        Samples per pixel of the reference (a multiple of :data:`N_TIMES`).
    seed : int
        Seed, in [0, 2³²).
    max_depth : int
        Path depth.
    signal_electrons : float, e⁻
        Signal of the brightest pixels in the sensor model (:func:`sensor_for`).
    cache : ReferenceCache
        Where the reference is looked up and stored.
    echo : callable
        Called with one line of progress text.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ValueError
        An spp that is not a positive multiple of :data:`N_TIMES`, or a bad
        ``signal_electrons``.
    """
    check_spp("spp", spp)
    check_spp("reference spp", reference_spp)
    check_signal_electrons(signal_electrons)
    folder = Path(folder)
    cameras = velocity_cameras(scene.base_camera)
    reference = reference_render(scene, cameras, reference_spp, seed, max_depth, cache, echo)
    sensor = sensor_for(reference, cameras[0], signal_electrons)
    runs = [("reference", REFERENCE_ESTIMATOR, reference)]
    for number, estimator in enumerate(estimators, 1):
        result, seconds = timed_render(scene, cameras, estimator, spp, seed, max_depth)
        echo(f"[{number}/{len(estimators)}] {estimator.label}: {seconds:.1f} s")
        runs.append((estimator.label.replace("/", "-"), estimator, result))

    rows, written, limit = [], [], None  # the reference's threshold, then every row's
    for name, estimator, result in runs:
        luma = _luminance(result.intensity)
        noisy = sensor.noisy_measurements(luma, result.measurements, cameras, seed=seed)
        # The render's covariance, plus the sensor's own noise (independent between cameras)
        # for the noisy measurements: the reconstruction marks as invalid what they cannot resolve.
        # (a cache older than the covariance gives the standard errors alone)
        covariance = covariance_from_errors(result.measurement_stderr, result.maps.get("measurement_covariance"), result.measurements.shape)
        noisy_covariance = covariance.copy()
        for i, (measurement, camera) in enumerate(zip(result.measurements, cameras)):
            noisy_covariance[i, i] += sensor.measurement_std(luma, measurement, camera) ** 2
        # the ratio, as the original animation script (the module docstring)
        reconstructed = {"none": reconstruct.velocity(result.measurements, cameras, method="ratio", measurement_covariance=covariance,
                                                      stderr_dof=result.info.get("stderr_dof"), max_velocity_stderr=limit)}
        limit = reconstructed["none"].max_velocity_stderr_m_s
        reconstructed["sensor"] = reconstruct.velocity(noisy, cameras, method="ratio", measurement_covariance=noisy_covariance,
                                                       stderr_dof=result.info.get("stderr_dof"), max_velocity_stderr=limit)
        maps = {noise: r.velocity for noise, r in reconstructed.items()}  # NaN where not valid
        for noise, r in reconstructed.items():
            rows.append({
                "scene": scene.label, "estimator": name, "time_sampling": estimator.time_sampling,
                "correlation": estimator.correlation, "spp": result.spp, "noise": noise,
                **velocity_errors(r.velocity, result.velocity), "max_velocity_stderr_m_s": r.max_velocity_stderr_m_s,
            })  # fmt: skip
        written += _figures(folder, scene.label, name, result, maps)

    written.append(write_csv(folder / "results.csv", rows, COLUMNS))
    written.append(io.write_json(folder / "metadata.json", {
        "experiment": "velocity",
        "scene": scene.label,
        "scene_identity": scene.identity,
        "cameras": [vars(c) for c in cameras],
        "scene_render_settings": scene.render_settings,
        "spp": spp,
        "seed": seed,
        "reference_spp": reference_spp,
        "reference_seed": reference_seed(seed),
        "max_depth": max_depth,
        "signal_electrons": signal_electrons,
        "sensor": dataclasses.asdict(sensor),
        "moving_speed_m_s": MOVING_PIXEL_M_S,
        "cache": str(cache.folder),
    }))  # fmt: skip
    return written


def _figures(folder: Path, scene_label: str, name: str, result, maps: dict) -> list[Path]:
    truth = result.velocity.astype(np.float64)
    # one range for the maps and the errors, from the ground truth, so that colours compare
    vmax = viz.auto_vmax(truth) * 1.1
    velocity_png = folder / f"velocity_{name}.png"
    viz.comparison_figure(
        velocity_png,
        {"ground truth": truth, "reconstructed": maps["none"], "with sensor noise": maps["sensor"]},
        vmax=vmax, unit="m/s", title=f"{scene_label}: radial velocity, {name}, {result.spp} spp",
    )  # fmt: skip
    error_png = folder / f"velocity_error_{name}.png"
    viz.comparison_figure(
        error_png,
        {"error": maps["none"] - truth, "error with sensor noise": maps["sensor"] - truth},
        vmax=vmax, unit="m/s", title=f"{scene_label}: reconstructed − ground truth, {name}",
    )  # fmt: skip
    return [velocity_png, error_png]
