"""Error of time-sampling estimators over a grid of heterodyne ratios h and phases ψ.

Both sweeps render the whole h × ψ grid of cameras (× waveforms, where a sweep has
several) in one render per estimator (all cameras of a render share its paths, and a camera
costs little next to a path) and compare every camera's image with the same camera of a
high-spp reference. A phase ψ ≥ π is not rendered: its measurement is that of ψ − π with
the sign flipped (every waveform is odd under a half-period shift), so its errors are the
same numbers, and its rows repeat them (the original scripts' ψ ∈ 2π·{0, 0.1, …, 1} needs
5 cameras per h instead of 11).

``time_sampling``
    The paper's Fig. 12: every time sampling × correlation mode; the error averaged over ψ
    versus h (the original ``main_experiment.py`` E = 1 and ``main_plot.py``).
``shifts``
    The paper's Fig. 15: antithetic and mirrored antithetic sampling over the shift a ∈ [0, 1]
    (units of T), the error versus a and h (the original E = 3).

Both write ``results.csv`` (one row per estimator and camera), ``summary.csv`` (averaged
over ψ, with the standard deviation over ψ), PNG plots and ``metadata.json``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .. import io, viz
from .common import (
    Echo,
    Estimator,
    ExperimentScene,
    SWEEP_REPLICATES,
    ReferenceCache,
    camera_grid,
    check_spp,
    image_errors,
    mean_over,
    reference_render,
    reference_seed,
    rms,
    sweep_lanes_per_pass,
    timed_render,
    write_csv,
)

METRICS = ("mae", "rmse", "relative_mae", "relative_rmse", "psnr_db", "rmse_x_exposure")
RESULT_COLUMNS = (
    "scene", "waveform", "time_sampling", "correlation", "stratify_intervals", "shift", "h", "psi_deg", "spp", "seed",
    *METRICS,
    "stderr_rms", "reference_stderr_rms", "render_seconds",
)  # fmt: skip
"""``shift``: antithetic shift a (units of T), empty for methods without one;
``stratify_intervals``: per-interval ("further") stratification in force (false for
uniform times, which have no strata); ``psi_deg``: ψ in
degrees; errors in measurement units (see :func:`~.common.image_errors`);
``rmse_x_exposure``: the RMSE times the exposure T (s), the error of the exposure integral
∫W f dt on which the original scripts' plots are drawn;
``stderr_rms``: the RMSE the render's own noise predicts; ``reference_stderr_rms``: the
reference's, which adds in quadrature to every measured RMSE (the floor of the curves)."""

SUMMARY_GROUP = ("scene", "waveform", "time_sampling", "correlation", "stratify_intervals", "shift", "h", "spp")
SUMMARY_COLUMNS = (*SUMMARY_GROUP, "count", *(f"{m}_{s}" for m in METRICS for s in ("mean", "std")))


@dataclass(frozen=True)
class SweepSettings:
    """The camera grid and sample counts of a sweep.

    Attributes
    ----------
    h_values : tuple of float
        Heterodyne ratios h (beat cycles per exposure).
    phases_rad : tuple of float
        Sensor phase offsets ψ (rad), each averaged over with equal weight.
    spp, reference_spp : int
        Paths per pixel of the compared renders and of the reference.
    seed : int
        Seed of the compared renders (the reference uses another).
    max_depth : int
        Path depth.
    replicates : int
        Replicates per pixel of every render (default :data:`~.common.SWEEP_REPLICATES`).
    waveforms : tuple of str
        The cameras' waveforms, all in the same renders (default: the scene's camera's).
    """

    h_values: tuple
    phases_rad: tuple
    spp: int
    reference_spp: int
    seed: int
    max_depth: int
    replicates: int = SWEEP_REPLICATES
    waveforms: tuple = ()

    def __post_init__(self):
        check_spp("spp", self.spp)
        check_spp("reference spp", self.reference_spp)
        if not self.h_values or not self.phases_rad:
            raise ValueError(f"need at least one h and one phase, got h={self.h_values}, psi={self.phases_rad}")


