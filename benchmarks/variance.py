#!/usr/bin/env python
"""Variance of the D-ToF estimators: MSE against a high-spp reference at equal spp.

For every time sampling (``dopplertof.timesampling.METHODS``) x correlation
(``dopplertof.correlation.MODES``, so modes added later are picked up) it renders a scene
``--repeats`` times at ``--spp`` paths per pixel (different seeds), all six cameras
h ∈ {0, ½, 1} x ψ ∈ {0, π/2} from the same paths in one render, and measures per camera
the mean squared error against a reference::

    python benchmarks/variance.py            # 64x64, 64 spp x 8 repeats, reference 32768 spp, depth 4 (~3 min, 2 cores)
    python benchmarks/variance.py --quick    # 16x16, 16 spp x 2 repeats, reference 2048 spp (< 1 min)
    python benchmarks/variance.py --scenes cornell-box --methods uniform antithetic --correlations none replay

Definitions:

* time sampling: every method draws *pairs* of times (``n_times=2``; the render defaults
  otherwise: antithetic shift ½, mirror shift 0, per-interval stratification on), so
  ``uniform`` x ``replay`` means two independent times that replay the same path;
  ``uniform`` x ``none`` is plain independent sampling. Stratified times take their
  standard errors from their strata (each interval stratified over all of a pixel's
  groups); uniform renders use 2 replicates per pixel
  (``dopplertof.experiments.common.SWEEP_REPLICATES``, as the ``experiment`` sweeps);
* reference: one render with antithetic + replay at ``--ref-spp`` and a seed no test
  render uses. Its own variance (mean of its squared standard errors over the region) is
  **subtracted** from the raw mean squared difference, so that MSE estimates the error
  against the true image; the CSV keeps the raw value and the reference's share of it
  (``ref_var_fraction``: where it is not small the ratio is capped by reference noise);
* MSE per camera and region: mean over the region's pixels of (x − ref)², averaged over
  the repeats, minus the reference variance; per h, the MSEs of the two ψ are summed;
* regions: ``all`` (the whole image) and ``moving`` (pixels whose reference ground-truth
  ``velocity`` or ``point_velocity`` exceeds 1 mm/s in magnitude: the moving bodies);
* ratios: "N x lower MSE" = MSE(baseline) / MSE(configuration), against ``uniform`` x
  ``none`` and against ``uniform`` with the same correlation; for correlations other
  than none/pixel/replay (reconnection, adaptive) also against ``replay`` with the same
  time sampling (> 1: better than replay).

* ``bias_z``: the region's summed difference to the reference over its standard error, a
  global bias check. The reference uses antithetic + replay itself, so a bias that
  estimator shares with its reference would not show in its own MSE; the other
  configurations check it.

Scenes: ``cornell-box`` (built-in, boxes at ∓10 m/s) and ``rotating``: the built-in
merry-go-round of that name when ``dopplertof.scenes.SCENES`` has one, else
:func:`rotating_body_scene` (a turntable with two boxes in the Cornell room, 9 m/s).

Outputs: a CSV with one row per (scene, time sampling, correlation, camera, region) and a
PNG of the MSE ratios against h, next to it; the tables are printed.
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
from _common import CAMERA_GRID, diffuse, paired_times, transform
from dopplertof.experiments.common import SWEEP_REPLICATES
from dopplertof.timesampling import stratifies

SCENE_NAMES = ("cornell-box", "rotating")
HETERODYNES = (0.0, 0.5, 1.0)
REGIONS = ("all", "moving")
MOVING_THRESHOLD_M_S = 1e-3
REFERENCE = ("antithetic", "replay")
REFERENCE_SEED = 1_000_003  # the test renders use seeds 0 .. repeats-1
BASE_CORRELATIONS = ("none", "pixel", "replay")
TURNTABLE_RATE_RAD_S = 20.0


# ----------------------------------------------------------------------------------------
# Scenes


def rotating_body_scene(resolution=64, exposure=1.5e-3):
    """A turntable in the Cornell room: fallback for a missing built-in ``rotating`` scene.

    Room, camera (0, 1, 6.8) and point light at the camera as in ``cornell-box``. A square
    platform (1.2 m x 1.2 m x 8 cm) and two boxes on it (centres at x = ±0.45 m, 0.25 m
    and 0.4 m tall) rotate together about the vertical axis through the room's centre at
    ``TURNTABLE_RATE_RAD_S`` (20 rad/s: the boxes' centres move at 9 m/s, 0.03 rad turn
    during the exposure), so the left box approaches the camera and the right one recedes.
    """
    from dopplertof.scenes import WHITE

    turning = {"type": "parametric", "angular_velocity": [0.0, TURNTABLE_RATE_RAD_S, 0.0], "pivot": [0.0, 0.0, 0.0]}
    scene = _common.cornell_room(resolution)
    scene["platform"] = {"type": "cube", "bsdf": diffuse(WHITE), "to_world": transform((0, 0.04, 0), rotate_y_deg=30, scale=(0.6, 0.04, 0.6)), "motion": turning}
    scene["left-box"] = {"type": "cube", "bsdf": diffuse(WHITE), "to_world": transform((-0.45, 0.33, 0), rotate_y_deg=20, scale=(0.15, 0.25, 0.15)), "motion": turning}
    scene["right-box"] = {"type": "cube", "bsdf": diffuse(WHITE), "to_world": transform((0.45, 0.28, 0), rotate_y_deg=-25, scale=(0.15, 0.2, 0.15)), "motion": turning}
    return dopplertof.load_scene(scene)


def build_scene(name, resolution):
    """(scene, description) of a benchmark scene."""
    from dopplertof import scenes

    if name in scenes.SCENES:
        return scenes.build(name, resolution=resolution), f"built-in {name!r}"
    if name == "rotating":
        return rotating_body_scene(resolution), "benchmark fallback turntable (benchmarks/variance.py: rotating_body_scene)"
    raise ValueError(f"unknown scene {name!r}")


# ----------------------------------------------------------------------------------------
# Measurement


def moving_mask(reference):
    """Pixels of the moving bodies: |velocity| or |point_velocity| above 1 mm/s."""
    speeds = np.nan_to_num(np.maximum(np.abs(reference.velocity), np.abs(reference.point_velocity)), nan=0.0)
    return speeds > MOVING_THRESHOLD_M_S


def render_config(scene, cameras, method, correlation, spp, seed, max_depth):
    return dopplertof.render(
        scene, cameras=cameras, spp=spp, seed=seed, max_depth=max_depth, correlation=correlation, **paired_times(method),
        **({} if stratifies(method, True) else {"replicates": SWEEP_REPLICATES}),  # stratified times: errors from their strata
    )


def measure_config(scene, cameras, method, correlation, args, reference, masks):
    """Per (camera, region): MSE statistics over ``args.repeats`` renders; None if unsupported."""
    ref = reference.measurements.astype(np.float64)
    ref_var = reference.measurement_stderr.astype(np.float64) ** 2
    raw = {key: [] for key in itertools.product(range(len(cameras)), masks)}
    own_var = {key: [] for key in raw}
    diff_sum = {key: [] for key in raw}
    diff_var = {key: [] for key in raw}
    seconds = []
    for rep in range(args.repeats):
        t = time.perf_counter()
        try:
            result = render_config(scene, cameras, method, correlation, args.spp, rep, args.max_depth)
        except ValueError as exc:  # a combination the renderer rejects (e.g. a mode needing other times)
            return None, str(exc)
        seconds.append(time.perf_counter() - t)
        x = result.measurements.astype(np.float64)
        var = result.measurement_stderr.astype(np.float64) ** 2
        for (i, region), mask in ((k, masks[k[1]]) for k in raw):
            d = x[i][mask] - ref[i][mask]
            raw[(i, region)].append(float(np.mean(d * d)))
            own_var[(i, region)].append(float(np.mean(var[i][mask])))
            diff_sum[(i, region)].append(float(d.sum()))
            diff_var[(i, region)].append(float(var[i][mask].sum()))
    stats = {}
    for key in raw:
        i, region = key
        reps = raw[key]
        ref_var_mean = float(np.mean(ref_var[i][masks[region]]))
        mse_raw = statistics.fmean(reps)
        sem = statistics.stdev(reps) / math.sqrt(len(reps)) if len(reps) > 1 else float("nan")
        # z of the region's summed difference: a global bias check of this estimator vs the reference
        # (the reference is shared by the repeats, so its variance does not average down)
        z_var = statistics.fmean(diff_var[key]) / len(reps) + float(ref_var[i][masks[region]].sum())
        z = statistics.fmean(diff_sum[key]) / math.sqrt(z_var)
        stats[key] = dict(
            mse=mse_raw - ref_var_mean, mse_raw=mse_raw, mse_sem=sem, ref_var=ref_var_mean,
            ref_var_fraction=ref_var_mean / mse_raw if mse_raw > 0 else float("nan"),
            own_var=statistics.fmean(own_var[key]), bias_z=z,
            ref_rms=float(np.sqrt(np.mean(ref[i][masks[region]] ** 2))),
            render_s=statistics.median(seconds),
        )
    return stats, None


def bench_scene(name, args, log):
    t = time.perf_counter()
    scene, description = build_scene(name, args.resolution)
    cameras = [dopplertof.Camera(heterodyne=h, phase=psi) for h, psi in CAMERA_GRID]
    log(f"[{name}] {description}: {len(scene.bodies)} moving bodies, loaded in {time.perf_counter() - t:.1f} s")
    t = time.perf_counter()
    reference = render_config(scene, cameras, *REFERENCE, args.ref_spp, REFERENCE_SEED, args.max_depth)
    log(f"[{name}] reference {REFERENCE[0]} + {REFERENCE[1]}, {args.ref_spp} spp: {time.perf_counter() - t:.1f} s")
    masks = {"all": np.ones(reference.measurements.shape[1:], dtype=bool), "moving": moving_mask(reference)}
    n_moving = int(masks["moving"].sum())
    log(f"[{name}] moving pixels: {n_moving} of {masks['moving'].size}")
    if n_moving == 0:
        del masks["moving"]
    rows = []
    configs = list(itertools.product(args.methods, args.correlations))
    for k, (method, correlation) in enumerate(configs):
        stats, error = measure_config(scene, cameras, method, correlation, args, reference, masks)
        if stats is None:
            log(f"[{name}] {k + 1}/{len(configs)} {method} x {correlation}: skipped ({error})")
            continue
        for (i, region), s in stats.items():
            h, psi = CAMERA_GRID[i]
            rows.append(dict(scene=name, scene_source=description, method=method, correlation=correlation, h=h, psi=psi, region=region, pixels=int(masks[region].sum()), **s))
        h1 = sum(stats[(i, "all")]["mse"] for i, (h, _) in enumerate(CAMERA_GRID) if h == 1.0)
        log(f"[{name}] {k + 1}/{len(configs)} {method} x {correlation}: {stats[(0, 'all')]['render_s']:.2f} s/render, MSE(h=1, all) {h1:.3e}")
    return rows


# ----------------------------------------------------------------------------------------
# Summaries


def per_h(rows):
    """{(scene, method, correlation, region, h): MSE summed over ψ}."""
    out = {}
    for r in rows:
        key = (r["scene"], r["method"], r["correlation"], r["region"], r["h"])
        out[key] = out.get(key, 0.0) + r["mse"]
    return out


def add_ratios(rows):
    """Ratios per camera row: baseline MSE / this MSE (> 1: lower MSE than the baseline)."""
    index = {(r["scene"], r["method"], r["correlation"], r["h"], r["psi"], r["region"]): r for r in rows}

    def ratio(r, method, correlation):
        base = index.get((r["scene"], method, correlation, r["h"], r["psi"], r["region"]))
        return base["mse"] / r["mse"] if base is not None and r["mse"] > 0 else float("nan")

    for r in rows:
        r["ratio_vs_uniform_none"] = ratio(r, "uniform", "none")
        r["ratio_vs_uniform_same_corr"] = ratio(r, "uniform", r["correlation"])
        r["ratio_vs_replay_same_method"] = ratio(r, r["method"], "replay")


def ratio_table(sums, scene, region, methods, correlations):
    """Markdown: rows (method x correlation), columns h; cells "A (B)" with A = MSE(uniform x
    none) / MSE and B = MSE(uniform x same correlation) / MSE, ψ summed."""
    lines = ["| time sampling | correlation | " + " | ".join(f"h = {h:g}" for h in HETERODYNES) + " |", "|---|---|" + "---:|" * len(HETERODYNES)]
    for method, correlation in itertools.product(methods, correlations):
        if (scene, method, correlation, region, 0.0) not in sums:
            continue
        cells = []
        for h in HETERODYNES:
            mse = sums[(scene, method, correlation, region, h)]
            ratios = []
            for base_key in ((scene, "uniform", "none", region, h), (scene, "uniform", correlation, region, h)):
                base = sums.get(base_key)
                ratios.append("-" if base is None or mse <= 0 else f"{base / mse:.3g}x")
            cells.append(f"{ratios[0]} ({ratios[1]})")
        lines.append(f"| {method} | {correlation} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def target_lines(sums, rows):
    """The issue's target: antithetic x replay >= 300x lower MSE than uniform x none, Cornell box, h = 1."""
    lines = []
    for region in REGIONS:
        mine = sums.get(("cornell-box", "antithetic", "replay", region, 1.0))
        base = sums.get(("cornell-box", "uniform", "none", region, 1.0))
        if mine and base:
            # relative standard error of the ratio from the repeat-to-repeat spread of both MSEs
            sel = [r for r in rows if r["scene"] == "cornell-box" and r["region"] == region and r["h"] == 1.0 and r["correlation"] in ("replay", "none")]
            rel = [r["mse_sem"] / r["mse"] for r in sel if (r["method"], r["correlation"]) in (("antithetic", "replay"), ("uniform", "none"))]
            spread = math.sqrt(sum(x * x for x in rel)) if rel and all(math.isfinite(x) for x in rel) else float("nan")
            verdict = "met" if base / mine >= 300 else "NOT met"
            lines.append(f"target (cornell-box, {region} pixels, h = 1): antithetic x replay {base / mine:.0f}x lower MSE than uniform x none (± {spread:.0%}); >= 300x {verdict}")
    return lines


