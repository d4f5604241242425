#!/usr/bin/env python
"""Where the static overhead of D-ToF goes: parts of the tracer switched off, one at a time.

One process, configurations interleaved, every render timed against stock ``path`` on the
same static Cornell box (``benchmarks/throughput.py``'s ``static`` scene) in the same
repetition::

    python benchmarks/static_overhead.py                       # 256x256, 32 spp, 5 reps (~2 min on 2 cores)
    python benchmarks/static_overhead.py --resolution 128 --spp 64
    python benchmarks/static_overhead.py --quick               # 32x32, 8 spp, 2 reps (smoke test)

Every configuration but ``full`` computes less than a render (some render *wrong* images on
purpose: they measure what a part costs, not what it computes). D-ToF with 4 cameras
(h in {0, 1} x psi in {0, pi/2}), antithetic time sampling, replay, as ``throughput.py``'s
``dtof4``, with:

* ``full``         -- as shipped;
* ``1-camera``     -- one camera (h = 1, psi = 0) instead of four;
* ``no-cameras``   -- no camera (intensity only: no modulation weights, no Float64 lengths);
* ``no-truth``     -- the ground-truth maps of the camera ray's hit replaced by zeros;
* ``f32-length``   -- optical lengths from the Float32 hit distance on every path (no Float64
  re-intersection with the hit primitive's plane), still summed in Float64: on this static
  scene what ``full`` does (a path that met no motion keeps Float32 distances,
  ``tracing.path.float64_distances``);
* ``f32-weights``  -- the modulation weights' sincos(kL) in Float32;
* ``replicates``   -- ``stratify_intervals`` off: 16 independent replicates per pixel instead of
  strata (other reductions, other times);
* ``uniform``      -- uniform time sampling, one time per path (no groups, no replay);
* ``slice-rows``   -- the same paths, the lanes of a pass in a slice kernel's order
  (``traversal="slices"``: pixels fastest, along rows), so a SIMD packet holds 16 pixels'
  paths, not 16 paths of one pixel (images scrambled);
* ``slice-blocks`` -- pixels fastest in 4x4 blocks of pixels (images scrambled; where the
  film's width is a multiple of 4 and the pass holds whole bands of 4 rows, else rows);
* ``members-apart`` -- pixel-major as shipped, but a pixel's lanes member-major: a SIMD
  packet holds 16 groups' paths of one pixel at one member, where as shipped it holds 8
  groups' paths at both members, whose rays coincide but for the bodies' motion (the same
  random numbers: replay). Separates what ``slice-rows`` loses to its pixels from what it
  loses to its members (images scrambled).

Reported per configuration: medians over the repetitions of the wall-time and the CPU-time
(``time.process_time``, both threads; less sensitive to other load) ratios to stock, the
operation count of the path-tracing kernel and the split of the wall time between that
kernel, the other kernels (the reductions in ``dopplertof.passes``) and the host (Python
tracing of the kernel, numpy), from Dr.Jit's kernel history; and the minor page faults of a
render (``resource.getrusage``: memory the process touches for the first time, which costs
several microseconds a page on a virtual machine: the host's sums are new numpy arrays in
every render, where stock Mitsuba's memory comes from Dr.Jit's cache).
"""

from __future__ import annotations

import contextlib
import math
import resource
import statistics
import sys
import time

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
import throughput

ABLATIONS = ("full", "1-camera", "no-cameras", "no-truth", "f32-length", "f32-weights", "replicates", "uniform", "slice-rows", "slice-blocks", "members-apart")


@contextlib.contextmanager
def ablation(name):
    """Switch off the part of the tracer that ``name`` names, for the ``with`` block."""
    from dopplertof import modulation
    from dopplertof.tracing import lanes, single

    saved = (single.ground_truth, single.float64_distances, modulation.CameraBank.weights, lanes.pixel_and_index)
    try:
        if name == "no-truth":
            single.ground_truth = _zero_truth
        elif name == "f32-length":
            single.float64_distances = lambda scene, needs_length: "none"
        elif name == "f32-weights":
            modulation.CameraBank.weights = _weights32
        elif name in ("slice-rows", "slice-blocks"):
            lanes.pixel_and_index = lambda setup, per_pixel: _pixels_fastest(setup, per_pixel, blocks=name == "slice-blocks")
        elif name == "members-apart":
            lanes.pixel_and_index = _members_apart
        yield
    finally:
        single.ground_truth, single.float64_distances, modulation.CameraBank.weights, lanes.pixel_and_index = saved


