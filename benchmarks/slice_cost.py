#!/usr/bin/env python
"""What one Mitsuba scene per instant (issue 17, DESIGN §6) would cost on the CPU, measured on
stock Mitsuba ``path`` alone.

One scene per instant traces every lane of a kernel at one slice time: each correlated
member of each group of a pixel is its own kernel (a render of S spp with antithetic pairs
is S kernels of one lane per pixel), and each kernel first places the bodies at its time.
Three costs decide whether that beats today's per-lane times, and stock Mitsuba measures
all three, one process, configurations interleaved, every scene loaded afresh for each
timing (Mitsuba's shape registry grows every kernel's virtual calls with the shapes of
every scene alive, so no two scenes are alive at once)::

    python benchmarks/slice_cost.py                  # 8 and 128 moving cubes, 256x256 x 32 spp, 3 reps (~2 min on 2 cores)
    python benchmarks/slice_cost.py --resolution 128 --spp 64
    python benchmarks/slice_cost.py --quick          # 32x32, 8 spp, 1 rep (smoke test)

* **per path**: ``path`` on the scene of ``throughput.py`` with its cubes (a) merged into the
  static meshes (Mitsuba's default loading; ``throughput.py``'s stock baseline), (b) merged
  into one mesh of their own, apart from the room's (a scene whose moving mesh is rewritten
  per slice), (c) as meshes of their own (``optimize=False``) and (d) as instances of one
  shape group (the form DESIGN §6 names);
* **per slice**: writing every cube's pose, (b) the moving mesh's or (c) each cube's
  ``vertex_positions`` or (d) each instance's ``to_world``, then ``params.update()``
  (Embree's rebuild included);
* **per kernel**: ``mi.render`` at 1 spp against ``--spp`` on the same scene; the difference
  per render is the fixed cost a kernel pays whatever its size (tracing, launch, film).
  A dopplertof kernel traces a larger symbolic loop than ``path``, so the smallest of the
  forms' is the lower bound;
  the fixed cost of a whole ``dopplertof.render`` call (D-ToF, 4 cameras, one stratum of
  two antithetic pairs per pixel against ``--spp``, on the static scene of ``throughput.py``:
  its host work included) is the upper bound;
* **per kernel, frozen**: the same 1-spp render of the one-mesh scene after each slice update,
  traced each time against replayed by ``dr.freeze`` (which skips the Python tracing), and
  whether the two images are the same.

Reported: each time, and the projected time of a render of R² x S spp traced as S kernels,
relative to today's baseline (``path`` on the merged scene, one kernel):
(S x (per-kernel + per-slice) + per-path time of (b), (c) or (d)) / stock time, with the
lower and the upper bound of the per-kernel cost.
"""

from __future__ import annotations

import gc
import statistics
import time

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
import throughput

FORMS = ("merged", "one-mesh", "own-meshes", "instances")
ONE_SPP_RENDERS = 5  # per repetition: the fixed cost is a small difference of noisy times
FROZEN_CALLS = 5  # replays of the frozen render timed
STRATUM_SPP = 4  # a dopplertof render's smallest whole unit: one stratum of two antithetic pairs


def scene_dict(name, form, resolution, max_depth):
    """Stock Mitsuba dict of ``throughput.py``'s scene ``name``, its cubes in ``form``."""
    import mitsuba as mi

    _, stock = throughput.scene_dicts(name, resolution, max_depth)
    if form == "one-mesh":  # the cubes merged into one mesh of their own, the room into another
        cubes = {"type": "scene", **{key: stock.pop(key) for key, _, _ in throughput._bodies(name)}}
        (stock["moving-mesh"],) = mi.load_dict(cubes).shapes()
    if form != "instances":
        return stock
    bodies = throughput._bodies(name)
    stock["cube-group"] = {"type": "shapegroup", "cube": {"type": "cube", "bsdf": stock[bodies[0][0]]["bsdf"]}}
    for key, m0, _ in bodies:
        stock[key] = {"type": "instance", "shapegroup": {"type": "ref", "id": "cube-group"}, "to_world": m0}
    return stock


def load(name, form, resolution, max_depth):
    import mitsuba as mi

    return mi.load_dict(scene_dict(name, form, resolution, max_depth), optimize=form in ("merged", "one-mesh"))