def beyond_replay_lines(sums, scenes, methods, correlations):
    """Where each correlation other than none/pixel/replay beats replay, and by how much."""
    extra = [c for c in correlations if c not in BASE_CORRELATIONS]
    if "replay" not in correlations or not extra:
        return [f"no correlation beyond {', '.join(BASE_CORRELATIONS)} in this run (MODES: {', '.join(correlations)})"]
    lines = []
    for scene, correlation in itertools.product(scenes, extra):
        parts = []
        for method, region, h in itertools.product(methods, REGIONS, HETERODYNES):
            mine = sums.get((scene, method, correlation, region, h))
            replay = sums.get((scene, method, "replay", region, h))
            if mine and replay:
                parts.append(f"{method}/{region}/h={h:g}: {replay / mine:.2f}x")
        lines.append(f"{scene}, {correlation} vs replay (replay MSE / its MSE, > 1 = better): " + "; ".join(parts))
    return lines


def plot(path, sums, scenes, methods, correlations):
    from matplotlib.figure import Figure

    regions = [r for r in REGIONS if any(k[3] == r for k in sums)]
    figure = Figure(figsize=(5.2 * len(regions) + 2.6, 3.8 * len(scenes)), layout="constrained")
    grid = figure.subplots(len(scenes), len(regions), squeeze=False)
    styles = ["-", "--", ":", "-.", (0, (5, 1, 1, 1, 1, 1))]
    for row, scene in enumerate(scenes):
        for col, region in enumerate(regions):
            axes = grid[row][col]
            for (mi_, method), (ci, correlation) in itertools.product(enumerate(methods), enumerate(correlations)):
                keys = [(scene, method, correlation, region, h) for h in HETERODYNES]
                base = [sums.get((scene, "uniform", "none", region, h)) for h in HETERODYNES]
                if not all(k in sums for k in keys) or None in base:
                    continue
                y = [b / sums[k] if sums[k] > 0 else np.nan for b, k in zip(base, keys)]
                axes.semilogy(HETERODYNES, y, marker="o", markersize=3, color=f"C{mi_}", linestyle=styles[ci % len(styles)], label=f"{method} x {correlation}")
            axes.set_title(f"{scene}, {region} pixels")
            axes.set_xlabel("heterodyne h (cycles per exposure)")
            axes.set_ylabel("MSE(uniform x none) / MSE")
            axes.set_xticks(HETERODYNES)
            axes.grid(True, which="both", alpha=0.3)
    _common.save_figure(figure, grid[0][0], path)


