#!/usr/bin/env python
"""Velocity RMSE of the D-ToF estimators versus render time, with and without sensor noise.

For every time sampling x correlation (default uniform/stratified/antithetic x
replay/adaptive) and every spp of a sweep it renders a scene, reconstructs the radial
velocity with :func:`dopplertof.reconstruct.velocity` (``method="ratio"``: the
homodyne/heterodyne ratio, fused over both phases, as the measured tables were made) and measures the RMSE against the
render's ground truth ``RenderResult.velocity`` on the moving pixels, once from the
rendered measurements and once after :class:`dopplertof.sensor.SensorModel` (shot, read
and ADC noise at realistic photon counts)::

    python benchmarks/velocity.py            # 64x64, spp 4..1024, 5 seeds, reference 4096 spp (2-5 min, 2 cores)
    python benchmarks/velocity.py --quick    # 32x32, spp 4 and 32, 2 seeds, reference 256 spp (< 1 min)
    python benchmarks/velocity.py --scenes cornell-box --methods uniform antithetic --correlations replay

Definitions:

* cameras: homodyne and heterodyne (h = 0 and 1) at ψ = 0 and 90°, all four from the
  same paths in one render (f_g = 30 MHz, T = 1.5 ms, low-pass sinusoid);
* time sampling: every method draws *pairs* of times (``n_times=2``, antithetic shift ½,
  mirror 0, stratified intervals: ``_common.paired_times``), so ``uniform`` x ``replay`` is two
  independent times replaying one path and ``adaptive`` (paired tracing,
  :mod:`dopplertof.tracing.paired`) gets the pairs it needs;
* scenes: ``cornell-box`` (boxes at ∓10 m/s, exposure [0, T]) and ``rotating`` (the
  merry-go-round, 3 m/s at the rim, exposure opening at half its clip,
  ``clip_duration("rotating") / 2``);
* moving pixels: from a reference render (antithetic x replay at ``--ref-spp``, its own
  seed): ground-truth |velocity| > 1 mm/s and coverage 1, eroded by one pixel (all eight
  neighbours moving too) so that silhouettes against the static background are left out;
* RMSE: over the moving pixels where the reconstruction is valid, pooled over the seeds
  (sqrt of the mean squared error of all of them); ``valid_fraction`` says how many are;
* time: wall time (``time.perf_counter``) of ``dopplertof.render``, median over the
  timed seeds. The first seed of each (estimator, spp) is the warm-up: the kernel depends
  on spp, so every configuration compiles (or loads Dr.Jit's kernel cache) once; it is not
  timed but its errors count. The sweep runs spp by spp, the estimators interleaved, so
  a change of load on the shared machine hits them alike; process CPU time is in the CSV;
* sensor noise: a 2-tap pixel with ``--full-well`` e⁻ per tap (default 20 000), read
  noise ``--read-noise`` e⁻ rms (3), 12-bit ADC at full well / 4000 e⁻ per DN, no ambient
  light; the light level is set so that in the reference's 99th-percentile brightest
  pixel each tap collects on average ``--fill`` x full well (0.5: 10 000 e⁻ per tap).
  The noise of seed i is drawn from the same stream for every estimator and spp (common
  random numbers), so differences between estimators are not sensor-noise luck;
* reference row: the reference's own RMSE (at 4096 spp still mostly Monte Carlo noise, not
  a model floor); with sensor noise (the sweep's noise streams) it is the sensor-noise
  floor of that light level;
* headline, measured: the time each estimator needs to reach a target RMSE (log-log
  interpolation between sweep points): without sensor noise the RMSE of uniform x replay
  at the largest spp, with sensor noise 1.1 x the sensor-noise floor. Where an estimator
  is below the target already at the smallest spp its time is a bound (≤, so the speed-up
  is ≥): a render's fixed cost (~0.03 s at 64x64) stops the time from falling further;
* headline, asymptotic: the efficiency 1/(MSE x time) at the largest spp relative to
  uniform x replay, i.e. the speed-up to equal RMSE where the MSE falls as 1/spp and the
  time grows as spp (the Monte Carlo regime; no sensor noise).

Outputs: a CSV with one row per (scene, estimator, spp, noise) plus the reference rows,
and a PNG (log-log RMSE against render time, one line per estimator, per scene and noise
setting), next to it; the tables are printed.
"""

