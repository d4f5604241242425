#!/usr/bin/env python
"""The first render of a new scene, compilation included: the per-body loop, the tree and
the body atlas.

    python benchmarks/first_render.py            # 256x256, 32 spp, 2/8/16/32/64 moving cubes (~6 min, 2 cores)
    python benchmarks/first_render.py --quick    # smoke test: 32x32, 8 spp, 2 and 16 cubes (< 1 min)
    python benchmarks/first_render.py --scenes 128-moving 1024-moving --traversals tree atlas
    python benchmarks/first_render.py --variant cuda_ad_rgb --traversals per-body atlas --timeout-s 120
    python benchmarks/first_render.py --scenes 8-moving 128-moving --traversals tree slices   # one scene per instant

``throughput.py`` times renders whose kernels are compiled already (its warm-up run is not
timed); a new scene's first render also compiles its kernel, which with the per-body loop
grows with the number of bodies (the loop is unrolled: each body's queries are code) and
with the tree does not (the bodies are reached through one ``dr.switch``, or, with the atlas,
one trace against a scene of every body: CUDA's traversal; with ``slices``, one query
of one member scene whatever the number of bodies, its pass recorded by ``dr.freeze``).
Every new scene pays it: each sample of a dataset, each scene of a design study. This
script renders each scene of ``throughput.py`` (D-ToF, 4 cameras, antithetic + replay) with
each traversal in a process of its own whose Dr.Jit kernel cache is empty (a temporary
``$HOME``), and reports per render: the first render's wall time, the part of it Dr.Jit
spent compiling and the number of kernels it compiled (kernel history), a second render's
wall time (another seed: the kernel cached), and the first render again in a new process
that finds the first process's kernels in Dr.Jit's cache on disk (what a render of the same
scene from the command line pays). Before them it times loading the scene
(``dopplertof.load_scene``: one Mitsuba scene per body, each body's swept box over the
exposure, the tree) beside stock ``mi.load_dict`` of the same geometry baked static, after
a warm-up load of one cube.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
import throughput

TRAVERSALS = ("per-body", "tree", "atlas", "slices")  # atlas: the tree without dr.switch (CUDA's traversal); slices: one scene per instant
SCENES = ("2-moving", "8-moving", "16-moving", "32-moving", "64-moving")
CSV_FIELDS = ["scene", "bodies", "traversal", "resolution", "spp", "load_s", "stock_load_s", "load_vs_stock", "first_s", "compile_s", "kernels_compiled", "warm_s", "cached_first_s", "cached_compile_s", "cached_kernels_compiled", "first_vs_per_body", "warm_vs_per_body"]


def parse_args(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="film size (default 256; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel (default 32; quick 8)")
    p.add_argument("--scenes", nargs="+", choices=throughput.ALL_SCENES, default=None, help=f"default {' '.join(SCENES)}")
    p.add_argument("--traversals", nargs="+", choices=TRAVERSALS, default=list(TRAVERSALS[:3]),
                   help="default per-body, tree, atlas (the per-body loop compiles for minutes above ~64 bodies; on CUDA above ~10)")
    p.add_argument("--timeout-s", type=float, default=600.0, help="seconds a scene's process may take; more is reported as '> N s' (default 600)")
    p.add_argument("--one", nargs=2, metavar=("SCENE", "TRAVERSAL"), help=argparse.SUPPRESS)  # the child of in_fresh_process
    _common.add_output_options(p, "first_render", quick_help="smoke test: 32x32, 8 spp, 2 and 16 cubes", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, {"resolution": 32, "spp": 8, "scenes": ["2-moving", "16-moving"]} if args.quick
                          else {"resolution": 256, "spp": 32, "scenes": list(SCENES)})
    _common.require_positive(p, args, ["resolution", "spp"])
    _common.default_output_paths(args, "first_render")
    return args


def measure_one(scene_name, traversal, args):
    """In this process (its kernel cache empty): the first and a second render's wall times
    and the first's compilation time and compiled kernels, as a dict."""
    import drjit as dr
    import mitsuba as mi

    dopplertof.set_variant(args.variant or _common.DEFAULT_VARIANT)
    ours, stock = throughput.scene_dicts(scene_name, args.resolution, 5)
    mi.load_dict({"type": "scene", "warm-up": {"type": "cube"}})
    t = time.perf_counter()
    scene = dopplertof.load_scene(ours)
    load = time.perf_counter() - t
    t = time.perf_counter()
    stock_scene = mi.load_dict(stock)
    stock_load = time.perf_counter() - t
    scene.traversal = traversal
    render = throughput.make_runners(scene, stock_scene, args.spp, 5)["dtof4"]
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    t = time.perf_counter()
    render(1)
    first = time.perf_counter() - t
    history = dr.kernel_history()
    compile_s, compiled = _common.compile_seconds(history), _common.kernels_compiled(history)
    t = time.perf_counter()
    render(2)
    warm = time.perf_counter() - t
    return {"bodies": len(scene.bodies), "load_s": load, "stock_load_s": stock_load, "load_vs_stock": load / stock_load,
            "first_s": first, "compile_s": compile_s, "kernels_compiled": compiled, "warm_s": warm}


