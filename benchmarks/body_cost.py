#!/usr/bin/env python
"""Where the time of moving bodies goes: parts of the body queries switched off, one at a time.

One process, one timer (``time.process_time``: CPU time of both threads, less sensitive to
other load than wall time), configurations interleaved, every render timed against stock
``path`` on the same geometry baked static in the same repetition::

    python benchmarks/body_cost.py                 # 8 moving cubes, 128x128, 32 spp, 7 reps (~1 min on 2 cores)
    python benchmarks/body_cost.py --scene 32-moving   # (~2 min)
    python benchmarks/body_cost.py --quick         # 32x32, 4 spp, 2 reps (smoke test)

The scenes are ``benchmarks/throughput.py``'s. Ablations (every one but ``baked`` renders a
*wrong* image on purpose: they measure what a part costs, not what it computes):

* ``baked``         -- ours on the same geometry with the bodies baked static (no body work);
* ``full``          -- ours as shipped (``DynamicScene.traversal`` = auto);
* ``no-body-calls`` -- everything but the bodies' Embree queries: box tests, poses, changes of
  frame, branches, the tree walk (a body's query returns "no hit" without calling Embree);
* ``masked-calls``  -- the bodies' Embree queries made with every lane masked off: the fixed
  cost of a call, paid by each SIMD packet with a lane near the body;
* ``one-call``      -- one Embree query per ray query for all lanes near *any* body (each such
  lane traces body 0's sub-scene, in the frame of a body it is near): the cost of any scheme
  that resolves the bodies in one extra query per SIMD packet (a single "atlas" of the
  bodies); it replaces the per-body loop, which it then uses whatever the number of bodies.

Configurations: ``ours`` (intensity, uniform time sampling) and ``dtof4`` (D-ToF with 4
cameras, antithetic time sampling, replay), as in throughput.py. Reported: median over the
repetitions of the CPU-time ratio to stock, and its range.
"""

from __future__ import annotations

import contextlib
import math
import statistics
import sys
import time

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
import throughput

ABLATIONS = ("baked", "full", "no-body-calls", "masked-calls", "one-call")
CONFIGS = ("ours", "dtof4")


class _MaskedScene:
    """A body's sub-scene whose queries trace no lane (``call``: still call Embree)."""

    def __init__(self, scene, call):
        self._scene, self._call = scene, call

    def __getattr__(self, name):
        return getattr(self._scene, name)

    def ray_intersect_preliminary(self, ray, coherent=False, active=True):
        import drjit as dr
        import mitsuba as mi

        if self._call:
            return self._scene.ray_intersect_preliminary(ray, coherent=coherent, active=mi.Bool(False))
        missed = dr.zeros(mi.PreliminaryIntersection3f)
        missed.t = mi.Float(dr.inf)
        return missed

    def ray_test(self, ray, active=True):
        import mitsuba as mi

        return self._scene.ray_test(ray, mi.Bool(False)) if self._call else mi.Bool(False)


def _lanes_near_a_body(scene, ray, poses, active, t_max):
    """(ray in the frame of the last body it is near, lanes near any body): the per-body
    loop's box tests, without its branches."""
    import drjit as dr
    import mitsuba as mi

    near_any, ray_local = mi.Bool(False), mi.Ray3f(ray)
    for b, body in enumerate(scene.bodies):
        enters = active & scene._box_hit(ray.o, ray.d, body.swept_min, body.swept_max, t_max)
        local = scene._to_local(ray, scene._body_pose(poses, b), ray.maxt)
        near = enters & scene._box_hit(local.o, local.d, body.local_min, body.local_max, t_max)
        ray_local, near_any = dr.select(near, local, ray_local), near_any | near
    return ray_local, near_any


def _one_call_closest(self, ray, poses, pi, active):
    """Stand-in for DynamicScene._per_body_closest: one query for every lane near a body."""
    import drjit as dr
    import mitsuba as mi

    ray_local, near_any = _lanes_near_a_body(self, ray, poses, active, dr.minimum(ray.maxt, pi.t))
    pib = self.bodies[0].scene.ray_intersect_preliminary(ray_local, coherent=False, active=near_any)
    closer = near_any & pib.is_valid() & (pib.t < pi.t)
    body_index = dr.select(closer, mi.UInt32(1), mi.UInt32(0))
    pose = self._body_pose(poses, 0)
    return dr.select(closer, pib, pi), dr.select(closer, self._to_local(ray, pose, ray.maxt), mi.Ray3f(ray)), body_index, pose


def _one_call_blocked(self, ray, poses, blocked, active):
    """Stand-in for DynamicScene._per_body_blocked: one query for every lane near a body."""
    ray_local, near_any = _lanes_near_a_body(self, ray, poses, active & ~blocked, ray.maxt)
    return blocked | self.bodies[0].scene.ray_test(ray_local, near_any)