from __future__ import annotations

import itertools
import math
import statistics
import sys
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

SCENE_NAMES = ("cornell-box", "rotating")
DEFAULT_METHODS = ("uniform", "stratified", "antithetic")
DEFAULT_CORRELATIONS = ("replay", "adaptive")
BASELINE = ("uniform", "replay")
REFERENCE = ("antithetic", "replay")
REFERENCE_SEED = 1_000_003  # the sweep uses seeds 0 .. seeds-1
MOVING_THRESHOLD_M_S = 1e-3
NOISE_SETTINGS = ("none", "sensor")
NEAR_FLOOR = 1.1  # with sensor noise, the target RMSE is this multiple of the sensor-noise floor
ADC_LEVELS_AT_FULL_WELL = 4000.0  # SensorModel's default: 20 000 e⁻ at 5 e⁻/DN in 12 bits


# ----------------------------------------------------------------------------------------
# Setup


def velocity_cameras():
    """h ∈ {0, 1} x ψ ∈ {0, π/2}: two matched homodyne/heterodyne pairs."""
    return [dopplertof.Camera(heterodyne=h, phase=psi) for psi in (0.0, math.pi / 2) for h in (0.0, 1.0)]


def exposure_start_s(name):
    """Scene time (s) at which the exposure opens: inside the motion of every scene."""
    if name == "cornell-box":
        return 0.0  # the boxes move during the first exposure only
    return dopplertof.scenes.clip_duration(name) / 2


def moving_mask(reference):
    """Moving pixels away from silhouettes: |v| > 1 mm/s, full coverage, eroded by one pixel."""
    speed = np.nan_to_num(np.abs(reference.velocity), nan=0.0)
    moving = (speed > MOVING_THRESHOLD_M_S) & (reference.coverage >= 1.0)
    padded = np.pad(moving, 1, constant_values=False)
    height, width = moving.shape
    eroded = moving.copy()
    for dy, dx in itertools.product((-1, 0, 1), repeat=2):
        eroded &= padded[1 + dy : 1 + dy + height, 1 + dx : 1 + dx + width]
    return eroded


def sensor_model(reference, camera, full_well_e, fill, read_noise_e):
    """A 2-tap sensor whose 99th-percentile pixel fills each tap to ``fill`` x full well.

    A tap collects κT(g0 I ± m)/2 e⁻ (:mod:`dopplertof.sensor`), on average κT g0 I / 2:
    solve for κ at the reference's 99th-percentile luminance I. The conversion gain keeps
    the full well at 4000 DN of the 12-bit ADC, as SensorModel's defaults do.
    """
    from dopplertof.sensor import SensorModel, luminance

    bright = float(np.percentile(luminance(reference.intensity), 99))
    if not bright > 0:
        raise ValueError("the reference image is black: no light reaches the camera")
    return SensorModel(
        electrons_per_unit=2.0 * fill * full_well_e / (camera.exposure * camera.g0 * bright),
        full_well_e=full_well_e,
        read_noise_e=read_noise_e,
        gain_e_per_dn=full_well_e / ADC_LEVELS_AT_FULL_WELL,
    )


# ----------------------------------------------------------------------------------------
# Measurement


def render(scene, cameras, method, correlation, spp, seed, args, start_s):
    return dopplertof.render(
        scene, cameras=cameras, spp=spp, seed=seed, max_depth=args.max_depth,
        correlation=correlation, **_common.paired_times(method),
        exposure_start=start_s,
    )  # fmt: skip


def velocity_maps(result, cameras, sensor, noise_seed):
    """{noise setting: reconstructed velocity (m/s, NaN = invalid)} of one render."""
    from dopplertof import reconstruct
    from dopplertof.sensor import luminance

    noisy = sensor.noisy_measurements(luminance(result.intensity), result.measurements, cameras, seed=noise_seed)
    return {
        "none": reconstruct.velocity(result.measurements, cameras, method="ratio").velocity,
        "sensor": reconstruct.velocity(noisy, cameras, method="ratio").velocity,
    }