def render_s(scene, spp, seed):
    """Wall time of one ``mi.render``, evaluation and copy to the host included."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    t0 = time.perf_counter()
    np.array(mi.render(scene, spp=spp, seed=seed))
    dr.sync_thread()
    return time.perf_counter() - t0


def slice_update_s(scene, form, shift_m):
    """Wall time of placing every cube at a new pose (shifted by ``shift_m`` along z) and
    updating the scene; None where the form has no per-cube pose (merged)."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    params = mi.traverse(scene)
    if form in ("one-mesh", "own-meshes"):
        keys = [k for k in params.keys() if k.endswith("vertex_positions") and (form == "own-meshes" or k.startswith("moving-mesh"))]
        new = {k: mi.Float((np.array(params[k]).reshape(-1, 3) + np.float32([0, 0, shift_m])).ravel()) for k in keys}
    elif form == "instances":
        keys = [k for k in params.keys() if k.startswith("cube-") and k.endswith(".to_world")]
        new = {k: mi.Transform4f().translate([0, 0, shift_m]) @ params[k] for k in keys}
    else:
        return None
    assert new, f"no pose to write in the {form} scene"
    dr.eval(new)
    t0 = time.perf_counter()
    for k, v in new.items():
        params[k] = v
    params.update()
    dr.eval()
    dr.sync_thread()
    return time.perf_counter() - t0


def dopplertof_fixed_s(args, log):
    """Fixed cost of one ``dopplertof.render`` call: one stratum per pixel (two antithetic
    pairs, ``STRATUM_SPP``: a whole unit, reduced as a full render's are) against ``--spp``."""
    ours, _ = throughput.scene_dicts("static", args.resolution, args.max_depth)
    scene = dopplertof.load_scene(ours)
    dtof4 = {spp: throughput.make_runners(scene, None, spp, args.max_depth)["dtof4"] for spp in (args.spp, STRATUM_SPP)}

    def ours_s(spp, seed):
        t0 = time.perf_counter()
        dtof4[spp](seed)
        return time.perf_counter() - t0

    ours_s(args.spp, 0), ours_s(STRATUM_SPP, 0)
    full, stratum = [], []
    for rep in range(args.reps):
        full.append(ours_s(args.spp, rep + 1))
        stratum += [ours_s(STRATUM_SPP, 10 * rep + k) for k in range(ONE_SPP_RENDERS)]
    fixed = max(0.0, statistics.median(stratum) - STRATUM_SPP * statistics.median(full) / args.spp)
    log(f"[dopplertof] static scene: {statistics.median(full):.3f}s at {args.spp} spp, {statistics.median(stratum):.4f}s at {STRATUM_SPP} spp: fixed {1e3 * fixed:.1f} ms")
    return fixed