def _pixels_fastest(setup, per_pixel, blocks):
    """lanes.pixel_and_index with the pass's pixels fastest (a slice kernel's order), along
    rows or in 4x4 blocks: the same (pixel, index) pairs in other lanes."""
    import drjit as dr
    import mitsuba as mi

    from dopplertof.tracing import lanes

    lane = dr.arange(mi.UInt32, setup.n_pixels * per_pixel)
    n_pixels = lanes.opaque_u32(setup.n_pixels)
    pixel = lane % n_pixels
    if blocks and setup.width % 4 == 0 and setup.n_pixels % (4 * setup.width) == 0:
        band, block, within = pixel // (4 * setup.width), pixel % (4 * setup.width) // 16, pixel % 16
        pixel = (band * 4 + within // 4) * setup.width + block * 4 + within % 4
    return pixel + lanes.opaque_u32(setup.pixel_start), lane // n_pixels


def _members_apart(setup, per_pixel):
    """lanes.pixel_and_index with a pixel's lanes member-major (``n_times`` members of
    ``per_pixel / n_times`` groups): the same (pixel, index) pairs in other lanes."""
    import drjit as dr
    import mitsuba as mi

    from dopplertof.tracing import lanes

    lane = dr.arange(mi.UInt32, setup.n_pixels * per_pixel)
    per, groups = lanes.opaque_u32(per_pixel), lanes.opaque_u32(per_pixel // setup.n_times)
    within = lane % per
    return lane // per + lanes.opaque_u32(setup.pixel_start), within % groups * setup.n_times + within // groups


def _zero_truth(scene, hit, ray_d, depth_m, time_s, pinhole):
    import drjit as dr
    import mitsuba as mi

    zero = dr.zeros(mi.Float, dr.width(hit.si.t))
    truth = {"depth": zero, "velocity": zero, "point_velocity": zero, "velocity_3d": mi.Vector3f(zero), "flow": mi.Vector2f(zero), "instance_id": zero}
    return truth, hit.si.is_valid()


def _weights32(self, path_length_m):
    """CameraBank.weights of sinusoidal low-pass cameras with sincos(kL) in Float32."""
    import drjit as dr
    import mitsuba as mi

    trig = {}
    out = []
    for kind, k_key, k, c, s in self._terms:
        assert kind == "sin"
        if k_key not in trig:
            kl = k * path_length_m
            trig[k_key] = dr.sincos(mi.Float(kl - dr.floor(kl * (1 / (2 * math.pi))) * (2 * math.pi)))
        sin_kl, cos_kl = trig[k_key]
        out.append(mi.Float(c) * cos_kl - mi.Float(s) * sin_kl)
    return out


def render_kwargs(name, spp):
    """dopplertof.render's arguments for ablation ``name``."""
    cams4 = [dopplertof.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]
    kw = dict(cameras=cams4, spp=spp, max_depth=5, time_sampling="antithetic", correlation="replay")
    if name == "1-camera":
        kw["cameras"] = [dopplertof.Camera(heterodyne=1.0, phase=0.0)]
    elif name == "no-cameras":
        kw["cameras"] = []
    elif name == "replicates":
        kw["stratify_intervals"] = False
    elif name == "uniform":
        kw.update(time_sampling="uniform", correlation="none")
    return kw


def kernel_split(history):
    """(ops of the largest JIT kernel, its seconds, the other kernels' seconds)."""
    timed = [k for k in history if "execution_time" in k]
    jit = [k for k in timed if str(k.get("type")).endswith("JIT")]
    main_kernel = max(jit, key=lambda k: k["execution_time"]) if jit else None
    total = sum(k["execution_time"] for k in timed) / 1e3
    if main_kernel is None:
        return 0, 0.0, total
    main_s = main_kernel["execution_time"] / 1e3
    return main_kernel.get("operation_count", 0), main_s, total - main_s


def parse_args(argv=None):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 256; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel, even (default 32; quick 8)")
    p.add_argument("--reps", type=int, default=None, help="interleaved repetitions (default 5; quick 2)")
    p.add_argument("--ablations", nargs="+", choices=ABLATIONS, default=list(ABLATIONS))
    _common.add_output_options(p, "static_overhead", quick_help="smoke test (32x32, 8 spp, 2 reps)", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, dict(resolution=32, spp=8, reps=2) if args.quick else dict(resolution=256, spp=32, reps=5))
    _common.default_output_paths(args, "static_overhead")
    _common.require_positive(p, args, ["resolution", "spp", "reps"])
    if args.spp % 2:
        p.error("--spp must be even (antithetic pairs)")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = (
        f"settings: static Cornell box, {args.resolution}x{args.resolution}, spp {args.spp}, max_depth 5, {args.reps} interleaved reps "
        f"after 1 warm-up each; timers time.perf_counter and time.process_time; load avg at start {_common.loadavg()}"
    )
    run = _common.Run("static_overhead", args, argv, settings)
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    ours_dict, stock_dict = throughput.scene_dicts("static", args.resolution, 5)
    stock_scene = mi.load_dict(stock_dict)
    scene = dopplertof.load_scene(ours_dict)

    def stock(seed):
        np.array(mi.render(stock_scene, spp=args.spp, seed=seed))
        dr.sync_thread()

    def ours(name, seed):
        with ablation(name):
            dopplertof.render(scene, seed=seed, **render_kwargs(name, args.spp))

    jobs = {"stock": stock, **{a: (lambda seed, a=a: ours(a, seed)) for a in args.ablations}}

    def timed(job, seed):
        dr.kernel_history()  # drop what came before
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        cpu, wall = time.process_time(), time.perf_counter()
        jobs[job](seed)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
        ops, main_s, other_s = kernel_split(dr.kernel_history())
        return dict(wall=wall, cpu=cpu, ops=ops, main=main_s, other=other_s, host=wall - main_s - other_s, faults=faults)

    for job in jobs:
        timed(job, 10_000)  # JIT compilation
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    samples = {job: [] for job in jobs}
    keys = list(jobs)
    for r in range(args.reps):
        rep = {job: timed(job, r) for job in keys[r % len(keys):] + keys[: r % len(keys)]}
        for job in keys:
            x = dict(rep[job])
            x["wall_ratio"], x["cpu_ratio"] = x["wall"] / rep["stock"]["wall"], x["cpu"] / rep["stock"]["cpu"]
            samples[job].append(x)
        run.log(f"rep {r + 1}/{args.reps}: " + "  ".join(f"{a} {samples[a][-1]['wall_ratio']:.2f}x" for a in args.ablations))
    dr.set_flag(dr.JitFlag.KernelHistory, False)

    def med(job, key):
        return statistics.median(x[key] for x in samples[job])

    rows = []
    for job in keys:
        rows.append(dict(
            config=job, resolution=args.resolution, spp=args.spp, reps=args.reps,
            wall_ratio_median=med(job, "wall_ratio"), cpu_ratio_median=med(job, "cpu_ratio"),
            wall_s_median=med(job, "wall"), main_kernel_ops=samples[job][-1]["ops"],
            main_kernel_s_median=med(job, "main"), other_kernels_s_median=med(job, "other"), host_s_median=med(job, "host"),
            minor_page_faults_median=med(job, "faults"),
            wall_ratios=" ".join(f"{x['wall_ratio']:.3f}" for x in samples[job]),
        ))  # fmt: skip
    print()
    print("| configuration | wall time / stock | CPU time / stock | tracing kernel: ops | tracing kernel s | other kernels s | host s | page faults |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        print(
            f"| {row['config']} | {row['wall_ratio_median']:.3f}x | {row['cpu_ratio_median']:.3f}x | {row['main_kernel_ops']} | "
            f"{row['main_kernel_s_median']:.3f} | {row['other_kernels_s_median']:.3f} | {row['host_s_median']:.3f} | {row['minor_page_faults_median']:.0f} |"
        )
    print()
    return run.finish(rows, list(rows[0]), total_note=f"; load avg at end {_common.loadavg()}")


if __name__ == "__main__":
    sys.exit(main())
