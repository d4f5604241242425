#!/usr/bin/env python
"""Precision of the D-ToF estimator on a slowly moving plane, against its exact value.

The moving-plane oracle of :mod:`dopplertof.oracles` (also used by tests/test_dtof.py): a
large diffuse plane faces a camera at the origin and recedes along the optical axis at
speed v, a point light sits at the camera, direct light only (``max_depth=2``). Its
measurement has a closed form (original-implementation reference §5.2), kept exact in A(t)
and L(t) and integrated over the film and the exposure by Gauss-Legendre quadrature
(:func:`dopplertof.oracles.moving_plane_measurement_mean`), whose convergence is checked by
refining it.

::

    python benchmarks/precision.py            # 64x64, 2048 spp x 8 seeds, 10 m/s ... 1 mm/s, sinusoid (~1 min, 2 cores)
    python benchmarks/precision.py --quick    # 8x8, 64 spp x 3 seeds, 1, 0.01 and 0.001 m/s (< 30 s)
    python benchmarks/precision.py --waveforms all --speeds 1 0.01

For speeds 10, 1, 0.1, 0.01, 0.001 m/s at 30 MHz and T = 1.5 ms (15 mm ... 1.5 µm of travel
during the exposure) and every camera h ∈ {0, ½, 1} × ψ ∈ {0, π/2}, all six from the same
paths in one render per speed, it prints and writes to CSV the relative error of the image
mean, (measured − exact)/|exact|, averaged over ``--seeds`` renders, next to the relative
standard error of that average from the seed-to-seed spread: an error well above the
standard error is bias, one of its size is noise. (The renderer's own ``stderr``, which
treats the samples of a pixel as independent, overestimates the noise of stratified
antithetic times up to a few hundredfold here; the CSV keeps it as ``stderr_render``.) Every
speed uses the same seeds, so the noise is nearly the same at every speed and a trend with
speed is bias. A log-log plot of
|relative error| and relative standard error against speed goes next to the CSV.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)
from dopplertof.oracles import PLANE_DISTANCE_M, PLANE_EXPOSURE_S, moving_plane_measurement_mean, moving_plane_scene

import _common
from _common import CAMERA_GRID

EXPOSURE_S = PLANE_EXPOSURE_S
MODULATION_FREQUENCY_HZ = 30e6
SPEEDS_M_S = (10.0, 1.0, 0.1, 0.01, 0.001)


def reference_with_check(camera, speed_m_s):
    """(exact value, relative change when the quadrature is refined): the second number bounds
    the quadrature error, so it must sit far below the errors being reported."""
    # the sinusoid is smooth in time; the other waveforms have kinks, so many short panels
    panels, order = (8, 8) if camera.waveform == "sinusoidal" else (1024, 4)
    coarse = moving_plane_measurement_mean(camera, speed_m_s, nodes_xy=32, time_panels=panels, time_order=order)
    fine = moving_plane_measurement_mean(camera, speed_m_s, nodes_xy=48, time_panels=2 * panels, time_order=order)
    return fine, abs(fine - coarse) / max(abs(fine), 1e-300)


# ----------------------------------------------------------------------------------------
# Benchmark


def measure(args, log):
    cameras_by_waveform = {
        wf: [dopplertof.Camera(MODULATION_FREQUENCY_HZ, EXPOSURE_S, heterodyne=h, phase=psi, waveform=wf) for h, psi in CAMERA_GRID]
        for wf in args.waveforms
    }
    seeds = [args.seed + k for k in range(args.seeds)]
    rows = []
    for speed in args.speeds:
        scene = moving_plane_scene(speed, resolution=args.resolution)
        for wf, cameras in cameras_by_waveform.items():
            means = np.zeros((len(seeds), len(cameras)))
            render_var = np.zeros((len(seeds), len(cameras)))
            t = time.perf_counter()
            for k, seed in enumerate(seeds):
                result = dopplertof.render(
                    scene, cameras=cameras, spp=args.spp, seed=seed, max_depth=2,
                    time_sampling=args.time_sampling, correlation=args.correlation,
                )
                n_pixels = result.measurements[0].size
                means[k] = result.measurements.astype(np.float64).mean(axis=(1, 2))
                # pixels use disjoint random numbers, so their errors add in quadrature
                render_var[k] = (result.measurement_stderr.astype(np.float64) ** 2).sum(axis=(1, 2)) / n_pixels**2
            render_s = (time.perf_counter() - t) / len(seeds)
            for i, cam in enumerate(cameras):
                measured = float(means[:, i].mean())
                stderr_render = float(np.sqrt(render_var[:, i].mean() / len(seeds)))
                stderr_seeds = float(means[:, i].std(ddof=1) / math.sqrt(len(seeds))) if len(seeds) > 1 else float("nan")
                stderr = stderr_seeds if len(seeds) > 1 else stderr_render
                exact, quadrature_change = reference_with_check(cam, speed)
                rows.append(dict(
                    waveform=wf, speed_m_s=speed, travel_m=speed * EXPOSURE_S, h=cam.heterodyne, psi=cam.phase,
                    measured=measured, stderr=stderr, stderr_seeds=stderr_seeds, stderr_render=stderr_render, exact=exact,
                    rel_error=(measured - exact) / abs(exact), rel_stderr=stderr / abs(exact),
                    z=(measured - exact) / stderr if stderr > 0 else float("nan"),
                    quadrature_rel_change=quadrature_change, render_s=render_s,
                ))
            worst = max(abs(r["rel_error"]) for r in rows[-len(cameras):])
            log(f"v = {speed:g} m/s, {wf}: {len(seeds)} renders, {render_s:.2f} s each; worst |rel. error| {worst:.3g}")
    return rows


def psi_label(psi):
    return "0" if psi == 0 else f"{math.degrees(psi):g}deg"


def markdown_table(rows, waveform):
    keys = [(h, psi) for h, psi in CAMERA_GRID]
    head = "| speed (m/s) | travel | " + " | ".join(f"h={h:g}, ψ={psi_label(p)}" for h, p in keys) + " |"
    lines = [head, "|---|---|" + "---:|" * len(keys)]
    for speed in sorted({r["speed_m_s"] for r in rows if r["waveform"] == waveform}, reverse=True):
        cells = []
        for h, psi in keys:
            r = next(r for r in rows if r["waveform"] == waveform and r["speed_m_s"] == speed and r["h"] == h and r["psi"] == psi)
            cells.append(f"{r['rel_error']:+.2e} (±{r['rel_stderr']:.1e})")
        travel = speed * EXPOSURE_S
        travel_s = f"{travel * 1e3:g} mm" if travel >= 1e-3 else f"{travel * 1e6:g} µm"
        lines.append(f"| {speed:g} | {travel_s} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(path, rows, waveforms):
    from matplotlib.figure import Figure

    figure = Figure(figsize=(5.6 * len(waveforms) + 1.8, 4.6), layout="constrained")
    axes_list = figure.subplots(1, len(waveforms), squeeze=False)[0]
    for axes, wf in zip(axes_list, waveforms):
        for i, (h, psi) in enumerate(CAMERA_GRID):
            sel = sorted((r for r in rows if r["waveform"] == wf and r["h"] == h and r["psi"] == psi), key=lambda r: r["speed_m_s"])
            v = np.array([r["speed_m_s"] for r in sel])
            color = f"C{i}"
            axes.loglog(v, [abs(r["rel_error"]) for r in sel], "o-", color=color, label=f"h={h:g}, ψ={psi_label(psi)}")
            axes.loglog(v, [r["rel_stderr"] for r in sel], ":", color=color, alpha=0.8)
        axes.set_xlabel("plane speed (m/s)")
        axes.set_ylabel("relative error of the image mean")
        axes.set_title(f"{wf}: |error| (solid) vs standard error (dotted)")
        axes.grid(True, which="both", alpha=0.3)
    _common.save_figure(figure, axes_list[0], path)


CSV_FIELDS = [
    "waveform", "speed_m_s", "travel_m", "h", "psi", "measured", "stderr", "stderr_seeds", "stderr_render", "exact", "rel_error", "rel_stderr", "z",
    "quadrature_rel_change", "render_s",
]


def parse_args(argv=None):
    from dopplertof.correlation import MODES
    from dopplertof.modulation import WAVEFORMS
    from dopplertof.timesampling import METHODS

    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 64; quick 8)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel per render (even; default 2048; quick 64)")
    p.add_argument("--speeds", type=float, nargs="+", default=None, help="plane speeds, m/s (default 10 1 0.1 0.01 0.001)")
    p.add_argument("--waveforms", nargs="+", default=["sinusoidal"], help=f"any of {', '.join(WAVEFORMS)}, or 'all'")
    p.add_argument("--time-sampling", default="antithetic", choices=METHODS)
    p.add_argument("--correlation", default="replay", choices=MODES)
    p.add_argument("--seed", type=int, default=7, help="first seed (default 7)")
    p.add_argument("--seeds", type=int, default=None, help="renders per speed, seeds seed .. seed+N-1 (default 8; quick 3)")
    _common.add_output_options(p, "precision", quick_help="smoke test: 8x8, 64 spp x 3 seeds, speeds 1 0.01 0.001 (< 30 s)")
    args = p.parse_args(argv)
    _common.fill_defaults(
        args,
        dict(resolution=8, spp=64, seeds=3, speeds=[1.0, 0.01, 0.001]) if args.quick
        else dict(resolution=64, spp=2048, seeds=8, speeds=list(SPEEDS_M_S)),
    )  # fmt: skip
    if args.waveforms == ["all"]:
        args.waveforms = list(WAVEFORMS)
    bad = [w for w in args.waveforms if w not in WAVEFORMS]
    if bad:
        p.error(f"unknown waveform(s) {bad}; choose from {', '.join(WAVEFORMS)} or 'all'")
    if args.seeds <= 0:
        p.error(f"--seeds must be positive, got {args.seeds}")
    if args.resolution <= 0 or args.spp <= 0 or args.spp % 2:
        p.error(f"--resolution must be positive and --spp positive and even, got {args.resolution} and {args.spp}")
    if any(not math.isfinite(v) or v <= 0 for v in args.speeds):
        p.error(f"--speeds must be positive, got {args.speeds}")
    _common.default_output_paths(args, "precision")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = (
        f"settings: {args.resolution}x{args.resolution}, spp {args.spp} x {args.seeds} seeds from {args.seed}, max_depth 2, "
        f"{args.time_sampling} + {args.correlation}, f_g {MODULATION_FREQUENCY_HZ / 1e6:g} MHz, T {EXPOSURE_S * 1e3:g} ms, "
        f"plane at {PLANE_DISTANCE_M:g} m"
    )
    run = _common.Run("precision", args, argv, settings)
    rows = measure(args, run.log)
    print()
    for wf in args.waveforms:
        print(f"{wf}: relative error of the image mean (± its relative standard error over the seeds), per camera")
        print(markdown_table(rows, wf))
        print()
    worst_quadrature = max(r["quadrature_rel_change"] for r in rows)
    print(f"reference quadrature: largest relative change on refinement {worst_quadrature:.1e}")
    return run.finish(rows, CSV_FIELDS, plot=lambda path: plot(path, rows, args.waveforms), digits=9)


if __name__ == "__main__":
    sys.exit(main())