CSV_FIELDS = [
    "scene", "scene_source", "method", "correlation", "h", "psi", "region", "pixels",
    "mse", "mse_raw", "mse_sem", "ref_var", "ref_var_fraction", "own_var", "ref_rms", "bias_z",
    "ratio_vs_uniform_none", "ratio_vs_uniform_same_corr", "ratio_vs_replay_same_method", "render_s",
]


def parse_args(argv=None):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 64; quick 16)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel of each test render (even; default 64; quick 16)")
    p.add_argument("--repeats", type=int, default=None, help="test renders (seeds) per configuration (default 8; quick 2)")
    _common.add_sweep_options(p, SCENE_NAMES, ref_spp_help="default 32768; quick 2048")
    _common.add_output_options(p, "variance", quick_help="smoke test: 16x16, 16 spp x 2, reference 2048 spp (< 1 min)")
    args = p.parse_args(argv)
    _common.fill_defaults(args, dict(resolution=16, spp=16, repeats=2, ref_spp=2048) if args.quick else dict(resolution=64, spp=64, repeats=8, ref_spp=32768))
    _common.require_positive(p, args, ("resolution", "spp", "repeats", "ref_spp", "max_depth"))
    if args.spp % 2 or args.ref_spp % 2:
        p.error(f"--spp and --ref-spp must be even (pairs of times), got {args.spp} and {args.ref_spp}")
    if "uniform" not in args.methods or "none" not in args.correlations:
        p.error("the baseline uniform x none must be part of the run (keep 'uniform' in --methods and 'none' in --correlations)")
    _common.default_output_paths(args, "variance")
    return args