def evenly_spaced(count: int, name: str, stop: float = 1.0) -> tuple:
    """``count`` ≥ 2 values from 0 to ``stop`` inclusive (the original linspace(0, 1, 11)).

    Parameters
    ----------
    count : int
        Values, at least 2.
    name : str
        The option named in the error.
    stop : float, default 1
        The last value.

    Returns
    -------
    tuple of float

    Raises
    ------
    ValueError
        ``count`` is not an integer ≥ 2.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 2:
        raise ValueError(f"{name} must be an integer >= 2, got {count!r}")
    return tuple(float(v) for v in np.linspace(0.0, stop, count))


def phase_offsets(count: int) -> tuple:
    """``count`` ≥ 1 phases ψ = π k / count (rad), k = 0 … count − 1.

    Half a period is enough: every sensor waveform flips sign under ψ → ψ + π, so the
    measurement and its error at ψ + π are those at ψ with the sign flipped.

    Parameters
    ----------
    count : int
        Phases, at least 1.

    Returns
    -------
    tuple of float
        Phases in rad.

    Raises
    ------
    ValueError
        ``count`` is not an integer ≥ 1.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"phases must be an integer >= 1, got {count!r}")
    return tuple(math.pi * k / count for k in range(count))


def folded_phases(phases_rad: Sequence[float]) -> tuple[tuple, list[int]]:
    """Phases folded into [0, π), each rendered once.

    Parameters
    ----------
    phases_rad : sequence of float
        Phases ψ (rad), any range.

    Returns
    -------
    tuple of (tuple of float, list of int)
        The phases to render (rad, in [0, π), distinct), and for each given phase the index
        of its folded phase among them.
    """
    rendered: list[float] = []
    index = []
    for phase in phases_rad:
        folded = math.fmod(float(phase), math.pi)
        folded = folded + math.pi if folded < 0 else folded
        folded = 0.0 if math.isclose(folded, math.pi, abs_tol=1e-9) else folded
        match = [k for k, p in enumerate(rendered) if math.isclose(p, folded, abs_tol=1e-9)]
        if not match:
            rendered.append(folded)
        index.append(match[0] if match else len(rendered) - 1)
    return tuple(rendered), index


def sweep_cameras(base, settings: SweepSettings) -> list:
    """The rendered cameras, waveform-major, then h, then folded phase (:func:`folded_phases`).

    Parameters
    ----------
    base : Camera
        The camera every other parameter comes from.
    settings : SweepSettings
        Its ``waveforms`` (empty: ``base``'s), ``h_values`` and ``phases_rad``.

    Returns
    -------
    list of Camera
    """
    rendered, _ = folded_phases(settings.phases_rad)
    waveforms = settings.waveforms or (base.waveform,)
    return [camera for w in waveforms for camera in camera_grid(dataclasses.replace(base, waveform=w), settings.h_values, rendered)]


def _error_rows(scene, estimator, result, reference, seconds, settings: SweepSettings) -> list[dict]:
    """One row per camera of the reported grid (a phase ψ ≥ π repeats the rendered ψ − π's errors)."""
    rendered, index = folded_phases(settings.phases_rad)
    rows = []
    for i, camera in enumerate(result.cameras):
        errors = image_errors(result.measurements[i], reference.measurements[i])
        errors["rmse_x_exposure"] = errors["rmse"] * camera.exposure
        common = {
            "scene": scene.label,
            "waveform": camera.waveform,
            "time_sampling": estimator.time_sampling,
            "correlation": estimator.correlation,
            "stratify_intervals": estimator.stratified,
            "shift": estimator.shift_label,
            "h": camera.heterodyne,
            "spp": result.spp,
            "seed": result.seed,
            **errors,
            "stderr_rms": rms(result.measurement_stderr[i]),
            "reference_stderr_rms": rms(reference.measurement_stderr[i]),
            "render_seconds": seconds,
        }  # fmt: skip
        for phase, k in zip(settings.phases_rad, index):
            if k == i % len(rendered):
                rows.append({**common, "psi_deg": math.degrees(phase)})
    return rows


