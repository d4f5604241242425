#!/usr/bin/env python
"""Throughput of dopplertof against stock Mitsuba 3 ``path`` on the same scenes.

One process, one timer (``time.perf_counter``), configurations interleaved::

    python benchmarks/throughput.py            # default: 256x256, 32 spp, depth 5, 3 reps (~3-4 min, 2 cores)
    python benchmarks/throughput.py --full     # 256x256, 64 spp, 5 reps (~9 min on 2 idle cores)
    python benchmarks/throughput.py --quick    # smoke test: 32x32, 8 spp, 2 reps (< 40 s)

Scenes (Cornell-like box, point light at the camera):

* ``static``  -- the short and tall boxes at rest;
* ``2-moving`` -- the same boxes, each translating 15 mm over the 1.5 ms exposure;
* ``8-moving`` -- eight small cubes, each with its own 15 mm translation;
* ``32-moving``, ``128-moving`` (and, with ``--scenes``, ``16-moving``, ``64-moving``, ``1024-moving``) -- that
  many cubes on a jittered lattice filling the room
  (some on the floor), each with its own 15 mm translation; their size shrinks as
  1/sqrt(count) so that they show as much surface as the eight;
* ``moving-camera`` -- the static boxes, the camera (with its light attached) moving 15 mm
  towards them over the exposure.

``--traversal`` picks how our renders find the moving bodies a ray hits (``auto``, the
default, ``per-body`` or ``tree``; see :mod:`dopplertof.scene`).

Configurations per scene:

* ``stock``   -- ``mi.render`` with the ``path`` integrator (moving bodies baked at their
  t = 0 pose), box reconstruction filter, forced evaluation (``np.array(img)``);
* ``ours``    -- ``dopplertof.render(..., time_sampling="uniform")`` (intensity only);
* ``dtof1``   -- D-ToF, 1 camera (h=1, psi=0), antithetic time sampling, replay correlation;
* ``dtof4``   -- D-ToF, 4 cameras (h in {0, 1} x psi in {0, pi/2}), same settings.

Each configuration is warmed up once (JIT compilation; Dr.Jit caches the kernels), then
the R repetitions run interleaved (stock, ours, dtof1, dtof4, stock, ...; the order is
rotated every repetition). Reported: median time, paths/s = W*H*spp / median time, and
ratios to stock ``path`` on the same scene. All medians, minima and maxima go to a CSV.
"""

from __future__ import annotations

import math
import statistics
import sys
import time

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)
from dopplertof.scene import TRAVERSALS
from dopplertof.scenes import WHITE

import _common
from _common import diffuse, transform

EXPOSURE_S = 1.5e-3
DISPLACEMENT_M = 0.015

CONFIGS = ("stock", "ours", "dtof1", "dtof4")
CONFIG_LABELS = {
    "stock": "stock path",
    "ours": "ours intensity (uniform)",
    "dtof1": "D-ToF 1 camera (antithetic, replay)",
    "dtof4": "D-ToF 4 cameras (antithetic, replay)",
}
SCENE_NAMES = ("static", "2-moving", "8-moving", "32-moving", "128-moving", "moving-camera")  # the default run
LATTICE_SCENES = ("16-moving", "32-moving", "64-moving", "128-moving", "1024-moving")
ALL_SCENES = ("static", "2-moving", "8-moving", *LATTICE_SCENES, "moving-camera")
# Eight directions of travel, cycled over the cubes.
DIRECTIONS = [(0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0.5**0.5, 0, 0.5**0.5), (-(0.5**0.5), 0, 0.5**0.5), (0.5**0.5, 0.5**0.5, 0)]


# ----------------------------------------------------------------------------------------
# Scenes


def _bodies(name):
    """[(key, M0 at t=0, displacement over the exposure)] of the scene's bodies."""
    two = [
        ("short-box", transform((0.33, 0.3, 0.37), rotate_y_deg=-17, scale=(0.3, 0.3, 0.3)), (0, 0, DISPLACEMENT_M)),
        ("tall-box", transform((-0.33, 0.6, -0.29), rotate_y_deg=17, scale=(0.3, 0.6, 0.3)), (0, 0, -DISPLACEMENT_M)),
    ]
    if name in ("static", "2-moving", "moving-camera"):
        return two
    d = DISPLACEMENT_M
    if name == "8-moving":
        cubes = []
        for i, direction in enumerate(DIRECTIONS):
            x = -0.6 + 0.4 * (i % 4)
            z = -0.45 if i < 4 else 0.35
            y = 0.1 + 0.15 * (i % 3)  # some on the floor, some floating
            m0 = transform((x, y, z), rotate_y_deg=11.0 * i, scale=(0.1, 0.1, 0.1))
            cubes.append((f"cube-{i}", m0, tuple(d * c for c in direction)))
        return cubes
    if name in LATTICE_SCENES:
        return _cube_lattice(int(name.split("-")[0]))
    raise ValueError(f"unknown scene {name!r}")


