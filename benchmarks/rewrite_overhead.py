#!/usr/bin/env python
"""Cost of the core rewrite (one bounce, tracing/ package): the current renderer against the
one before it, side by side in one process, on the scenes and configurations of
``throughput.py``::

    python benchmarks/rewrite_overhead.py            # 256x256, 32 spp, 5 reps (~5 min on 2 cores)
    python benchmarks/rewrite_overhead.py --quick    # 64x64, 8 spp, 3 reps
    python benchmarks/rewrite_overhead.py --reps 15 --scenes 2-moving   # one scene, more repetitions

The baseline is the package at git commit ``BASELINE`` (the last commit before the
rewrite), extracted with ``git archive`` into a temporary folder and imported as
``dopplertof_baseline`` (its imports are relative). Both render the same scene dicts with
the same settings; runs are interleaved (baseline, current, baseline, …) after one warm-up
each, and the table reports median times and the ratio current / baseline per row.
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time

import dopplertof  # noqa: I001 - sets the libLLVM path before drjit

import _common
import throughput

BASELINE = "bba5c87"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--reps", type=int, default=None)
    parser.add_argument("--scenes", nargs="+", choices=("static", "2-moving", "8-moving"), default=["static", "2-moving", "8-moving"])
    parser.add_argument("--csv", default=None, help="CSV output (default benchmarks/results/rewrite_overhead.csv; quick: rewrite_overhead_quick.csv)")
    args = parser.parse_args(argv)
    _common.default_output_paths(args, "rewrite_overhead")
    resolution, spp, reps = (64, 8, 3) if args.quick else (256, 32, 5)
    reps = args.reps or reps
    dopplertof.set_variant("llvm_ad_rgb")
    with tempfile.TemporaryDirectory() as folder:
        old = _common.import_baseline(BASELINE, folder)
        print(_common.machine_line("llvm_ad_rgb", f"{resolution}x{resolution}", f"{spp} spp", f"{reps} reps", f"baseline {BASELINE}"))
        cam1 = [dict(heterodyne=1.0)]
        cam4 = [dict(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
        rows = []
        for name in args.scenes:
            ours_dict, _ = throughput.scene_dicts(name, resolution, 5)
            scenes = {"baseline": old.load_scene(ours_dict), "current": dopplertof.load_scene(ours_dict)}
            packages = {"baseline": old, "current": dopplertof}
            configs = {
                "intensity": dict(time_sampling="uniform"),
                "dtof1": dict(cameras=cam1, time_sampling="antithetic", correlation="replay"),
                "dtof4": dict(cameras=cam4, time_sampling="antithetic", correlation="replay"),
            }
            for config, kwargs in configs.items():
                def run(which, seed):
                    package = packages[which]
                    options = {**kwargs, "cameras": [package.Camera(**c) for c in kwargs.get("cameras", [])]}
                    start = time.perf_counter()
                    package.render(scenes[which], spp=spp, seed=seed, max_depth=5, **options)
                    return time.perf_counter() - start

                for which in packages:  # warm-up: kernel compilation
                    run(which, 0)
                times = {"baseline": [], "current": []}
                for rep in range(reps):
                    order = ("baseline", "current") if rep % 2 == 0 else ("current", "baseline")
                    for which in order:
                        times[which].append(run(which, rep + 1))
                base, cur = statistics.median(times["baseline"]), statistics.median(times["current"])
                rows.append({"scene": name, "config": config, "baseline_s": base, "current_s": cur, "ratio": cur / base,
                             "ratio_min": min(c / b for b, c in zip(times["baseline"], times["current"])),
                             "ratio_max": max(c / b for b, c in zip(times["baseline"], times["current"]))})
                print(f"{name:9s} {config:9s} baseline {base:7.3f} s  current {cur:7.3f} s  current/baseline {cur / base:5.3f}", flush=True)
    print("\n| scene | configuration | baseline (s) | current (s) | current / baseline (min–max) |\n|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['config']} | {r['baseline_s']:.3f} | {r['current_s']:.3f} | {r['ratio']:.3f} ({r['ratio_min']:.2f}–{r['ratio_max']:.2f}) |")
    _common.write_csv(args.csv, rows, list(rows[0]), {"baseline": BASELINE, "resolution": resolution, "spp": spp, "reps": reps})


if __name__ == "__main__":
    main()