def _sweep(scene: ExperimentScene, estimators: Sequence[Estimator], settings: SweepSettings, cache: ReferenceCache, echo: Echo):
    """Render every estimator and the reference; rows of :data:`RESULT_COLUMNS`."""
    cameras = sweep_cameras(scene.base_camera, settings)
    lanes = sweep_lanes_per_pass(len(cameras))
    reference = reference_render(scene, cameras, settings.reference_spp, settings.seed, settings.max_depth, cache, echo, settings.replicates, lanes)
    rows = []
    for number, estimator in enumerate(estimators, 1):
        result, seconds = timed_render(scene, cameras, estimator, settings.spp, settings.seed, settings.max_depth, replicates=settings.replicates, lanes_per_pass=lanes)
        shift = f" shift {estimator.shift_label:g}" if estimator.shift_label != "" else ""
        echo(f"[{number}/{len(estimators)}] {estimator.label}{shift}: {seconds:.1f} s")
        rows.extend(_error_rows(scene, estimator, result, reference, seconds, settings))
    return rows, reference


def _write_tables(folder: Path, rows, metadata) -> list[Path]:
    summary = mean_over(rows, SUMMARY_GROUP, METRICS)
    return [
        write_csv(folder / "results.csv", rows, RESULT_COLUMNS),
        write_csv(folder / "summary.csv", summary, SUMMARY_COLUMNS),
        io.write_json(folder / "metadata.json", metadata),
    ]


def _metadata(scene, settings, estimators, cache, experiment) -> dict:
    return {
        "experiment": experiment,
        "scene": scene.label,
        "scene_identity": scene.identity,
        "base_camera": vars(scene.base_camera),
        "scene_render_settings": scene.render_settings,
        "h_values": list(settings.h_values),
        "psi_deg": [math.degrees(p) for p in settings.phases_rad],
        "spp": settings.spp,
        "seed": settings.seed,
        "reference_spp": settings.reference_spp,
        "reference_seed": reference_seed(settings.seed),
        "reference_estimator": "antithetic/replay, shift 0.5",
        "max_depth": settings.max_depth,
        "replicates": settings.replicates,
        "waveforms": list(settings.waveforms or (scene.base_camera.waveform,)),
        "rendered_psi_deg": [math.degrees(p) for p in folded_phases(settings.phases_rad)[0]],
        "estimators": [{"time_sampling": e.time_sampling, "correlation": e.correlation, "shift": e.shift_label, "stratify_intervals": e.stratified} for e in estimators],
        "cache": str(cache.folder),
    }


def _curve(summary, metric, **match):
    """(mean, std) over ψ of ``metric`` versus h for the summary rows matching ``match``."""
    chosen = [row for row in summary if all(row[k] == v for k, v in match.items())]
    mean = np.array([row[f"{metric}_mean"] for row in chosen])
    std = np.array([row[f"{metric}_std"] for row in chosen])
    return mean, np.nan_to_num(std, nan=0.0)


def run_time_sampling(scene: ExperimentScene, folder, estimators: Sequence[Estimator], settings: SweepSettings, cache: ReferenceCache, echo: Echo) -> list[Path]:
    """Fig. 12: every estimator's error against the reference over the h × ψ grid.

    Writes ``results.csv``, ``summary.csv``, ``metadata.json`` and, per correlation mode,
    ``rmse_vs_h_<mode>.png`` and ``psnr_vs_h_<mode>.png`` (one curve per time sampling:
    mean over ψ with ±1 std band).

    Parameters
    ----------
    scene : ExperimentScene
    folder : str or path
        Output folder (created).
    estimators : sequence of Estimator
    settings : SweepSettings
        The grid, spp, seeds and depth.
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
    KeyboardInterrupt
        A render was interrupted.
    """
    folder = Path(folder)
    rows, _ = _sweep(scene, estimators, settings, cache, echo)
    written = _write_tables(folder, rows, _metadata(scene, settings, estimators, cache, "time-sampling"))
    summary = mean_over(rows, SUMMARY_GROUP, METRICS)
    h = np.array(settings.h_values)
    for mode in dict.fromkeys(e.correlation for e in estimators):
        methods = [e.time_sampling for e in estimators if e.correlation == mode]
        for metric, ylabel, logy in (("rmse", "RMSE (measurement units)", True), ("psnr_db", "PSNR (dB)", False)):
            curves = {m: _curve(summary, metric, time_sampling=m, correlation=mode) for m in methods}
            name = metric.split("_")[0]
            written.append(viz.plot_curves(
                folder / f"{name}_vs_h_{mode}.png", h, curves, xlabel="heterodyne ratio h (cycles per exposure)",
                ylabel=ylabel, logy=logy, title=f"{scene.label}: correlation {mode}, {settings.spp} spp, mean over {len(settings.phases_rad)} ψ",
            ))  # fmt: skip
    return written