def frozen_kernel(name, args, log):
    """(plain s, frozen s, equal): a 1-spp ``mi.render`` of the one-mesh scene after each
    slice update, traced every time against ``dr.freeze``'d (its kernels replayed)."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    scene = load(name, "one-mesh", args.resolution, args.max_depth)

    def plain(scene, seed):
        return mi.render(scene, spp=1, seed=seed)

    frozen = dr.freeze(plain)
    times, equal = {"plain": [], "frozen": []}, True
    for k in range(2 + FROZEN_CALLS):  # two calls to record, then replays
        slice_update_s(scene, "one-mesh", 1e-3 * (k % 2 + 1))
        images = {}
        for label, f in (("plain", plain), ("frozen", frozen)):
            t0 = time.perf_counter()
            images[label] = np.array(f(scene, mi.UInt32(k)))
            dr.sync_thread()
            if k >= 2:
                times[label].append(time.perf_counter() - t0)
        equal &= bool(np.array_equal(images["plain"], images["frozen"]))
    plain_s, frozen_s = statistics.median(times["plain"]), statistics.median(times["frozen"])
    log(f"[{name}] 1-spp render after a slice update: traced {1e3 * plain_s:.1f} ms, frozen {1e3 * frozen_s:.1f} ms, same image: {equal}")
    return plain_s, frozen_s, equal


def measure(name, args, log):
    """{form: {per_path_s, slice_s, kernel_s}} medians over the repetitions."""
    times = {form: {"render": [], "render1": [], "slice": []} for form in FORMS}
    for form in FORMS:  # warm-up: compile each form's kernels once
        scene = load(name, form, args.resolution, args.max_depth)
        render_s(scene, args.spp, 0), render_s(scene, 1, 0)
        del scene
        gc.collect()
    for rep in range(args.reps):
        for form in FORMS[rep % len(FORMS) :] + FORMS[: rep % len(FORMS)]:
            scene = load(name, form, args.resolution, args.max_depth)
            times[form]["render"].append(render_s(scene, args.spp, rep + 1))
            times[form]["render1"] += [render_s(scene, 1, 10 * rep + k) for k in range(ONE_SPP_RENDERS)]
            for k in range(4):
                s = slice_update_s(scene, form, 1e-3 * (k % 2 + 1))
                if s is not None:
                    times[form]["slice"].append(s)
            del scene
            gc.collect()
        log(f"[{name}] rep {rep + 1}/{args.reps}: " + "  ".join(f"{f} {times[f]['render'][-1]:.3f}s" for f in FORMS))
    out = {}
    for form in FORMS:
        render, render1 = statistics.median(times[form]["render"]), statistics.median(times[form]["render1"])
        out[form] = {
            "render_s": render,
            "kernel_s": max(0.0, render1 - render / args.spp),
            "slice_s": statistics.median(times[form]["slice"]) if times[form]["slice"] else 0.0,
        }
    return out


def rows_of(name, m, ours_fixed_s, frozen, args):
    stock = m["merged"]["render_s"]
    kernel = min(m[form]["kernel_s"] for form in FORMS)  # the lower bound: the smallest of the forms' (a noisy difference)

    def projected(form, fixed_s):
        return (args.spp * (fixed_s + m[form]["slice_s"]) + m[form]["render_s"]) / stock

    return [
        {
            "scene": name, "form": form, "resolution": args.resolution, "spp": args.spp,
            "render_s": m[form]["render_s"], "per_path_vs_merged": m[form]["render_s"] / stock,
            "kernel_fixed_s": m[form]["kernel_s"], "dopplertof_fixed_s": ours_fixed_s, "slice_update_s": m[form]["slice_s"],
            "slices_per_render": args.spp, "projected_low_vs_merged": projected(form, kernel),
            "projected_high_vs_merged": projected(form, ours_fixed_s),
            "one_spp_traced_s": frozen[0], "one_spp_frozen_s": frozen[1], "frozen_image_equal": frozen[2],
        }
        for form in FORMS
    ]  # fmt: skip


def markdown_table(rows):
    lines = [
        "| scene | cubes as | path time / merged | fixed cost per kernel | scene update per slice | one scene per instant, projected / merged (kernel cost: path's - dopplertof's) |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        update = "-" if r["form"] == "merged" else f"{1e3 * r['slice_update_s']:.2f} ms"
        projected = "-" if r["form"] == "merged" else f"{r['projected_low_vs_merged']:.2f}x - {r['projected_high_vs_merged']:.2f}x"
        lines.append(
            f"| {r['scene']} | {r['form']} | {r['per_path_vs_merged']:.2f}x | {1e3 * r['kernel_fixed_s']:.1f} ms | {update} | {projected} |"
        )
    return "\n".join(lines)


def parse_args(argv=None):
    parser = _common.argument_parser(__doc__)
    parser.add_argument("--scenes", nargs="+", choices=throughput.ALL_SCENES[1:-1], default=["8-moving", "128-moving"])
    parser.add_argument("--resolution", type=int, default=None, help="film side, pixels (default 256)")
    parser.add_argument("--spp", type=int, default=None, help="paths per pixel of a render, = its slices (default 32)")
    parser.add_argument("--max-depth", type=int, default=5)
    parser.add_argument("--reps", type=int, default=None, help="interleaved repetitions (default 3)")
    _common.add_output_options(parser, "slice_cost", "32x32, 8 spp, 1 rep (smoke test)", plot=False)
    args = parser.parse_args(argv)
    quick = dict(resolution=32, spp=8, reps=1)
    _common.fill_defaults(args, quick if args.quick else dict(resolution=256, spp=32, reps=3))
    _common.require_positive(parser, args, ["resolution", "spp", "reps"])
    if args.spp <= STRATUM_SPP:
        parser.error(f"--spp must be above {STRATUM_SPP} (the fixed costs are 1 and {STRATUM_SPP} spp against --spp)")
    _common.default_output_paths(args, "slice_cost")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = f"settings: {args.resolution}x{args.resolution}, spp {args.spp}, max_depth {args.max_depth}, {args.reps} interleaved reps after 1 warm-up; timer time.perf_counter; load avg at start {_common.loadavg()}"
    run = _common.Run("slice_cost", args, argv, settings)
    ours_fixed_s = dopplertof_fixed_s(args, run.log)
    rows = []
    for name in args.scenes:
        rows += rows_of(name, measure(name, args, run.log), ours_fixed_s, frozen_kernel(name, args, run.log), args)
    print()
    print(markdown_table(rows))
    run.finish(rows, list(rows[0]))


if __name__ == "__main__":
    main()