def main(argv=None):
    from dopplertof.correlation import MODES

    args = parse_args(argv)
    settings = (
        f"settings: {args.resolution}x{args.resolution}, {args.spp} spp x {args.repeats} seeds per configuration, "
        f"reference {REFERENCE[0]} + {REFERENCE[1]} {args.ref_spp} spp (seed {REFERENCE_SEED}, variance subtracted), "
        f"max_depth {args.max_depth}, pairs of times (shifts 0.5 / mirror 0, stratified intervals; uniform: {SWEEP_REPLICATES} replicates)"
    )
    run = _common.Run("variance", args, argv, settings, f"correlation MODES: {', '.join(MODES)}")
    rows = [row for name in args.scenes for row in bench_scene(name, args, run.log)]
    add_ratios(rows)
    sums = per_h(rows)
    scenes = [s for s in args.scenes if any(r["scene"] == s for r in rows)]
    print()
    for scene in scenes:
        for region in REGIONS:
            if not any(k[0] == scene and k[3] == region for k in sums):
                continue
            print(f"### {scene}, {region} pixels: MSE(uniform x none) / MSE (in brackets: MSE(uniform x same correlation) / MSE); ψ summed")
            print(ratio_table(sums, scene, region, args.methods, args.correlations))
            print()
    for line in target_lines(sums, rows) + beyond_replay_lines(sums, scenes, args.methods, args.correlations):
        print(line)
    worst = max(rows, key=lambda r: r["ref_var_fraction"])
    print(
        f"reference noise: largest share of the raw MSE {worst['ref_var_fraction']:.1%} "
        f"({worst['scene']}, {worst['method']} x {worst['correlation']}, h={worst['h']:g}, {worst['region']}); subtracted"
    )
    worst_z = max(rows, key=lambda r: abs(r["bias_z"]))
    print(f"largest |z| of a region-sum difference to the reference: {worst_z['bias_z']:.1f} ({worst_z['scene']}, {worst_z['method']} x {worst_z['correlation']}, h={worst_z['h']:g}, psi={worst_z['psi']:.3g}, {worst_z['region']})")
    return run.finish(rows, CSV_FIELDS, plot=lambda path: plot(path, sums, scenes, args.methods, args.correlations))


if __name__ == "__main__":
    sys.exit(main())
