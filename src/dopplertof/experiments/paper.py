"""The paper's Figs. 12, 9 and 15 with the protocol of the original ``doppler_tutorials``.

The original scripts (``main_experiment.py``, ``main_plot.py``; reference
``sensor-design.md`` §1.2) sweep the heterodyne ratio ω_r (our ``h``) and the phase ψ over
``linspace(0, 1, 11)`` each (ψ in units of 2π, so 0 and 2π both count), render every
method at 1024 spp against an antithetic + full-replay reference at 131 072 spp, with
max_depth 4 (Cornell box) or 8, T = 1.5 ms and 30 MHz (the command defaults,
:data:`~.cli.PAPER`), and plot the RMSE of the exposure integral (image × T), averaged
over ψ, against ω_r on a log scale. Here every camera of a
sweep comes from one render per method (:func:`~.sweeps._sweep`, which renders a phase
ψ ≥ π as ψ − π: the same errors), the reference is cached, and a pixel is the luminance
measurement (the original took the RGB arrays).

========  =======================================================================
figure    what it plots (:func:`run_fig12`, :func:`run_fig9`, ``sweeps.run_shifts``)
========  =======================================================================
Fig. 12   uniform, stratified, antithetic and mirrored antithetic, each with
          independent paths (correlation ``none``, the original's depth 0: dash-dot)
          and replayed paths (``replay``, depth 16: solid), RMSE × T and PSNR vs ω_r
Fig. 9    the four waveforms; stratified, antithetic and mirror with and without
          further stratification (``stratify_intervals``; solid / dashed) and
          uniform, all with replayed paths
Fig. 15   antithetic and mirror (replay) over the shift a ∈ linspace(0, 1, 11) × ω_r
========  =======================================================================

Colours as the original's: uniform black, stratified red, antithetic green, mirror blue.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Sequence

import numpy as np

from .. import viz
from ..modulation import WAVEFORMS
from ..timesampling import METHODS
from .common import Echo, Estimator, ExperimentScene, ReferenceCache, mean_over
from .sweeps import METRICS, SUMMARY_GROUP, SweepSettings, _curve, _metadata, _sweep, _write_tables, evenly_spaced

SHALLOW_SCENES = ("cornell-box", "cornell-box-area")
"""Built-in scenes traced to max_depth 4, as the original's Cornell box; other scenes 8."""
FIG12_CORRELATIONS = ("none", "replay")
FIG9_ESTIMATORS = (Estimator("uniform", "replay"),) + tuple(
    Estimator(method, "replay", stratify_intervals=stratify) for method in ("stratified", "antithetic", "antithetic_mirror") for stratify in (True, False)
)  # fmt: skip
FIG15_METHODS = ("antithetic", "antithetic_mirror")

RMSE_LABEL = "RMSE × T (measurement units · s)"
COLOURS = {"uniform": "k", "stratified": "r", "antithetic": "g", "antithetic_mirror": "b"}
CORRELATION_STYLES = {"none": "-.", "pixel": ":", "replay": "-", "reconnection": "--", "adaptive": (0, (5, 1, 1, 1))}


def protocol_max_depth(scene: ExperimentScene) -> int:
    """The scene's own max_depth, else 4 for :data:`SHALLOW_SCENES` and 8 for the others.

    Parameters
    ----------
    scene : ExperimentScene

    Returns
    -------
    int
    """
    if scene.max_depth is not None:
        return scene.max_depth
    return 4 if scene.identity.get("builtin") in SHALLOW_SCENES else 8


def protocol_phases(steps: int) -> tuple:
    """ψ = 2π·linspace(0, 1, steps) (rad), as the original's ``hetero_offset`` sweep.

    Parameters
    ----------
    steps : int
        Phases, at least 2.

    Returns
    -------
    tuple of float
        Phases in rad.

    Raises
    ------
    ValueError
        ``steps`` is not an integer ≥ 2.
    """
    return evenly_spaced(steps, "--phase-steps", stop=2.0 * math.pi)


def fig12_estimators(time_samplings: Sequence[str] = (), correlations: Sequence[str] = ()) -> list[Estimator]:
    """Every time sampling × correlation (default: all methods, ``none`` and ``replay``).

    Parameters
    ----------
    time_samplings : sequence of str, default all methods
    correlations : sequence of str, default ``("none", "replay")``

    Returns
    -------
    list of Estimator
        Time-sampling-major.

    Raises
    ------
    ValueError
        An unknown time sampling or correlation mode.
    """
    return [Estimator(t, c) for t in dict.fromkeys(time_samplings or METHODS) for c in dict.fromkeys(correlations or FIG12_CORRELATIONS)]


