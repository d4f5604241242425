#!/usr/bin/env python
"""What a new scene's kernel costs: the current package against a baseline commit, side by
side in one process.

    python benchmarks/kernel_cost.py            # 6 street samples (20-24 moving bodies) and 4 throughput scenes, 128², 64 spp (~2.5 min, 2 cores)
    python benchmarks/kernel_cost.py --quick    # smoke test: 2 street samples and 2 scenes, 32², 8 spp (< 1 min)
    python benchmarks/kernel_cost.py --baseline 1c8b874 --samples 10

Every scene of a dataset, of a design study or a first look at a file compiles its kernel
on its first render, and on the CPU that compilation can take longer than the render
(``first_render.py``). This script renders scenes neither package has rendered before, in a
process whose Dr.Jit kernel cache starts empty (a temporary ``$HOME``; the two packages'
kernels differ, so neither finds the other's), alternating which package goes first:

* ``street-<i>``: sample ``i`` of a dataset of street scenes with ``--street-bodies`` to
  ``--street-bodies`` + 4 moving bodies, rendered as the dataset renders it
  (:func:`dopplertof.dataset.sample.render_record`: the full and the direct-light render,
  which shares the full render's kernel, and the sensor model);
* ``throughput.py``'s scenes (``static``, ``8-moving``: the per-body loop, ``32-moving`` and
  ``128-moving``: the tree), rendered with D-ToF, 4 cameras, antithetic + replay (``--correlation``: another); and
  ``area-hidden``: the built-in ``cornell-box-area`` (its moving boxes and area light) with
  ``hide_emitters``, whose camera rays pass through the light.

Reported per scene and package: the first render's wall time, the operations of its largest
kernel and the time Dr.Jit spent compiling (kernel history), and for the throughput scenes
the median of ``--reps`` later renders of the same scene (other seeds, its kernels compiled),
the two packages' interleaved; and whether the two first renders' images are bit for bit the
same (a change that only makes kernels smaller keeps them). The baseline is the package at git
``--baseline`` (default ``1c8b874``: before the camera ray was traced in the path loop and a
hit carried its body's pose), imported as ``dopplertof_baseline``.
"""

from __future__ import annotations

import importlib
import itertools
import math
import statistics
import sys
import tempfile
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
import throughput

BASELINE = "1c8b874"
SCENES = ("static", "8-moving", "32-moving", "128-moving", "area-hidden")
HIDDEN_EMITTER_SCENE = "cornell-box-area"  # "area-hidden": this built-in scene with hide_emitters (its camera rays pass through the light)
PACKAGES = ("baseline", "current")
CSV_FIELDS = ["scene", "bodies", "package", "first_s", "compile_s", "kernel_ops", "warm_s", "identical"]