def _cube_lattice(count):
    """``count`` cubes (half side 0.1 m x sqrt(8/count)) at the points of a jittered
    lattice in x in [-0.7, 0.7], y in [0, 1.5], z in [-0.7, 0.5] m, the lowest layer on the
    floor; fixed seed."""
    import numpy as np

    rng = np.random.default_rng(count)
    half = 0.1 * math.sqrt(8.0 / count)
    nx = nz = round(count ** (1 / 3))
    ny = -(-count // (nx * nz))
    cubes = []
    for i in range(count):
        ix, iy, iz = i % nx, (i // nx) % ny, i // (nx * ny)
        jitter = rng.uniform(-0.25, 0.25, 3) / np.array([nx, ny, nz])
        x = -0.7 + 1.4 * ((ix + 0.5) / nx + jitter[0])
        y = half if iy == 0 else 1.5 * ((iy + 0.5) / ny + jitter[1])
        z = -0.7 + 1.2 * ((iz + 0.5) / nz + jitter[2])
        m0 = transform((x, y, z), rotate_y_deg=float(rng.uniform(0, 90)), scale=(half, half, half))
        cubes.append((f"cube-{i}", m0, tuple(DISPLACEMENT_M * c for c in DIRECTIONS[i % len(DIRECTIONS)])))
    return cubes


def scene_dicts(name, resolution, max_depth):
    """(dopplertof dict, stock Mitsuba dict) of the named benchmark scene."""
    import mitsuba as mi

    ours = _common.cornell_room(resolution)
    stock = _common.cornell_room(resolution)
    stock["integrator"] = {"type": "path", "max_depth": max_depth}
    if name == "moving-camera":
        sensor = ours["sensor"]
        m0 = mi.ScalarTransform4d(sensor.pop("to_world").matrix)
        m1 = mi.ScalarTransform4d().translate([0, 0, -DISPLACEMENT_M]) @ m0
        sensor["motion"] = {"type": "keyframes", "keys": [(0.0, m0), (EXPOSURE_S, m1)]}
        sensor["light"] = {**ours.pop("light"), "position": [0.0, 0.0, 0.0]}  # at the aperture, as in the room
    for key, m0, disp in _bodies(name):
        stock[key] = {"type": "cube", "bsdf": diffuse(WHITE), "to_world": m0}
        if name in ("static", "moving-camera"):
            ours[key] = {"type": "cube", "bsdf": diffuse(WHITE), "to_world": m0}
        else:
            m1 = mi.ScalarTransform4f().translate(list(disp)) @ m0
            ours[key] = {
                "type": "cube",
                "bsdf": diffuse(WHITE),
                "motion": {"type": "keyframes", "keys": [(0.0, m0), (EXPOSURE_S, m1)]},
            }
    return ours, stock


# ----------------------------------------------------------------------------------------
# Benchmark


def make_runners(ours_scene, stock_scene, spp, max_depth):
    """config -> callable(seed) that renders and forces evaluation."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    cam1 = [dopplertof.Camera(heterodyne=1.0, phase=0.0)]
    cam4 = [dopplertof.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]

    def stock(seed):
        img = mi.render(stock_scene, spp=spp, seed=seed)
        a = np.array(img)  # forces evaluation and the copy to the host
        dr.sync_thread()
        return a

    def ours(seed):
        return dopplertof.render(ours_scene, spp=spp, seed=seed, max_depth=max_depth, time_sampling="uniform")

    def dtof(cams):
        def run(seed):
            return dopplertof.render(
                ours_scene, cameras=cams, spp=spp, seed=seed, max_depth=max_depth,
                time_sampling="antithetic", correlation="replay",
            )

        return run

    return {"stock": stock, "ours": ours, "dtof1": dtof(cam1), "dtof4": dtof(cam4)}


def sanity(config, out):
    """Raise if a render produced no finite image (a benchmark of garbage is worthless)."""
    import numpy as np

    img = out if config == "stock" else out.intensity
    if not np.isfinite(img).all() or float(np.mean(img)) <= 0.0:
        raise RuntimeError(f"{config}: non-finite or black image (mean {float(np.nanmean(img))!r})")
    if config.startswith("dtof") and not np.isfinite(out.measurements).all():
        raise RuntimeError(f"{config}: non-finite D-ToF measurements")


def bench_scene(name, args, log):
    ours_dict, stock_dict = scene_dicts(name, args.resolution, args.max_depth)
    import mitsuba as mi

    t = time.perf_counter()
    ours_scene = dopplertof.load_scene(ours_dict)
    ours_scene.traversal = args.traversal
    stock_scene = mi.load_dict(stock_dict)
    log(f"[{name}] scenes loaded in {time.perf_counter() - t:.2f} s ({len(ours_scene.bodies)} moving bodies, tree traversal: {ours_scene.uses_tree()})")
    runners = make_runners(ours_scene, stock_scene, args.spp, args.max_depth)
    configs = [c for c in CONFIGS if c in args.configs]

    warm = {}
    for c in configs:
        t = time.perf_counter()
        out = runners[c](10_000)  # a seed never used by the timed runs
        warm[c] = time.perf_counter() - t
        sanity(c, out)
        log(f"[{name}] warm-up {c:<6} {warm[c]:8.3f} s")
    times = {c: [] for c in configs}
    cpu = {c: [] for c in configs}
    for r in range(args.reps):
        order = configs[r % len(configs):] + configs[: r % len(configs)]  # rotate the start
        for c in order:
            p = time.process_time()
            t = time.perf_counter()
            runners[c](r)
            times[c].append(time.perf_counter() - t)
            cpu[c].append(time.process_time() - p)
        log(f"[{name}] rep {r + 1}/{args.reps}: " + "  ".join(f"{c} {times[c][-1]:.3f}s" for c in configs))
    return warm, times, cpu


def summarise(name, warm, times, cpu, args):
    paths = args.resolution * args.resolution * args.spp
    rows = {}
    for c, ts in times.items():
        med = statistics.median(ts)
        rows[c] = dict(
            scene=name, config=c, label=CONFIG_LABELS[c], traversal=args.traversal, resolution=args.resolution, spp=args.spp,
            max_depth=args.max_depth, reps=len(ts), paths=paths,
            median_s=med, min_s=min(ts), max_s=max(ts), warmup_s=warm[c],
            mpaths_per_s_median=paths / med / 1e6, mpaths_per_s_best=paths / min(ts) / 1e6,
            cpu_median_s=statistics.median(cpu[c]),
            times_s=" ".join(f"{t:.4f}" for t in ts),
        )
    stock = rows.get("stock")
    for row in rows.values():
        if stock is not None:
            # throughput ratio to stock (same paths): stock time / our time
            row["ratio_to_stock_median"] = stock["median_s"] / row["median_s"]
            row["ratio_to_stock_best"] = stock["min_s"] / row["min_s"]
            row["cpu_ratio_to_stock_median"] = stock["cpu_median_s"] / row["cpu_median_s"]
        else:
            row["ratio_to_stock_median"] = row["ratio_to_stock_best"] = float("nan")
    if "dtof1" in rows and "dtof4" in rows:
        rows["dtof4"]["time_vs_dtof1_median"] = rows["dtof4"]["median_s"] / rows["dtof1"]["median_s"]
    return rows


CSV_FIELDS = [
    "scene", "config", "label", "traversal", "resolution", "spp", "max_depth", "reps", "paths",
    "median_s", "min_s", "max_s", "warmup_s", "mpaths_per_s_median", "mpaths_per_s_best",
    "ratio_to_stock_median", "ratio_to_stock_best", "time_vs_dtof1_median",
    "cpu_median_s", "cpu_ratio_to_stock_median", "times_s",
]


def markdown_table(all_rows):
    def cell(rows, c):
        if c not in rows:
            return "-"
        r = rows[c]
        ratio = r["ratio_to_stock_median"]
        ratio_s = "" if math.isnan(ratio) else f" ({ratio:.3f}x)"
        return f"{r['mpaths_per_s_median']:.3f}{ratio_s}"

    lines = [
        "| scene | stock path Mpaths/s | ours intensity Mpaths/s (vs stock) | D-ToF 1 camera (vs stock) | D-ToF 4 cameras (vs stock) | time 4 cams / 1 cam |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for rows in all_rows:
        name = next(iter(rows.values()))["scene"]
        stock = f"{rows['stock']['mpaths_per_s_median']:.3f}" if "stock" in rows else "-"
        r41 = rows.get("dtof4", {}).get("time_vs_dtof1_median")
        lines.append(
            f"| {name} | {stock} | {cell(rows, 'ours')} | {cell(rows, 'dtof1')} | {cell(rows, 'dtof4')} | "
            f"{'-' if r41 is None else f'{r41:.2f}'} |"
        )
    return "\n".join(lines)


def parse_args(argv=None):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 256; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel (even; default 32; --full 64; quick 8)")
    p.add_argument("--max-depth", type=int, default=None, help="path depth, Mitsuba semantics (default 5)")
    p.add_argument("--reps", type=int, default=None, help="timed repetitions per configuration (default 3; --full 5; quick 2)")
    p.add_argument("--scenes", nargs="+", choices=ALL_SCENES, default=list(SCENE_NAMES))
    p.add_argument("--configs", nargs="+", choices=CONFIGS, default=list(CONFIGS))
    p.add_argument("--traversal", choices=TRAVERSALS, default="auto", help="how our renders find the moving bodies a ray hits (default auto)")
    p.add_argument("--full", action="store_true", help="256x256, 64 spp, 5 reps (about 9 min on 2 idle cores)")
    _common.add_output_options(p, "throughput", quick_help="tiny smoke-test run (32x32, 8 spp, 2 reps; < 40 s)", plot=False, quiet_help="only print the machine line and the table")
    args = p.parse_args(argv)
    if args.quick and args.full:
        p.error("--quick and --full exclude each other")
    if args.quick:
        defaults = dict(resolution=32, spp=8, max_depth=5, reps=2)
    elif args.full:
        defaults = dict(resolution=256, spp=64, max_depth=5, reps=5)
    else:  # fits ~4 min on 2 idle cores; spp 32 at 256x256 = one 2M-lane pass of dopplertof.render
        defaults = dict(resolution=256, spp=32, max_depth=5, reps=3)
    _common.fill_defaults(args, defaults)
    _common.default_output_paths(args, "throughput")
    if args.resolution <= 0 or args.spp <= 0 or args.reps <= 0:
        p.error("--resolution, --spp and --reps must be positive")
    if args.spp % 2 and any(c.startswith("dtof") for c in args.configs):
        p.error("--spp must be even for the antithetic D-ToF configurations")
    if "stock" not in args.configs:
        print("note: without 'stock' no ratios are reported", file=sys.stderr)
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = (
        f"settings: {args.resolution}x{args.resolution}, spp {args.spp}, max_depth {args.max_depth}, traversal {args.traversal}, "
        f"{args.reps} interleaved reps after 1 warm-up per config; timer time.perf_counter; load avg at start {_common.loadavg()}"
    )
    run = _common.Run("throughput", args, argv, settings)
    all_rows = []
    for name in args.scenes:
        warm, times, cpu = bench_scene(name, args, run.log)
        all_rows.append(summarise(name, warm, times, cpu, args))
    print()
    print(markdown_table(all_rows))
    print()
    print(
        "Mpaths/s = W*H*spp / median wall time of one render call (incl. host-side accumulation); "
        "(Nx) = throughput relative to stock `path` on the same scene (stock time / our time); "
        "D-ToF spp counts paths (an antithetic pair = 2)."
    )
    print(
        "process CPU-time ratios to stock (less sensitive to other load on the machine): "
        + "; ".join(
            f"{next(iter(rows.values()))['scene']}: "
            + ", ".join(f"{c} {rows[c]['cpu_ratio_to_stock_median']:.3f}x" for c in rows if c != "stock" and "cpu_ratio_to_stock_median" in rows[c])
            for rows in all_rows
        )
    )
    rows = [row for scene_rows in all_rows for row in scene_rows.values()]
    return run.finish(rows, CSV_FIELDS, total_note=f"; load avg at end {_common.loadavg()}", extrasaction="ignore")


if __name__ == "__main__":
    sys.exit(main())