def errors_on(estimate, truth, mask):
    """Signed errors (m/s) on the mask's pixels with a valid estimate, and how many were valid."""
    valid = mask & np.isfinite(estimate)
    return (estimate.astype(np.float64) - truth.astype(np.float64))[valid], int(valid.sum())


def summarize(errors, valid, pixels):
    """Error statistics pooled over renders: lists of error arrays and valid counts."""
    e = np.concatenate(errors) if errors else np.zeros(0)
    if e.size == 0:
        nan = float("nan")
        return dict(valid_fraction=0.0, rmse_m_s=nan, mae_m_s=nan, median_abs_error_m_s=nan, bias_m_s=nan)
    return dict(
        valid_fraction=sum(valid) / (pixels * len(valid)),
        rmse_m_s=float(np.sqrt(np.mean(e * e))),
        mae_m_s=float(np.mean(np.abs(e))),
        median_abs_error_m_s=float(np.median(np.abs(e))),
        bias_m_s=float(np.mean(e)),
    )


def noise_stream(args, seed):
    """The sensor-noise seed of render seed ``seed``: the same for every estimator and spp."""
    return np.random.SeedSequence([args.noise_seed, seed])


def bench_scene(name, args, log):
    t = time.perf_counter()
    scene = dopplertof.scenes.build(name, resolution=args.resolution)
    cameras = velocity_cameras()
    start_s = exposure_start_s(name)
    log(f"[{name}] {len(scene.bodies)} moving bodies, exposure opens at {start_s:g} s, loaded in {time.perf_counter() - t:.1f} s")

    t = time.perf_counter()
    reference = render(scene, cameras, *REFERENCE, args.ref_spp, REFERENCE_SEED, args, start_s)
    mask = moving_mask(reference)
    pixels = int(mask.sum())
    if pixels == 0:
        raise ValueError(f"{name}: no moving pixels away from silhouettes at {args.resolution}x{args.resolution}; raise --resolution")
    sensor = sensor_model(reference, cameras[0], args.full_well, args.fill, args.read_noise)
    rows = []
    # with the sweep's noise streams, so that the reference's sensor-noise RMSE is the floor under the sweep's
    ref_errors = {noise: ([], []) for noise in NOISE_SETTINGS}
    for seed in range(args.seeds):
        for noise, estimate in velocity_maps(reference, cameras, sensor, noise_stream(args, seed)).items():
            e, n_valid = errors_on(estimate, reference.velocity, mask)
            ref_errors[noise][0].append(e)
            ref_errors[noise][1].append(n_valid)
    for noise in NOISE_SETTINGS:
        rows.append(dict(scene=name, role="reference", method=REFERENCE[0], correlation=REFERENCE[1], spp=args.ref_spp, noise=noise, seeds=args.seeds, pixels=pixels, **summarize(*ref_errors[noise], pixels)))
    ref_rmse = {r["noise"]: r["rmse_m_s"] for r in rows}
    speeds = np.abs(reference.velocity[mask])
    log(
        f"[{name}] reference {REFERENCE[0]} x {REFERENCE[1]}, {args.ref_spp} spp: {time.perf_counter() - t:.1f} s; "
        f"{pixels} moving pixels (|v| {speeds.min():.2g} .. {speeds.max():.2g} m/s, mean {speeds.mean():.2g}); "
        f"its RMSE {ref_rmse['none']:.3g} m/s, with sensor noise {ref_rmse['sensor']:.3g} m/s; "
        f"sensor {sensor.electrons_per_unit:.3g} e-/(s radiance), full well {sensor.full_well_e:g} e-, read noise {sensor.read_noise_e:g} e-"
    )

    estimators = list(itertools.product(args.methods, args.correlations))
    for spp in args.spp:
        errors = {(est, noise): ([], []) for est in estimators for noise in NOISE_SETTINGS}
        wall = {est: [] for est in estimators}
        cpu = {est: [] for est in estimators}
        for seed in range(args.seeds):
            # estimators interleaved, their order rotated per seed: load on the shared machine hits all alike
            shift = seed % len(estimators)
            for method, correlation in estimators[shift:] + estimators[:shift]:
                t_wall, t_cpu = time.perf_counter(), time.process_time()
                result = render(scene, cameras, method, correlation, spp, seed, args, start_s)
                if seed > 0:  # seed 0 warms up (compiles the kernel of this spp)
                    wall[(method, correlation)].append(time.perf_counter() - t_wall)
                    cpu[(method, correlation)].append(time.process_time() - t_cpu)
                for noise, estimate in velocity_maps(result, cameras, sensor, noise_stream(args, seed)).items():
                    e, n_valid = errors_on(estimate, result.velocity, mask)
                    errors[((method, correlation), noise)][0].append(e)
                    errors[((method, correlation), noise)][1].append(n_valid)
        for method, correlation in estimators:
            est = (method, correlation)
            for noise in NOISE_SETTINGS:
                rows.append(dict(
                    scene=name, role="sweep", method=method, correlation=correlation, spp=spp, noise=noise,
                    seeds=args.seeds, pixels=pixels, **summarize(*errors[(est, noise)], pixels),
                    render_s=statistics.median(wall[est]), render_s_min=min(wall[est]), cpu_s=statistics.median(cpu[est]),
                ))  # fmt: skip
            clean, noisy = rows[-2], rows[-1]
            log(
                f"[{name}] {spp:5d} spp {method} x {correlation}: {clean['render_s']:.2f} s/render, "
                f"RMSE {clean['rmse_m_s']:.3g} m/s, with sensor noise {noisy['rmse_m_s']:.3g} m/s (valid {noisy['valid_fraction']:.0%})"
            )
    return rows


