#!/usr/bin/env python
"""Precision of the D-ToF estimator on a slowly moving plane, against its exact value.

A large diffuse plane (a flattened cube) faces a camera at the origin and recedes along the
optical axis at speed v; a point light sits at the camera; direct light only
(``max_depth=2``). Its measurement has a closed form (original-implementation reference
§5.2): for a film point seeing along d̂, the plane is at distance s(t) = (z0 + v t)/|d_z|,
the round trip is L = 2 s and the radiance A = (ρ/π) I |d_z| / s², so a pixel holds

    (1/T) ∫₀ᵀ (g₁/2) Λ(2π h t/T + ψ + k L(t)) A(t) dt,      k = 2π f_g / c.

§5.2's one-line form assumes constant A and linear L; here both are kept exact and the
integral over the film and the exposure is done by Gauss-Legendre quadrature
(:func:`plane_measurement_mean`), whose convergence is checked by refining it.

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

import argparse
import csv
import math
import os
import platform
import sys
import time

import numpy as np

import dopplertof

HERE = os.path.dirname(os.path.abspath(__file__))

# The moving-plane scene of tests/test_dtof.py.
FOV_DEG = 30.0
DISTANCE_M = 5.0
RHO = 0.8
INTENSITY = 50.0
EXPOSURE_S = 1.5e-3
MODULATION_FREQUENCY_HZ = 30e6

SPEEDS_M_S = (10.0, 1.0, 0.1, 0.01, 0.001)
CAMERA_GRID = [(h, psi) for h in (0.0, 0.5, 1.0) for psi in (0.0, math.pi / 2)]


def moving_plane_scene(speed_m_s, exposure=EXPOSURE_S, resolution=16):
    """A diffuse plane facing a camera at the origin, receding along the axis at ``speed_m_s``.

    The plane is the front face (z = −``DISTANCE_M`` at t = 0) of a flattened 40 m x 40 m
    cube, so that hits are on a triangle mesh; a point light of intensity ``INTENSITY`` sits
    at the camera; film ``resolution``² pixels, box filter, fov ``FOV_DEG``.
    """
    import mitsuba as mi

    # Keys in double precision: a float32 5.5 m translation is quantised to 0.5 µm, which
    # would misstate a 15 µm displacement by up to 1.6 %.
    start = mi.ScalarTransform4d().translate([0, 0, -DISTANCE_M - 0.5]) @ mi.ScalarTransform4d().scale([20, 20, 0.5])
    end = mi.ScalarTransform4d().translate([0, 0, -speed_m_s * exposure]) @ start
    return dopplertof.load_scene(
        {
            "type": "scene",
            "sensor": {
                "type": "perspective",
                "fov": FOV_DEG,
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}},
            },
            "light": {"type": "point", "position": [0, 0, 0], "intensity": {"type": "rgb", "value": [INTENSITY] * 3}},
            "plane": {
                "type": "cube",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [RHO] * 3}},
                "motion": {"type": "keyframes", "keys": [(0.0, start), (exposure, end)]},
            },
        }
    )


def _gauss_legendre_01(panels, order):
    """Nodes and weights of composite Gauss-Legendre quadrature on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(order)
    edges = np.arange(panels)[:, None] / panels
    nodes = (edges + 0.5 * (x[None] + 1.0) / panels).ravel()
    weights = np.tile(0.5 * w / panels, panels)
    return nodes, weights


def plane_measurement_mean(camera, speed_m_s, nodes_xy=48, time_panels=64, time_order=8):
    """Exact image mean of the moving plane's direct-light measurement (module docstring).

    Parameters
    ----------
    camera : dopplertof.Camera (low-pass model; any waveform)
    speed_m_s : float, m/s. Receding speed of the plane.
    nodes_xy : int. Gauss-Legendre nodes per film axis.
    time_panels, time_order : int. Composite Gauss-Legendre over the exposure: ``time_panels``
        panels of ``time_order`` nodes (the sinusoid converges with few panels; the kinked
        waveforms need many).

    Returns
    -------
    float : the image mean, in the units of ``RenderResult.measurements``.
    """
    from dopplertof.modulation import lowpass_waveform

    tau = math.tan(math.radians(FOV_DEG) / 2)
    f, w = _gauss_legendre_01(1, nodes_xy)
    fx, fy = np.meshgrid(f, f, indexing="ij")
    w_xy = np.outer(w, w).ravel()
    cos_axis = 1.0 / np.sqrt(((2 * fx - 1) * tau) ** 2 + ((2 * fy - 1) * tau) ** 2 + 1.0).ravel()
    u, w_t = _gauss_legendre_01(time_panels, time_order)
    total = 0.0
    for chunk in range(0, u.size, 256):  # bounded memory: 256 times x nodes_xy² points at once
        uc = u[chunk:chunk + 256, None]
        s = (DISTANCE_M + speed_m_s * camera.exposure * uc) / cos_axis[None]
        radiance = RHO / math.pi * INTENSITY * cos_axis[None] / s**2
        phase = 2 * math.pi * camera.heterodyne * uc + camera.phase + camera.wavenumber * 2 * s
        integrand = 0.5 * camera.g1 * lowpass_waveform(phase, camera.waveform) * radiance
        total += float(w_t[chunk:chunk + 256] @ integrand @ w_xy)
    return total


