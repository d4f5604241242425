#!/usr/bin/env python
"""Path-correlation policies over the ω_r sweep at equal render time (issue 18, item 4).

Replayed paths make an antithetic pair's two members one path at two times: at ω_r = 1
the static part of the pair cancels (the paper's two orders of magnitude), at ω_r = 0
(homodyne) the members are the same number and the pair counts as one sample, so full
correlation raises the homodyne RMSE by about √2 (the paper: 1.3–1.6×). This script
measures, with the paper-fig12 protocol (every camera h ∈ linspace(0, 1, 11) ×
ψ ∈ 2π·linspace(0, 1, 11) from one render, antithetic sampling, the RMSE × T of each camera
against the cached 131 072-spp reference, averaged over ψ), the policies that could avoid
that loss with all cameras in one render::

    python benchmarks/correlation_policy.py            # cornell-box and rotating, 32², 1024 spp, 3 timed repeats (1 min; 10 min more if the references are not cached)
    python benchmarks/correlation_policy.py --quick    # 16², 64 spp, reference 4096 spp, 3 ω_r (< 1 min)

========================  ================================================================
policy                    what a render does
========================  ================================================================
``none``                  independent paths (the original's path_correlation_depth 0)
``replay``                replayed paths, every bounce (depth 16, the default)
``replay-depth-2``        replay of the pixel sample and the first bounce only: the
                          partner follows the primal only where most of the cancellation
                          is (``correlation_depth=2``)
``split``                 half the paths replayed, half independent (two renders of spp/2,
                          different seeds), combined per camera with inverse-variance
                          weights (each half's image-mean squared standard error); the
                          "extra uncorrelated paths for the homodyne cameras" policy with
                          the best per-camera weights
========================  ================================================================

A per-camera weighting of the two members of a pair is not listed: the members' times
have the same distribution (antithetic and mirrored pairs are symmetric), so every camera's
best weight is ½, the present estimator.

Equal time: each policy's render is timed (median of ``--repeats`` renders with different
seeds, after one untimed warm-up that compiles the kernels; the process's CPU time of all
its threads, which other users of a shared machine disturb less than the wall clock, which
the CSV keeps too) and its RMSE is scaled to the time of ``replay``: RMSE · √(t / t_replay)
(the variance of a fixed estimator falls as 1/time). The reference's own variance is
subtracted from every mean squared error.

Outputs: ``benchmarks/results/correlation_policy.csv`` (one row per scene, policy and ω_r:
RMSE × T at equal spp and at equal time, and the ratios to ``none`` and ``replay``), the
tables printed.
"""

from __future__ import annotations

import math
import statistics
import sys
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

NAME = "correlation_policy"
POLICIES = ("none", "replay", "replay-depth-2", "split")


def _render(scene, cameras, settings, spp, seed, max_depth, lanes):
    """(result, (CPU seconds, wall seconds)) of one antithetic render with ``settings`` (a dict)."""
    from dopplertof.experiments.common import N_TIMES

    start = time.process_time(), time.perf_counter()
    result = dopplertof.render(
        scene.scene, cameras=cameras, spp=spp, seed=seed, max_depth=max_depth, time_sampling="antithetic", n_times=N_TIMES,
        lanes_per_pass=lanes, **scene.render_settings, **settings,  # stratified times: errors from their strata
    )  # fmt: skip
    return result, np.array([time.process_time() - start[0], time.perf_counter() - start[1]])