def in_fresh_process(scene_name, traversal, args, argv):
    """:func:`measure_one` in a child process with an empty Dr.Jit kernel cache, and its
    first render again in a second child that finds the first one's kernels on disk (a
    render of the same scene in a new process: ``cached_first_s``, ``cached_compile_s``,
    ``cached_kernels_compiled``); None where they ran past ``--timeout-s``."""
    import subprocess

    script_args = [*(sys.argv[1:] if argv is None else argv), "--one", scene_name, traversal]
    try:
        runs = _common.run_with_empty_kernel_cache(__file__, script_args, runs=2, capture_output=True, text=True, check=True, timeout=args.timeout_s)
    except subprocess.TimeoutExpired:
        return None
    first, again = (json.loads(run.stdout.strip().splitlines()[-1]) for run in runs)
    return {**first, "cached_first_s": again["first_s"], "cached_compile_s": again["compile_s"], "cached_kernels_compiled": again["kernels_compiled"]}


def main(argv=None):
    args = parse_args(argv)
    if args.one:
        print(json.dumps(measure_one(*args.one, args)))
        return 0
    settings = f"settings: {args.resolution}x{args.resolution}, {args.spp} spp, D-ToF 4 cameras (antithetic, replay), max_depth 5, empty kernel cache per process"
    run = _common.Run("first_render", args, argv, settings)
    rows = []
    for name in args.scenes:
        per_body = None
        for traversal in args.traversals:
            r = in_fresh_process(name, traversal, args, argv)
            if r is None:
                run.log(f"[{name}] {traversal:<8} did not finish in {args.timeout_s:g} s")
                rows.append({"scene": name, "traversal": traversal, "resolution": args.resolution, "spp": args.spp, "first_s": None})
                continue
            per_body = r if traversal == "per-body" else per_body
            row = {"scene": name, "traversal": traversal, "resolution": args.resolution, "spp": args.spp, **r,
                   "first_vs_per_body": r["first_s"] / per_body["first_s"] if per_body else None,
                   "warm_vs_per_body": r["warm_s"] / per_body["warm_s"] if per_body else None}
            rows.append(row)
            run.log(f"[{name}] {traversal:<8} load {r['load_s']:6.2f} s ({r['load_vs_stock']:.1f}x stock)  "
                    f"first {r['first_s']:7.2f} s (compiling {r['compile_s']:6.2f} s, {r['kernels_compiled']} kernels)  second {r['warm_s']:6.2f} s  "
                    f"new process {r['cached_first_s']:6.2f} s (compiling {r['cached_compile_s']:5.2f} s, {r['cached_kernels_compiled']} kernels)")
    print()
    print("| scene | " + " | ".join(f"{t}: first render (compiling), second" for t in args.traversals) + " |")
    print("|---|" + "---:|" * len(args.traversals))
    for name in args.scenes:
        found = {r["traversal"]: r for r in rows if r["scene"] == name}
        cells = [f"{r['first_s']:.2f} s ({r['compile_s']:.2f} s), {r['warm_s']:.3f} s" if r["first_s"] is not None
                 else f"> {args.timeout_s:g} s" for r in (found[t] for t in args.traversals)]
        print(f"| {name} | " + " | ".join(cells) + " |")
    return run.finish(rows, CSV_FIELDS, total_note=f"; load avg at end {_common.loadavg()}")


if __name__ == "__main__":
    sys.exit(main())