def parse_args(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--baseline", default=BASELINE, help=f"git revision to compare with (default {BASELINE})")
    p.add_argument("--samples", type=int, default=None, help="street samples (default 6; quick 2)")
    p.add_argument("--street-bodies", type=int, default=20, metavar="N", help="street scenes with N to N+4 moving bodies (default 20)")
    p.add_argument("--scenes", nargs="*", choices=SCENES, default=None, help="throughput.py scenes and area-hidden (default all five; quick static and 32-moving)")
    p.add_argument("--resolution", type=int, default=None, help="film size (default 128; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel (default 64; quick 8)")
    p.add_argument("--reps", type=int, default=None, help="later renders of each throughput scene per package, interleaved (default 5; quick 2)")
    p.add_argument("--correlation", default="replay", help="the throughput scenes' correlation (default replay; reconnection, adaptive: the paired tracer)")
    _common.add_output_options(p, "kernel_cost", quick_help="smoke test: 2 street samples and 2 scenes, 32x32, 8 spp", plot=False)
    args = p.parse_args(argv)
    quick = {"samples": 2, "resolution": 32, "spp": 8, "scenes": ["static", "32-moving"], "reps": 2}
    _common.fill_defaults(args, quick if args.quick else {"samples": 6, "resolution": 128, "spp": 64, "scenes": list(SCENES), "reps": 5})
    _common.require_positive(p, args, ["samples", "resolution", "spp", "street_bodies", "reps"])
    _common.default_output_paths(args, "kernel_cost")
    return args


def compiled(drjit):
    """(compile time in s, operations of the largest kernel) of the kernels launched since the
    last call (Dr.Jit's kernel history, which the call clears)."""
    history = drjit.kernel_history()
    return _common.compile_seconds(history), max((k.get("operation_count", 0) for k in history), default=0)


def timed(drjit, render):
    """(wall s, compile s, largest kernel's operations, result) of ``render()``."""
    compiled(drjit)
    start = time.perf_counter()
    result = render()
    wall = time.perf_counter() - start
    return (wall, *compiled(drjit), result)


def arrays(result):
    """The images of a render (a RenderResult) or of a dataset sample (``render_record``'s
    arrays), by name."""
    if isinstance(result, tuple):
        return result[0]
    return {name: getattr(result, name) for name in ("intensity", "measurements", "depth", "velocity", "instance_id")}


def identical(a, b):
    """Whether two renders' images are bit for bit the same (NaN where NaN)."""
    a, b = arrays(a), arrays(b)
    return a.keys() == b.keys() and all(np.array_equal(np.asarray(a[k]), np.asarray(b[k]), equal_nan=True) for k in a)


def street_jobs(args, packages):
    """(name, bodies, {package: (render, None)}) of each street sample: a sample builds its
    scene anew each time, so a second render would be of another scene (whose kernel may or
    may not match, as the first one's Mitsuba objects are freed or not)."""
    from dopplertof.dataset import config, sample

    overrides = {"scene": {"kinds": {"street": 1.0}}, "bodies": {"count": [args.street_bodies, args.street_bodies + 4], "moving_probability": 1.0},
                 "render": {"resolution": args.resolution, "spp": args.spp}}  # fmt: skip
    cfg = config.load_config(None, overrides)
    variant = args.variant or _common.DEFAULT_VARIANT
    for i in range(args.samples):
        record = sample.make_record(cfg, 2027, i, variant)
        runs = {}
        for which, package in packages.items():
            render_record = importlib.import_module(f"{package.__name__}.dataset.sample").render_record
            runs[which] = (lambda r=render_record, rec=record: r(rec), None)
        yield f"street-{i}", len(record["scene"]["bodies"]), runs


def scene_jobs(args, packages):
    """(name, bodies, {package: (first render, a later render)}) of each throughput.py scene
    (and ``area-hidden``)."""
    cameras = [dict(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    for name in args.scenes:
        hidden = name == "area-hidden"
        ours = None if hidden else throughput.scene_dicts(name, args.resolution, 5)[0]
        runs = {}
        for which, package in packages.items():
            scene = package.scenes.build(HIDDEN_EMITTER_SCENE, resolution=args.resolution) if hidden else package.load_scene(ours)
            options = dict(cameras=[package.Camera(**c) for c in cameras], spp=args.spp, max_depth=5, time_sampling="antithetic", correlation=args.correlation, hide_emitters=hidden)
            runs[which] = (lambda p=package, s=scene, o=options: p.render(s, seed=1, **o), lambda p=package, s=scene, o=options: p.render(s, seed=2, **o))  # fmt: skip
        yield name, len(scene.bodies), runs


def main(argv=None):
    args = parse_args(argv)
    status = _common.rerun_with_empty_kernel_cache(__file__, argv)
    if status is not None:
        return status
    settings = (f"settings: {args.resolution}x{args.resolution}, {args.spp} spp, {args.samples} street samples ({args.street_bodies}-{args.street_bodies + 4} "
                f"moving bodies; full + direct renders), throughput scenes {' '.join(args.scenes) or '-'} (D-ToF 4 cameras, antithetic + {args.correlation}), "
                f"baseline {args.baseline}, empty kernel cache")  # fmt: skip
    run = _common.Run("kernel_cost", args, argv, settings)
    import drjit as dr

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="dopplertof-baseline-") as folder:
        packages = {"baseline": _common.import_baseline(args.baseline, folder), "current": dopplertof}
        # One job's scenes at a time: every Mitsuba object alive shapes every kernel's virtual calls.
        jobs = itertools.chain(street_jobs(args, packages), scene_jobs(args, packages))
        for k, (name, bodies, runs) in enumerate(jobs):
            order = PACKAGES if k % 2 == 0 else PACKAGES[::-1]
            row, results = {}, {}
            for which in order:
                first_s, compile_s, ops, results[which] = timed(dr, runs[which][0])
                row[which] = {"scene": name, "bodies": bodies, "package": which, "first_s": first_s, "compile_s": compile_s, "kernel_ops": ops, "warm_s": math.nan}
            same = identical(results["baseline"], results["current"])
            for which in PACKAGES:
                row[which]["identical"] = same
            if runs[order[0]][1] is not None:  # later renders, interleaved: medians
                warm = {which: [] for which in PACKAGES}
                for rep in range(args.reps):
                    for which in order if rep % 2 == 0 else order[::-1]:
                        warm[which].append(timed(dr, runs[which][1])[0])
                for which in PACKAGES:
                    row[which]["warm_s"] = statistics.median(warm[which])
            for which in order:
                r = row[which]
                rows.append(r)
                run.log(f"{name:11s} {which:8s} first {r['first_s']:6.2f} s (compiling {r['compile_s']:5.2f} s, largest kernel {r['kernel_ops']} ops)  later {r['warm_s']:6.2f} s"
                        f"  images {'identical' if same else 'DIFFER'}")
    summarise(rows)
    return run.finish(rows, CSV_FIELDS)


def summarise(rows):
    """Print the table: per scene, each package's figures and current ÷ baseline; the street
    samples' medians last."""
    by = {(r["scene"], r["package"]): r for r in rows}
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    print("\n| scene | bodies | first render: baseline → current (÷) | compiling | largest kernel, operations | later renders (÷) | images |")
    print("|---|---:|---:|---:|---:|---:|---|")

    def line(name, bodies, b, c, same):
        warm = "-" if math.isnan(b["warm_s"]) else f"{b['warm_s']:.2f} → {c['warm_s']:.2f} s ({c['warm_s'] / b['warm_s']:.2f})"
        print(f"| {name} | {bodies} | {b['first_s']:.2f} → {c['first_s']:.2f} s ({c['first_s'] / b['first_s']:.2f}) | {b['compile_s']:.2f} → {c['compile_s']:.2f} s | "
              f"{b['kernel_ops']} → {c['kernel_ops']} | {warm} | {same} |")  # fmt: skip

    for name in scenes:
        b, c = by[(name, "baseline")], by[(name, "current")]
        line(name, b["bodies"], b, c, "identical" if c["identical"] else "differ")
    streets = [name for name in scenes if name.startswith("street-")]
    if streets:
        med = {which: {f: statistics.median(by[(n, which)][f] for n in streets) for f in ("first_s", "compile_s", "kernel_ops")} for which in PACKAGES}
        med = {which: {**m, "warm_s": math.nan} for which, m in med.items()}
        med = {which: {**m, "kernel_ops": int(m["kernel_ops"])} for which, m in med.items()}
        line(f"street samples (median of {len(streets)})", "-", med["baseline"], med["current"], f"{sum(by[(n, 'current')]['identical'] for n in streets)} of {len(streets)} identical")


if __name__ == "__main__":
    sys.exit(main())
