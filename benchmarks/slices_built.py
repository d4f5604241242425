#!/usr/bin/env python
"""One scene per instant, built: ``traversal="slices"`` against the per-lane tracer
(``"auto"``) and stock ``path``, side by side in one process (issue 17, DESIGN §6).

    python benchmarks/slices_built.py              # 8 and 128 cubes at 256² x 32 spp, a street sample at 64² x 64 (~3 min)
    python benchmarks/slices_built.py --quick      # smoke test
    python benchmarks/slices_built.py --baseline fb813e3   # also slices as at that commit
    python benchmarks/slices_built.py --correlation reconnection --scenes 8-moving 128-moving   # the paired tracer

D-ToF with 4 cameras (antithetic + replay; ``--correlation`` another for the throughput scenes). Per scene, after one warm-up render of each
configuration (kernels compiled), ``--reps`` interleaved renders of each: the median wall
time, its ratio to stock ``path`` on the same geometry (the throughput scenes only), and for
``slices`` the time its path-tracing kernels ran (Dr.Jit's kernel history) and the time
Python spent tracing them (``tracing.trace_pass``: a recorded pass's replays skip it),
the milliseconds one group's placement of the bodies takes (``SliceScenes.place``,
timed from when the kernels in flight are done), and the rest of a render's wall time (its
wall time less those three: replaying the recorded pass, the pass's other kernels and its
reduction, the host work of the render). ``agree``: the
spread of z = (slices − auto) / sqrt(σ²_slices + σ²_auto) over the measurements whose
errors are not zero, and the same spread between two renders of ``auto`` (seeds 1 and 2):
equal where both estimate the same thing. With ``--baseline REV`` a fourth configuration
renders ``slices`` with the package at git ``REV`` (imported as ``dopplertof_baseline``,
its own scene objects, timed as the current package is): its wall and kernel times and the
current ``slices`` ÷ it.
"""

from __future__ import annotations

import gc
import math
import statistics
import tempfile
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
import throughput

CONFIGS = ("stock", "auto", "slices")