def reference_with_check(camera, speed_m_s):
    """(exact value, relative change when the quadrature is refined): the second number bounds
    the quadrature error, so it must sit far below the errors being reported."""
    # the sinusoid is smooth in time; the other waveforms have kinks, so many short panels
    panels, order = (8, 8) if camera.waveform == "sinusoidal" else (1024, 4)
    coarse = plane_measurement_mean(camera, speed_m_s, nodes_xy=32, time_panels=panels, time_order=order)
    fine = plane_measurement_mean(camera, speed_m_s, nodes_xy=48, time_panels=2 * panels, time_order=order)
    return fine, abs(fine - coarse) / max(abs(fine), 1e-300)


# ----------------------------------------------------------------------------------------
# Benchmark


def run(args, log):
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
    handles, labels = axes_list[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside right center", fontsize=8)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    figure.savefig(path, dpi=110)


CSV_FIELDS = [
    "waveform", "speed_m_s", "travel_m", "h", "psi", "measured", "stderr", "stderr_seeds", "stderr_render", "exact", "rel_error", "rel_stderr", "z",
    "quadrature_rel_change", "render_s",
]


def write_csv(path, rows, meta):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", newline="") as f:
        f.write(f"# {meta}\n")
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for row in rows:
            w.writerow({k: (f"{v:.9g}" if isinstance(v, float) else v) for k, v in row.items()})


def parse_args(argv=None):
    from dopplertof.correlation import MODES
    from dopplertof.modulation import WAVEFORMS
    from dopplertof.timesampling import METHODS

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 64; quick 8)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel per render (even; default 2048; quick 64)")
    p.add_argument("--speeds", type=float, nargs="+", default=None, help="plane speeds, m/s (default 10 1 0.1 0.01 0.001)")
    p.add_argument("--waveforms", nargs="+", default=["sinusoidal"], help=f"any of {', '.join(WAVEFORMS)}, or 'all'")
    p.add_argument("--time-sampling", default="antithetic", choices=METHODS)
    p.add_argument("--correlation", default="replay", choices=MODES)
    p.add_argument("--seed", type=int, default=7, help="first seed (default 7)")
    p.add_argument("--seeds", type=int, default=None, help="renders per speed, seeds seed .. seed+N-1 (default 8; quick 3)")
    p.add_argument("--variant", default=None, help="Mitsuba variant (default llvm_ad_rgb)")
    p.add_argument("--csv", default=None, help="CSV output (default benchmarks/results/precision.csv; quick: precision_quick.csv)")
    p.add_argument("--plot", default=None, help="PNG output (default: the CSV path with .png)")
    p.add_argument("--quick", action="store_true", help="smoke test: 8x8, 64 spp x 3 seeds, speeds 1 0.01 0.001 (< 30 s)")
    p.add_argument("--quiet", action="store_true", help="only print the machine line and the tables")
    args = p.parse_args(argv)
    defaults = (
        dict(resolution=8, spp=64, seeds=3, speeds=[1.0, 0.01, 0.001]) if args.quick
        else dict(resolution=64, spp=2048, seeds=8, speeds=list(SPEEDS_M_S))
    )
    for k, v in defaults.items():
        if getattr(args, k) is None:
            setattr(args, k, v)
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
    if args.csv is None:
        args.csv = os.path.join(HERE, "results", "precision_quick.csv" if args.quick else "precision.csv")
    if args.plot is None:
        args.plot = os.path.splitext(args.csv)[0] + ".png"
    return args


def main(argv=None):
    args = parse_args(argv)
    variant = dopplertof.set_variant(args.variant or "llvm_ad_rgb")

    def log(msg):
        if not args.quiet:
            print(msg, flush=True)

    import drjit as dr
    import mitsuba as mi

    machine = (
        f"machine: {platform.processor() or platform.machine()} | {os.cpu_count()} cores | Mitsuba {mi.__version__} | "
        f"Dr.Jit {dr.__version__} | variant {variant} | dopplertof {dopplertof.__version__}"
    )
    settings = (
        f"settings: {args.resolution}x{args.resolution}, spp {args.spp} x {args.seeds} seeds from {args.seed}, max_depth 2, "
        f"{args.time_sampling} + {args.correlation}, f_g {MODULATION_FREQUENCY_HZ / 1e6:g} MHz, T {EXPOSURE_S * 1e3:g} ms, "
        f"plane at {DISTANCE_M:g} m"
    )
    print(machine, flush=True)
    print(settings, flush=True)
    t_all = time.perf_counter()
    rows = run(args, log)
    print()
    for wf in args.waveforms:
        print(f"{wf}: relative error of the image mean (± its relative standard error over the seeds), per camera")
        print(markdown_table(rows, wf))
        print()
    worst_quadrature = max(r["quadrature_rel_change"] for r in rows)
    print(f"reference quadrature: largest relative change on refinement {worst_quadrature:.1e}")
    print(f"total {time.perf_counter() - t_all:.1f} s")
    command = "python benchmarks/precision.py " + " ".join(sys.argv[1:] if argv is None else argv)
    write_csv(args.csv, rows, f"{command.strip()} || {machine} || {settings}")
    plot(args.plot, rows, args.waveforms)
    print(f"CSV: {args.csv}\nplot: {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