# ----------------------------------------------------------------------------------------
# Summaries


def curve(rows, scene, method, correlation, noise):
    """[(time s, RMSE m/s, spp)] of one estimator, by increasing spp."""
    sel = [r for r in rows if r["role"] == "sweep" and (r["scene"], r["method"], r["correlation"], r["noise"]) == (scene, method, correlation, noise)]
    return [(r["render_s"], r["rmse_m_s"], r["spp"]) for r in sorted(sel, key=lambda r: r["spp"])]


def time_to_reach(points, target):
    """(seconds, is_bound) until the RMSE falls to ``target``; None if never in the sweep.

    Log-log interpolation between the sweep points around the first crossing. Below the
    target at the smallest spp already: the time of that render, a bound (is_bound True).
    """
    for i, (t, rmse, _) in enumerate(points):
        if not rmse <= target:
            continue
        if i == 0:
            return t, True
        t0, r0, _ = points[i - 1]
        w = math.log(r0 / target) / math.log(r0 / rmse) if r0 != rmse else 1.0
        return math.exp(math.log(t0) + w * (math.log(t) - math.log(t0))), False
    return None


def targets_for(rows, scenes, noise):
    """{scene: target RMSE}: without sensor noise the RMSE of uniform x replay at its largest
    spp; with sensor noise 1.1 x the sensor-noise floor (the reference's RMSE)."""
    out = {}
    for scene in scenes:
        if noise == "sensor":
            ref = [r for r in rows if r["role"] == "reference" and r["scene"] == scene and r["noise"] == noise]
            if ref:
                out[scene] = NEAR_FLOOR * ref[0]["rmse_m_s"]
        else:
            base = curve(rows, scene, *BASELINE, noise)
            if base:
                out[scene] = base[-1][1]
    return out


def time_to_target(rows, scenes, estimators, noise):
    """{(scene, method, correlation): (target, seconds or None, is_bound, speed-up or None)}."""
    out = {}
    for scene, target in targets_for(rows, scenes, noise).items():
        base_t = time_to_reach(curve(rows, scene, *BASELINE, noise), target)
        for method, correlation in estimators:
            reached = time_to_reach(curve(rows, scene, method, correlation, noise), target)
            seconds, bound = reached if reached else (None, False)
            speedup = base_t[0] / seconds if reached and base_t and not base_t[1] else None
            out[(scene, method, correlation)] = (target, seconds, bound, speedup)
    return out