def run_fig12(scene: ExperimentScene, folder, estimators: Sequence[Estimator], settings: SweepSettings, cache: ReferenceCache, echo: Echo) -> list[Path]:
    """Fig. 12: each estimator's RMSE × T and PSNR (mean over ψ, ±1 std) against ω_r.

    Writes ``results.csv`` (one row per estimator and camera), ``summary.csv`` (mean and
    std over ψ), ``metadata.json`` and ``fig12.png``.

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
    """
    folder = Path(folder)
    rows, _ = _sweep(scene, estimators, settings, cache, echo)
    written = _write_tables(folder, rows, _metadata(scene, settings, estimators, cache, "paper-fig12"))
    summary = mean_over(rows, SUMMARY_GROUP, METRICS)
    panels = []
    for metric, name, label, logy in (("rmse_x_exposure", "RMSE", RMSE_LABEL, True), ("psnr_db", "PSNR", "PSNR (dB)", False)):
        curves = [(e.label, COLOURS.get(e.time_sampling), CORRELATION_STYLES.get(e.correlation, "-"), _curve(summary, metric, **_of(e))) for e in estimators]
        panels.append((name, label, logy, curves))
    title = f"{scene.label}: {settings.spp} spp, mean over {len(settings.phases_rad)} ψ, max_depth {settings.max_depth}"
    written.append(_plot(folder / "fig12.png", np.array(settings.h_values), panels, title))
    return written


def run_fig9(scene: ExperimentScene, folder, settings: SweepSettings, cache: ReferenceCache, echo: Echo) -> list[Path]:
    """Fig. 9: per waveform, :data:`FIG9_ESTIMATORS`' RMSE × T against ω_r, with further
    stratification (solid) and without (dashed).

    Writes ``results.csv``, ``summary.csv``, ``metadata.json`` and ``fig9.png``.

    Parameters
    ----------
    scene : ExperimentScene
    folder : str or path
        Output folder (created).
    settings : SweepSettings
        The grid, spp, seeds and depth; its ``waveforms`` (default all of
        :data:`~dopplertof.modulation.WAVEFORMS`).
    cache : ReferenceCache
        Where the reference is looked up and stored.
    echo : callable
        Called with one line of progress text.

    Returns
    -------
    list of Path
        The files written.
    """
    folder = Path(folder)
    settings = settings if settings.waveforms else dataclasses.replace(settings, waveforms=WAVEFORMS)
    rows, _ = _sweep(scene, FIG9_ESTIMATORS, settings, cache, echo)
    written = _write_tables(folder, rows, _metadata(scene, settings, FIG9_ESTIMATORS, cache, "paper-fig9"))
    summary = mean_over(rows, SUMMARY_GROUP, METRICS)
    panels = []
    for waveform in settings.waveforms:
        curves = [
            (e.label, COLOURS.get(e.time_sampling), "-" if e.stratified else "--", _curve(summary, "rmse_x_exposure", waveform=waveform, **_of(e)))
            for e in FIG9_ESTIMATORS
        ]  # fmt: skip
        panels.append((waveform, RMSE_LABEL, True, curves))
    title = f"{scene.label}: {settings.spp} spp, mean over {len(settings.phases_rad)} ψ, replayed paths"
    written.append(_plot(folder / "fig9.png", np.array(settings.h_values), panels, title))
    return written


def _of(estimator: Estimator) -> dict:
    """The summary columns that identify ``estimator``'s rows."""
    return {"time_sampling": estimator.time_sampling, "correlation": estimator.correlation, "stratify_intervals": estimator.stratified, "shift": estimator.shift_label}


def _plot(path: Path, h, panels, title: str) -> Path:
    """Panels side by side, each (title, y label, log y, curves), the curves (label, colour,
    line style, (mean, std)) against ω_r with a ±1 std band; one legend (no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(4.2 * len(panels) + 2.6, 4.2), layout="constrained")
    axes_list = figure.subplots(1, len(panels), squeeze=False)[0]
    for axes, (name, ylabel, logy, curves) in zip(axes_list, panels):
        for label, colour, style, (mean, std) in curves:
            (line,) = axes.plot(h, mean, color=colour, linestyle=style, marker="o", markersize=3, label=label)
            low = np.maximum(mean - std, mean * 1e-3) if logy else mean - std
            axes.fill_between(h, low, mean + std, color=line.get_color(), alpha=0.15, linewidth=0)
        if logy:
            axes.set_yscale("log", nonpositive="clip")
        axes.set_xlabel("heterodyne ratio ω_r (cycles per exposure)")
        axes.set_ylabel(ylabel)
        axes.grid(True, which="both", alpha=0.3)
        axes.set_title(name)
    handles, labels = axes_list[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside right center", fontsize=8)
    figure.suptitle(title)
    FigureCanvasAgg(figure)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=viz.FIGURE_DPI, format="png")
    return path