@contextlib.contextmanager
def ablation(name, scene):
    """Switch off the part of the body queries that ``name`` names, for the ``with`` block."""
    from dopplertof.scene import DynamicScene

    saved_scenes = [body.scene for body in scene.bodies]
    saved_methods = (DynamicScene._per_body_closest, DynamicScene._per_body_blocked)
    saved_traversal = scene.traversal
    try:
        if name in ("no-body-calls", "masked-calls"):
            for body in scene.bodies:
                body.scene = _MaskedScene(body.scene, call=name == "masked-calls")
        elif name == "one-call":
            scene.traversal = "per-body"  # the stand-in replaces the per-body loop's queries
            DynamicScene._per_body_closest, DynamicScene._per_body_blocked = _one_call_closest, _one_call_blocked
        yield
    finally:
        for body, saved in zip(scene.bodies, saved_scenes):
            body.scene = saved
        DynamicScene._per_body_closest, DynamicScene._per_body_blocked = saved_methods
        scene.traversal = saved_traversal


def parse_args(argv=None):
    p = _common.argument_parser(__doc__)
    p.add_argument("--scene", choices=[s for s in throughput.ALL_SCENES if s.endswith("-moving")], default="8-moving")
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 128; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel, even (default 32; quick 4)")
    p.add_argument("--reps", type=int, default=None, help="interleaved repetitions (default 7; quick 2)")
    p.add_argument("--ablations", nargs="+", choices=ABLATIONS, default=list(ABLATIONS))
    _common.add_output_options(p, "body_cost", quick_help="smoke test (32x32, 4 spp, 2 reps)", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, dict(resolution=32, spp=4, reps=2) if args.quick else dict(resolution=128, spp=32, reps=7))
    _common.default_output_paths(args, f"body_cost_{args.scene}")
    _common.require_positive(p, args, ["resolution", "spp", "reps"])
    if args.spp % 2:
        p.error("--spp must be even (antithetic pairs)")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = (
        f"settings: {args.scene}, {args.resolution}x{args.resolution}, spp {args.spp}, max_depth 5, {args.reps} interleaved reps "
        f"after 1 warm-up each; timer time.process_time; load avg at start {_common.loadavg()}"
    )
    run = _common.Run("body_cost", args, argv, settings)
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    ours_dict, stock_dict = throughput.scene_dicts(args.scene, args.resolution, 5)
    baked_dict = {k: ({**{x: y for x, y in v.items() if x != "motion"}, "to_world": v["motion"]["keys"][0][1]} if isinstance(v, dict) and "motion" in v else v) for k, v in ours_dict.items()}
    stock_scene = mi.load_dict(stock_dict)
    scenes = {"moving": dopplertof.load_scene(ours_dict), "baked": dopplertof.load_scene(baked_dict)}
    run.log(f"{len(scenes['moving'].bodies)} moving bodies, tree traversal: {scenes['moving'].uses_tree()}")
    cams = [dopplertof.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, math.pi / 2)]

    def stock(seed):
        np.array(mi.render(stock_scene, spp=args.spp, seed=seed))
        dr.sync_thread()

    def ours(config, ablation_name, seed):
        scene = scenes["baked" if ablation_name == "baked" else "moving"]
        with ablation(ablation_name, scene):
            if config == "ours":
                dopplertof.render(scene, spp=args.spp, seed=seed, max_depth=5, time_sampling="uniform")
            else:
                dopplertof.render(scene, cameras=cams, spp=args.spp, seed=seed, max_depth=5, time_sampling="antithetic", correlation="replay")

    jobs = {("stock", "-"): stock, **{(c, a): (lambda seed, c=c, a=a: ours(c, a, seed)) for a in args.ablations for c in CONFIGS}}

    def timed(job, seed):
        start = time.process_time()
        jobs[job](seed)
        return time.process_time() - start

    for job in jobs:
        timed(job, 10_000)  # JIT compilation
    ratios = {job: [] for job in jobs if job[0] != "stock"}
    keys = list(jobs)
    for r in range(args.reps):
        times = {job: timed(job, r) for job in keys[r % len(keys):] + keys[: r % len(keys)]}
        for job in ratios:
            ratios[job].append(times[job] / times[("stock", "-")])
        run.log(f"rep {r + 1}/{args.reps}: " + "  ".join(f"{c}/{a} {ratios[(c, a)][-1]:.2f}x" for c, a in ratios))

    rows = [dict(scene=args.scene, config=c, ablation=a, resolution=args.resolution, spp=args.spp, reps=args.reps, cpu_ratio_to_stock_median=statistics.median(v), min=min(v), max=max(v)) for (c, a), v in ratios.items()]
    print()
    print("| ablation | ours intensity (CPU time / stock) | D-ToF 4 cameras |")
    print("|---|---:|---:|")
    for a in args.ablations:
        print("| " + a + " | " + " | ".join(f"{statistics.median(ratios[(c, a)]):.2f}x ({min(ratios[(c, a)]):.2f}-{max(ratios[(c, a)]):.2f})" for c in CONFIGS) + " |")
    print()
    return run.finish(rows, list(rows[0]), total_note=f"; load avg at end {_common.loadavg()}")


if __name__ == "__main__":
    sys.exit(main())