def parse_args(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--reps", type=int, default=None, help="timed renders per configuration (default 3; quick 1)")
    p.add_argument("--resolution", type=int, default=None, help="film side of the throughput scenes (default 256; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel of the throughput scenes (default 32; quick 8)")
    p.add_argument("--correlation", default=None, help="the throughput scenes' correlation (default replay; reconnection, adaptive: the paired tracer)")
    p.add_argument("--baseline", default=None, help="git revision whose slices to time beside the current (default: none)")
    p.add_argument("--scenes", nargs="*", choices=["8-moving", "32-moving", "128-moving", "1024-moving", "street"], default=None, help="default 8-moving 128-moving street")
    _common.add_output_options(p, "slices_built", quick_help="smoke test: 32x32, 8 spp, one rep", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, {"reps": 1, "resolution": 32, "spp": 8} if args.quick else {"reps": 3, "resolution": 256, "spp": 32})
    _common.default_output_paths(args, "slices_built")
    return args


def street_scene(package=dopplertof):
    """(scene, render options) of street sample 3 of the dataset benchmark's configuration,
    built by ``package`` (the current one or the baseline)."""
    import importlib

    config, randomize, sample = (importlib.import_module(f"{package.__name__}.dataset.{m}") for m in ("config", "randomize", "sample"))
    cfg = config.load_config(None, {"scene": {"kinds": {"street": 1.0}}, "bodies": {"count": [20, 24], "moving_probability": 1.0}})
    record = sample.make_record(cfg, 2027, 3, _common.DEFAULT_VARIANT)
    r = record["render"]
    scene = randomize.build_scene(record["scene"], r["resolution"])
    options = dict(spp=r["spp"], max_depth=r["max_depth"], cameras=[package.Camera(**c) for c in record["cameras"]],
                   time_sampling=r["time_sampling"], correlation=r["correlation"])  # fmt: skip
    return scene, options


class Timer:
    """Seconds spent in (and calls of) ``owner.name`` while active; with ``synced`` the
    clock starts once the kernels in flight are done (a placement waits for them anyway)."""

    def __init__(self, owner, name, synced=False):
        self.owner, self.name, self.synced = owner, name, synced
        self.seconds, self.calls = 0.0, 0

    def __enter__(self):
        import drjit as dr

        self.shipped = shipped = getattr(self.owner, self.name)

        def wrapped(*a, **k):
            if self.synced:
                dr.sync_thread()
            t0 = time.perf_counter()
            try:
                return shipped(*a, **k)
            finally:
                self.seconds += time.perf_counter() - t0
                self.calls += 1

        setattr(self.owner, self.name, wrapped)
        return self

    def __exit__(self, *exc):
        setattr(self.owner, self.name, self.shipped)


def timed(render, package=dopplertof):
    """(wall s, path-kernel s, tracing s, placement ms per group, result, rest s) of
    ``render()``, a render by ``package`` (the current one or the baseline: both are timed
    alike, Python's collector run before and paused during the render, the timers' syncs
    before each placement in both); the rest: the wall time less the other three."""
    import importlib

    import drjit as dr

    SliceScenes = importlib.import_module(f"{package.__name__}.slices").SliceScenes
    tracing = importlib.import_module(f"{package.__name__}.tracing")
    dr.kernel_history()
    gc.collect()  # before bd4736b Python's collector could free objects while a pass was recorded: an abort
    gc.disable()
    try:
        with Timer(tracing, "trace_pass") as traced, Timer(SliceScenes, "place", synced=True) as placing:
            t0 = time.perf_counter()
            result = render()
            wall = time.perf_counter() - t0
    finally:
        gc.enable()
    kernels = sum(k.get("execution_time", 0.0) for k in dr.kernel_history() if (k.get("operation_count") or 0) > 1000) / 1e3
    return wall, kernels, traced.seconds, 1e3 * placing.seconds / max(placing.calls, 1), result, wall - kernels - traced.seconds - placing.seconds


def z_spread(a, b):
    m1, m2 = np.asarray(a.measurements, np.float64), np.asarray(b.measurements, np.float64)
    e1, e2 = np.asarray(a.measurement_stderr, np.float64), np.asarray(b.measurement_stderr, np.float64)
    keep = (e1 > 0) & (e2 > 0)
    z = (m1 - m2)[keep] / np.sqrt(e1**2 + e2**2)[keep]
    return float(np.std(z)), float(np.mean(np.abs(z) > 3))


def bench(name, args, log, baseline=None):
    import drjit as dr
    import mitsuba as mi

    def load(package):
        """(scene, render options, stock scene or None) of ``name`` built by ``package``."""
        if name == "street":
            return (*street_scene(package), None)
        ours, stock_dict = throughput.scene_dicts(name, args.resolution, 5)
        cameras = [package.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
        options = dict(spp=args.spp, max_depth=5, cameras=cameras, **({"correlation": args.correlation} if args.correlation else {}))
        return package.load_scene(ours), options, mi.load_dict(stock_dict)

    scene, options, stock = load(dopplertof)
    if baseline is not None:
        base_scene, base_options, _ = load(baseline)
        base_scene.traversal = "slices"

    def run(config, seed):
        if config == "stock":
            return timed(lambda: np.asarray(mi.render(stock, spp=options["spp"], seed=seed)))
        if config == "baseline":  # the same seeds as slices: the same images where the change keeps them
            return timed(lambda: baseline.render(base_scene, seed=seed + 1000, **base_options), baseline)
        scene.traversal = config
        seed += 1000 if config == "slices" else 0  # other paths than auto's: their errors independent
        return timed(lambda: dopplertof.render(scene, seed=seed, **options))

    configs = [c for c in (*CONFIGS, "baseline") if (stock is not None or c != "stock") and (baseline is not None or c != "baseline")]
    for _ in range(2):  # warm-up, twice: the member scenes, once built, enter the other kernels' calls
        for c in configs:
            run(c, 0)
    times = {c: [] for c in configs}
    last = {}
    for rep in range(args.reps):
        for c in configs:
            times[c].append(run(c, 1 + rep))
            last[c] = times[c][-1][4]
        log(f"[{name}] rep {rep + 1}/{args.reps}: " + "  ".join(f"{c} {times[c][-1][0]:.2f}s" for c in configs))
    row = {"scene": name, "bodies": len(scene.bodies), "resolution": scene.resolution[0], "spp": options["spp"]}
    for c in configs:
        row[f"{c}_s"] = statistics.median(t[0] for t in times[c])
    row["slices_kernels_s"] = statistics.median(t[1] for t in times["slices"])
    row["slices_tracing_s"] = statistics.median(t[2] for t in times["slices"])
    row["slices_placing_ms_per_group"] = statistics.median(t[3] for t in times["slices"])
    row["slices_rest_s"] = statistics.median(t[5] for t in times["slices"])
    placement = scene.slice_scenes(2).placements[0]  # the renders' member scenes (antithetic pairs)
    row["moving_meshes"], row["moving_other_shapes"] = len(placement.spans), len(placement.to_world)  # per member scene
    row["auto_kernels_s"] = statistics.median(t[1] for t in times["auto"])
    if stock is not None:
        row["auto_vs_stock"] = row["auto_s"] / row["stock_s"]
        row["slices_vs_stock"] = row["slices_s"] / row["stock_s"]
    row["slices_vs_auto"] = row["slices_s"] / row["auto_s"]
    if baseline is not None:
        row["baseline_kernels_s"] = statistics.median(t[1] for t in times["baseline"])
        row["slices_vs_baseline"] = row["slices_s"] / row["baseline_s"]
        row["slices_kernels_vs_baseline"] = row["slices_kernels_s"] / row["baseline_kernels_s"]
        row["same_as_baseline"] = bool(np.array_equal(np.asarray(last["slices"].measurements), np.asarray(last["baseline"].measurements)))
    row["agree_z_spread"], row["agree_beyond_3"] = z_spread(last["slices"], last["auto"])
    if args.reps > 1:  # the same between two renders of the per-lane tracer
        row["auto_z_spread"], row["auto_beyond_3"] = z_spread(times["auto"][0][4], times["auto"][1][4])
    dr.sync_thread()
    return row


def main(argv=None):
    args = parse_args(argv)
    settings = f"{args.resolution}x{args.resolution}, spp {args.spp} (street: the dataset's 64x64, 64 spp), D-ToF 4 cameras, correlation {args.correlation or 'replay'} (street: its own), {args.reps} interleaved reps after a warm-up"
    run = _common.Run("slices_built", args, argv, settings)
    import drjit as dr

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    names = ["8-moving"] if args.quick else args.scenes or ["8-moving", "128-moving", "street"]
    with tempfile.TemporaryDirectory(prefix="dopplertof-baseline-") as folder:
        baseline = _common.import_baseline(args.baseline, folder) if args.baseline else None
        rows = [bench(n, args, run.log, baseline) for n in names]
    fields = ["scene", "bodies", "resolution", "spp", "stock_s", "auto_s", "slices_s", "auto_kernels_s", "slices_kernels_s", "slices_tracing_s", "slices_placing_ms_per_group", "slices_rest_s", "moving_meshes", "moving_other_shapes",
              "auto_vs_stock", "slices_vs_stock", "slices_vs_auto", "agree_z_spread", "agree_beyond_3", "auto_z_spread", "auto_beyond_3",
              *(["baseline_s", "baseline_kernels_s", "slices_vs_baseline", "slices_kernels_vs_baseline", "same_as_baseline"] if args.baseline else [])]  # fmt: skip
    print("| scene | bodies | auto ÷ stock | slices ÷ stock | slices ÷ auto | slices: kernels / tracing / rest s, placing ms a group | z spread (beyond 3), slices vs auto | auto vs auto |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        f = lambda k: f"{r[k]:.2f}" if k in r else "-"  # noqa: E731
        print(f"| {r['scene']} | {r['bodies']} | {f('auto_vs_stock')} | {f('slices_vs_stock')} | {f('slices_vs_auto')} | {f('slices_kernels_s')} / {f('slices_tracing_s')} / {f('slices_rest_s')}, {f('slices_placing_ms_per_group')} | {f('agree_z_spread')} ({100 * r['agree_beyond_3']:.1f} %) | {f('auto_z_spread')} ({100 * r.get('auto_beyond_3', float('nan')):.1f} %) |")
    if args.baseline:
        print(f"\n| scene | slices ÷ slices at {args.baseline} | its kernels ÷ | same measurements |\n|---|---:|---:|---|")
        for r in rows:
            print(f"| {r['scene']} | {r['slices_vs_baseline']:.2f} | {r['slices_kernels_vs_baseline']:.2f} | {r['same_as_baseline']} |")
    run.finish(rows, fields, restval="")


if __name__ == "__main__":
    main()