def _policy_images(policy, scene, cameras, spp, seed, max_depth, lanes):
    """(measurements (cameras, H, W), (CPU seconds, wall seconds)) of one render of ``policy``."""
    if policy == "split":
        (a, ta), (b, tb) = (_render(scene, cameras, {"correlation": c}, spp // 2, seed + k * 7919, max_depth, lanes) for k, c in enumerate(("replay", "none")))
        var_a = np.mean(np.square(a.measurement_stderr.astype(np.float64)), axis=(1, 2))
        var_b = np.mean(np.square(b.measurement_stderr.astype(np.float64)), axis=(1, 2))
        weight_a = (var_b / (var_a + var_b))[:, None, None]  # inverse-variance weight of the replayed half, per camera
        return weight_a * a.measurements + (1.0 - weight_a) * b.measurements, ta + tb
    settings = {"correlation": "replay", "correlation_depth": 2} if policy == "replay-depth-2" else {"correlation": policy}
    result, seconds = _render(scene, cameras, settings, spp, seed, max_depth, lanes)
    return result.measurements, seconds


def main(argv=None):
    parser = _common.argument_parser(__doc__)
    parser.add_argument("--scenes", nargs="+", default=["cornell-box", "rotating"], help="built-in scenes (default cornell-box rotating)")
    parser.add_argument("--resolution", type=int, default=None, help="film size (default 32; quick 16)")
    parser.add_argument("--spp", type=int, default=None, help="paths per pixel of each policy's render (default 1024; quick 64)")
    parser.add_argument("--ref-spp", type=int, default=None, help="paths per pixel of the reference (default 131072; quick 4096)")
    parser.add_argument("--repeats", type=int, default=None, help="timed renders per policy, seeds 0.. (default 3; quick 2)")
    parser.add_argument("--h-steps", type=int, default=None, help="ω_r from 0 to 1 (default 11; quick 3)")
    parser.add_argument("--cache", default=None, help="reference cache (default: the experiments' cache)")
    _common.add_output_options(parser, NAME, "16², 64 spp, reference 4096 spp, 3 ω_r × 3 ψ", plot=False)
    args = parser.parse_args(argv)
    quick = args.quick
    _common.fill_defaults(args, dict(resolution=16 if quick else 32, spp=64 if quick else 1024, ref_spp=4096 if quick else 131072, repeats=2 if quick else 3, h_steps=3 if quick else 11))
    _common.require_positive(parser, args, ["resolution", "spp", "ref_spp", "repeats"])
    _common.default_output_paths(args, NAME)
    settings_line = f"settings: {args.resolution}², {args.spp} spp, reference {args.ref_spp} spp, {args.repeats} repeats, {args.h_steps} ω_r"
    run = _common.Run(NAME, args, argv, settings_line)

    from dopplertof.experiments.common import ReferenceCache, default_cache_dir, image_errors, open_scene, reference_render, sweep_lanes_per_pass
    from dopplertof.experiments.paper import protocol_max_depth, protocol_phases
    from dopplertof.experiments.sweeps import SweepSettings, evenly_spaced, folded_phases, sweep_cameras

    cache = ReferenceCache(args.cache or default_cache_dir())
    rows = []
    for name in args.scenes:
        scene = open_scene(name, args.resolution)
        depth = protocol_max_depth(scene)
        sweep = SweepSettings(evenly_spaced(args.h_steps, "--h-steps"), protocol_phases(3 if quick else 11), args.spp, args.ref_spp, 0, depth)
        cameras = sweep_cameras(scene.base_camera, sweep)
        _, index = folded_phases(sweep.phases_rad)
        lanes = sweep_lanes_per_pass(len(cameras))
        reference = reference_render(scene, cameras, args.ref_spp, 0, depth, cache, run.log, sweep.replicates, lanes)
        ref_var = np.mean(np.square(reference.measurement_stderr.astype(np.float64)), axis=(1, 2))
        n_rendered = len(cameras) // len(sweep.h_values)
        results = {}
        for policy in POLICIES:
            _policy_images(policy, scene, cameras, args.spp, 1000, depth, lanes)  # warm-up: compiles the kernels
            seconds, mse = [], []
            for seed in range(args.repeats):
                images, t = _policy_images(policy, scene, cameras, args.spp, seed, depth, lanes)
                seconds.append(t)
                mse.append([image_errors(images[i], reference.measurements[i])["rmse"] ** 2 - ref_var[i] for i in range(len(cameras))])
            mse = np.mean(mse, axis=0)
            # RMSE per camera, then the mean over ψ (a ψ ≥ π repeats the folded ψ − π's error), as the protocol
            rmse = [np.mean([math.sqrt(max(mse[j * n_rendered + k], 0.0)) for k in index]) * cameras[j * n_rendered].exposure for j in range(len(sweep.h_values))]
            cpu, wall = (statistics.median(s[k] for s in seconds) for k in (0, 1))
            results[policy] = (cpu, np.array(rmse), wall)
            run.log(f"{name}: {policy}: median CPU {cpu:.2f} s ({', '.join(f'{s[0]:.2f}' for s in seconds)}), wall {wall:.2f} s")
        t_replay = results["replay"][0]
        equal_time = {p: rmse * math.sqrt(t / t_replay) for p, (t, rmse, _) in results.items()}
        print(f"\n{name} ({args.resolution}², {args.spp} spp, max_depth {depth}): RMSE × T at the time of replay, ÷ min(none, replay) at equal time")
        print("| policy | CPU s | " + " | ".join(f"ω_r {h:g}" for h in sweep.h_values) + " |")
        print("|---|---:|" + "---:|" * len(sweep.h_values))
        best = np.minimum(equal_time["none"], equal_time["replay"])
        for policy, (t, rmse, wall) in results.items():
            print(f"| {policy} | {t:.2f} | " + " | ".join(f"{e:.3g} ({e / b:.2f})" for e, b in zip(equal_time[policy], best)) + " |")
            for j, h in enumerate(sweep.h_values):
                rows.append({
                    "scene": name, "policy": policy, "h": h, "spp": args.spp, "cpu_seconds": t, "wall_seconds": wall, "rmse_x_exposure": float(rmse[j]),
                    "rmse_x_exposure_equal_time": float(equal_time[policy][j]),
                    "ratio_to_none_equal_time": float(equal_time[policy][j] / equal_time["none"][j]),
                    "ratio_to_replay_equal_time": float(equal_time[policy][j] / equal_time["replay"][j]),
                })  # fmt: skip
    return run.finish(rows, list(rows[0]))


if __name__ == "__main__":
    sys.exit(main())