def run_shifts(scene: ExperimentScene, folder, methods: Sequence[str], shifts: Sequence[float], correlation: str, settings: SweepSettings, cache: ReferenceCache, echo: Echo) -> list[Path]:
    """Fig. 15: antithetic estimators' error over the shift a (units of T) and h.

    Writes ``results.csv``, ``summary.csv``, ``metadata.json`` and per method
    ``rmse_<method>_shift_h.png`` (RMSE averaged over ψ as an image over a × h) and
    ``rmse_vs_shift_<method>.png`` (one curve per h).

    Parameters
    ----------
    scene : ExperimentScene
    folder : str or path
        Output folder (created).
    methods : sequence of str
        Antithetic time samplings (``antithetic``, ``antithetic_mirror``).
    shifts : sequence of float
        Shifts a, units of T, in [0, 1].
    correlation : str
        The correlation mode of every estimator.
    settings : SweepSettings
        The grid, spp, seeds and depth.
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
        A method that is not antithetic, or a shift outside [0, 1].
    """
    for method in methods:
        if method not in ("antithetic", "antithetic_mirror"):
            raise ValueError(f"the shift experiment needs an antithetic time sampling (antithetic, antithetic_mirror), got {method!r}")
    estimators = [Estimator(method, correlation, shift) for method in methods for shift in shifts]
    folder = Path(folder)
    rows, _ = _sweep(scene, estimators, settings, cache, echo)
    metadata = _metadata(scene, settings, estimators, cache, "shifts")
    metadata["shifts"] = list(shifts)
    written = _write_tables(folder, rows, metadata)
    summary = mean_over(rows, SUMMARY_GROUP, METRICS)
    h = np.array(settings.h_values)
    shift_axis = np.array(shifts)
    for method in methods:
        grid = np.array([_curve(summary, "rmse", time_sampling=method, shift=s)[0] for s in shifts])  # (shift, h)
        written.append(_heatmap(folder / f"rmse_{method}_shift_h.png", h, shift_axis, grid, f"{scene.label}: {method}/{correlation}, RMSE mean over ψ"))
        curves = {f"h = {hv:g}": grid[:, j] for j, hv in enumerate(h)}
        written.append(viz.plot_curves(
            folder / f"rmse_vs_shift_{method}.png", shift_axis, curves, xlabel="antithetic shift a (units of T)",
            ylabel="RMSE (measurement units)", logy=True, title=f"{scene.label}: {method}/{correlation}, {settings.spp} spp",
        ))  # fmt: skip
    return written


def _heatmap(path: Path, x, y, values, title: str) -> Path:
    """``values[i, j]`` at (x_j, y_i) as a log-coloured image with a colourbar (no pyplot)."""
    import matplotlib.colors
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    positive = values[np.isfinite(values) & (values > 0)]
    norm = matplotlib.colors.LogNorm(positive.min(), positive.max()) if positive.size and positive.min() < positive.max() else None
    figure = Figure(figsize=(6.4, 4.8), layout="constrained")
    axes = figure.add_subplot()
    mesh = axes.pcolormesh(x, y, values, norm=norm, cmap="viridis", shading="nearest")
    figure.colorbar(mesh, ax=axes, label="RMSE (measurement units)")
    axes.set_xlabel("heterodyne ratio h (cycles per exposure)")
    axes.set_ylabel("antithetic shift a (units of T)")
    axes.set_title(title)
    FigureCanvasAgg(figure)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=viz.FIGURE_DPI, format="png")
    return path