def rmse_table(rows, scene, estimators, spps, noise):
    """Markdown: rows estimators, columns spp; cells "RMSE m/s (render s)"."""
    index = {(r["method"], r["correlation"], r["spp"]): r for r in rows if r["role"] == "sweep" and r["scene"] == scene and r["noise"] == noise}
    lines = ["| time sampling | correlation | " + " | ".join(f"{s} spp" for s in spps) + " |", "|---|---|" + "---:|" * len(spps)]
    for method, correlation in estimators:
        cells = []
        for spp in spps:
            r = index.get((method, correlation, spp))
            cells.append("-" if r is None else f"{r['rmse_m_s']:.3g} ({r['render_s']:.2f} s)")
        lines.append(f"| {method} | {correlation} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def time_to_target_table(reached, scenes, estimators):
    """Markdown: per estimator and scene, the time to the target RMSE and the speed-up over
    uniform x replay ("≤" where the smallest spp is below the target already)."""
    lines = ["| time sampling | correlation | " + " | ".join(scenes) + " |", "|---|---|" + "---:|" * len(scenes)]
    for method, correlation in estimators:
        cells = []
        for scene in scenes:
            entry = reached.get((scene, method, correlation))
            if entry is None or entry[1] is None:
                cells.append("not reached")
                continue
            _, seconds, bound, factor = entry
            speedup = "" if factor is None else f" ({'≥ ' if bound else ''}{factor:.3g}x)"
            cells.append(f"{'≤ ' if bound else ''}{seconds:.2f} s{speedup}")
        lines.append(f"| {method} | {correlation} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def efficiency_table(rows, scenes, estimators):
    """Markdown: speed-up at equal RMSE over uniform x replay in the Monte Carlo regime.

    The efficiency 1/(MSE x time) at the largest spp relative to the baseline's: the time
    the baseline would need for this estimator's RMSE, extrapolated along MSE ∝ 1/spp and
    time ∝ spp from its own largest-spp point, over this estimator's time. Cells: with wall
    time (with process CPU time). Also returns {(scene, method, correlation): wall ratio}
    and per scene the baseline's log-log slope of RMSE against spp over its last two
    points (−0.5 where the extrapolation holds).
    """
    index = {}
    for r in rows:
        if r["role"] == "sweep" and r["noise"] == "none":
            best = index.get((r["scene"], r["method"], r["correlation"]))
            if best is None or r["spp"] > best["spp"]:
                index[(r["scene"], r["method"], r["correlation"])] = r
    lines = ["| time sampling | correlation | " + " | ".join(scenes) + " |", "|---|---|" + "---:|" * len(scenes)]
    ratios = {}
    for method, correlation in estimators:
        cells = []
        for scene in scenes:
            mine, base = index.get((scene, method, correlation)), index.get((scene, *BASELINE))
            if mine is None or base is None or not mine["rmse_m_s"] > 0:
                cells.append("-")
                continue
            mse = base["rmse_m_s"] ** 2 / mine["rmse_m_s"] ** 2
            ratios[(scene, method, correlation)] = mse * base["render_s"] / mine["render_s"]
            cells.append(f"{ratios[(scene, method, correlation)]:.3g}x ({mse * base['cpu_s'] / mine['cpu_s']:.3g}x)")
        lines.append(f"| {method} | {correlation} | " + " | ".join(cells) + " |")
    slopes = {}
    for scene in scenes:
        points = curve(rows, scene, *BASELINE, "none")
        if len(points) >= 2:
            (_, r0, s0), (_, r1, s1) = points[-2:]
            slopes[scene] = math.log(r1 / r0) / math.log(s1 / s0)
    return "\n".join(lines), ratios, slopes


def fastest_lines(reached, scenes, noise):
    """Per scene: the estimator that reaches the target first (measured)."""
    lines = []
    for scene in scenes:
        entries = [(key, v) for key, v in reached.items() if key[0] == scene and v[1] is not None]
        if not entries:
            continue
        (_, method, correlation), (target, seconds, bound, factor) = min(entries, key=lambda kv: kv[1][1])
        versus = "uniform x replay does not reach it in the sweep" if factor is None else f"{'≥ ' if bound else ''}{factor:.3g}x faster than uniform x replay"
        lines.append(
            f"measured, fastest to {target:.3g} m/s ({scene}, {'sensor noise' if noise == 'sensor' else 'no sensor noise'}): "
            f"{method} x {correlation}, {'≤ ' if bound else ''}{seconds:.2f} s; {versus}"
        )
    return lines


def plot(path, rows, scenes, estimators):
    from matplotlib.figure import Figure

    figure = Figure(figsize=(11, 3.9 * len(scenes)), layout="constrained")
    grid = figure.subplots(len(scenes), len(NOISE_SETTINGS), squeeze=False)
    methods = list(dict.fromkeys(m for m, _ in estimators))
    correlations = list(dict.fromkeys(c for _, c in estimators))
    styles = ["-", "--", ":", "-."]
    markers = ["o", "s", "^", "D"]
    for (row, scene), (col, noise) in itertools.product(enumerate(scenes), enumerate(NOISE_SETTINGS)):
        axes = grid[row][col]
        for method, correlation in estimators:
            points = curve(rows, scene, method, correlation, noise)
            if points:
                mi_, ci = methods.index(method), correlations.index(correlation)
                axes.loglog([p[0] for p in points], [p[1] for p in points], color=f"C{mi_}", linestyle=styles[ci % 4], marker=markers[ci % 4], markersize=4, label=f"{method} x {correlation}")
        ref = [r for r in rows if r["role"] == "reference" and r["scene"] == scene and r["noise"] == noise]
        if ref:
            axes.axhline(ref[0]["rmse_m_s"], color="grey", linestyle=":", linewidth=1, label=f"{REFERENCE[0]} x {REFERENCE[1]}, {ref[0]['spp']} spp (reference)")
        axes.set_title(f"{scene}, {'sensor noise' if noise == 'sensor' else 'no sensor noise'}")
        axes.set_xlabel("render wall time (s)")
        axes.set_ylabel("velocity RMSE, moving pixels (m/s)")
        axes.grid(True, which="both", alpha=0.3)
    _common.save_figure(figure, grid[0][0], path)


CSV_FIELDS = [
    "scene", "role", "method", "correlation", "spp", "noise", "seeds", "pixels", "valid_fraction",
    "rmse_m_s", "mae_m_s", "median_abs_error_m_s", "bias_m_s", "render_s", "render_s_min", "cpu_s",
]  # fmt: skip


# ----------------------------------------------------------------------------------------
# Command line


def parse_args(argv=None):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 64; quick 32)")
    p.add_argument("--spp", type=int, nargs="+", default=None, help="spp sweep, even values (default 4 16 64 256 1024; quick 4 32)")
    p.add_argument("--seeds", type=int, default=None, help="renders per (estimator, spp), the first one untimed warm-up (default 5; quick 2)")
    _common.add_sweep_options(p, SCENE_NAMES, ref_spp_help="default 4096; quick 256", methods=DEFAULT_METHODS, correlations=DEFAULT_CORRELATIONS)
    p.add_argument("--full-well", type=float, default=20_000.0, help="sensor full well per tap, e- (default 20000)")
    p.add_argument("--fill", type=float, default=0.5, help="mean tap charge of the 99th-percentile pixel / full well (default 0.5)")
    p.add_argument("--read-noise", type=float, default=3.0, help="read noise per tap, e- rms (default 3)")
    p.add_argument("--noise-seed", type=int, default=0, help="seed of the sensor noise (default 0)")
    _common.add_output_options(p, "velocity", quick_help="smoke test: 32x32, spp 4 and 32, 2 seeds, reference 256 spp (< 1 min)")
    args = p.parse_args(argv)
    quick = dict(resolution=32, spp=[4, 32], seeds=2, ref_spp=256)
    full = dict(resolution=64, spp=[4, 16, 64, 256, 1024], seeds=5, ref_spp=4096)
    _common.fill_defaults(args, quick if args.quick else full)
    _common.require_positive(p, args, ("resolution", "ref_spp", "max_depth"))
    if args.seeds < 2:
        p.error(f"--seeds must be at least 2 (the first one is the untimed warm-up), got {args.seeds}")
    bad = [s for s in args.spp if s <= 0 or s % 2] + ([args.ref_spp] if args.ref_spp % 2 else [])
    if bad:
        p.error(f"spp values must be positive and even (pairs of times), got {bad}")
    args.spp = sorted(set(args.spp))
    if not (args.full_well > 0 and math.isfinite(args.full_well)):
        p.error(f"--full-well must be a finite number > 0, got {args.full_well}")
    if not 0 < args.fill <= 1:
        p.error(f"--fill must be in (0, 1], got {args.fill}")
    if not (args.read_noise >= 0 and math.isfinite(args.read_noise)):
        p.error(f"--read-noise must be a finite number >= 0, got {args.read_noise}")
    _common.default_output_paths(args, "velocity")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = (
        f"settings: {args.resolution}x{args.resolution}, spp {' '.join(map(str, args.spp))}, {args.seeds} seeds per (estimator, spp) "
        f"(the first untimed warm-up), reference {REFERENCE[0]} x {REFERENCE[1]} {args.ref_spp} spp (seed {REFERENCE_SEED}), "
        f"max_depth {args.max_depth}, pairs of times (shifts 0.5 / mirror 0, stratified intervals), cameras h in (0, 1) x psi in (0, 90deg), "
        f"reconstruct.velocity(method='auto'); sensor: full well {args.full_well:g} e-, fill {args.fill:g} at the 99th-percentile pixel, "
        f"read noise {args.read_noise:g} e-, 12-bit ADC at {args.full_well / ADC_LEVELS_AT_FULL_WELL:g} e-/DN, noise seed {args.noise_seed}"
    )
    run = _common.Run("velocity", args, argv, settings)
    rows = [row for name in args.scenes for row in bench_scene(name, args, run.log)]
    estimators = list(itertools.product(args.methods, args.correlations))
    print()
    for scene, noise in itertools.product(args.scenes, NOISE_SETTINGS):
        label = "with sensor noise" if noise == "sensor" else "no sensor noise"
        ref = next(r for r in rows if r["role"] == "reference" and r["scene"] == scene and r["noise"] == noise)
        print(f"### {scene}, {label}: velocity RMSE on the moving pixels, m/s (median render time); reference ({REFERENCE[0]} x {REFERENCE[1]}, {ref['spp']} spp) {ref['rmse_m_s']:.3g} m/s")
        print(rmse_table(rows, scene, estimators, args.spp, noise))
        print()
    if BASELINE in estimators:
        headline = []
        for noise in NOISE_SETTINGS:
            reached = time_to_target(rows, args.scenes, estimators, noise)
            targets = targets_for(rows, args.scenes, noise)
            what = "uniform x replay's RMSE at the largest spp" if noise == "none" else f"{NEAR_FLOOR:g} x the sensor-noise floor"
            print(f"### {'with sensor noise' if noise == 'sensor' else 'no sensor noise'}: render time to reach {what} (speed-up over uniform x replay)")
            print(time_to_target_table(reached, args.scenes, estimators))
            print("targets: " + "; ".join(f"{k}: {v:.3g} m/s" for k, v in targets.items()))
            print()
            headline += fastest_lines(reached, args.scenes, noise)
        print(f"### no sensor noise, Monte Carlo regime: speed-up at equal RMSE over uniform x replay = efficiency 1/(MSE x time) at {args.spp[-1]} spp relative to uniform x replay's; wall time (CPU time)")
        table, ratios, slopes = efficiency_table(rows, args.scenes, estimators)
        print(table)
        print("uniform x replay, d log RMSE / d log spp over its last two points: " + "; ".join(f"{k}: {v:.2f}" for k, v in slopes.items()) + " (-0.5: the extrapolation holds)")
        print()
        for scene in args.scenes:
            best = max(((k, v) for k, v in ratios.items() if k[0] == scene), key=lambda kv: kv[1], default=None)
            if best is not None:
                headline.append(f"fastest at equal RMSE ({scene}, no sensor noise, Monte Carlo regime): {best[0][1]} x {best[0][2]}, {best[1]:.3g}x faster than uniform x replay")
        for line in headline:
            print(line)
    return run.finish(rows, CSV_FIELDS, plot=lambda path: plot(path, rows, args.scenes, estimators))


if __name__ == "__main__":
    sys.exit(main())
