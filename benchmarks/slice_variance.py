#!/usr/bin/env python
"""Per-pixel error of time slices (issue 17, DESIGN §6), emulated on today's per-lane tracer.

One scene per instant traces every lane of a kernel at one time, so a render's times are
shared by all its pixels. Where a scene is frozen at a time the per-lane tracer computes the
same paths, so it can trace that estimator before it exists: a lane's time is drawn from
numbers seeded by (seed, slice) instead of (seed, pixel, group). With S slices, group g of
every pixel takes slice g mod S, whose time is drawn as group s's would be in a render of S
groups (the same strata, one rotation for all pixels). S = G (the spp's groups: the issue's
design) keeps each pixel's estimator's distribution exactly; S < G would cut the kernels a
render needs (``slice_cost.py``) and shares a time among G/S groups of a pixel::

    python benchmarks/slice_variance.py                 # 64x64, 64 spp x 12 repeats, reference 16384 spp (~4 min on 2 cores)
    python benchmarks/slice_variance.py --quick         # 16x16, 16 spp x 3 repeats, reference 1024 spp (< 1 min)
    python benchmarks/slice_variance.py --scenes rotating --slices 32 8

D-ToF with the six cameras h ∈ {0, ½, 1} x ψ ∈ {0, π/2}, antithetic times and replay (the
render defaults), against a reference of the per-lane tracer at ``--ref-spp`` (seed 1000003).
Reported per scene, configuration, h (both ψ summed) and region (``moving``: |velocity| or
|point_velocity| above 1 mm/s in the reference; ``all``):

* ``mse``: mean over the region's pixels and the repeats of (x − ref)², less the reference's
  own variance; ``mse_vs_per_lane``: its ratio to the per-lane tracer's (issue 17 asks for
  ≤ 1.1 on the moving Cornell box and the merry-go-round);
* ``z_spread``: the standard deviation of z = (x − ref) / sqrt(stderr² + stderr_ref²) over
  the region's pixels and repeats (less those both renders determine exactly, such as a
  static pixel at h = 1): 1 where the standard errors are calibrated and have many degrees
  of freedom (a pixel's strata give spp/4 here);
* ``beyond_3``: the fraction of those z beyond ±3 (0.27 % for a normal, 0.85 % for Student's
  t with 16 degrees of freedom);
* ``variance_vs_stated``: each pixel's variance over the repeats, averaged over the region,
  over the mean stated variance (stderr²): 1 where the standard errors are right on aggregate.
"""

from __future__ import annotations

import contextlib
import dataclasses
import statistics
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
from _common import CAMERA_GRID
from variance import REFERENCE, REFERENCE_SEED, build_scene, moving_mask, render_config

SCENE_NAMES = ("cornell-box", "rotating")
STREAM_SLICE = 0x5EED5100  # the slices' times: a stream the package does not use
PER_LANE = 0  # configuration "per-lane": today's tracer


@contextlib.contextmanager
def slices(count):
    """Within the block, every render draws its lanes' times from ``count`` slices shared
    by all pixels (``PER_LANE``: unchanged)."""
    from dopplertof.tracing import lanes

    if count == PER_LANE:
        yield
        return
    shipped = lanes.sample_time

    def sliced(setup, settings, seed, pixel, group, member, r_shared, r_own):
        import mitsuba as mi

        from dopplertof.timesampling import sample_times

        if setup.n_groups % count:
            raise ValueError(f"{count} slices do not divide the {setup.n_groups} groups of a pixel")
        s = group % lanes.opaque_u32(count)
        everywhere = mi.UInt32(0)  # the pixel's place in the seeds: one value for all pixels
        r_slice = lanes.seeded_pcg(seed, STREAM_SLICE, everywhere, s).next_float32()
        key = mi.UInt32(member) if settings.time_sampling == "stratified" else mi.UInt32(0)
        rotation = lanes.seeded_pcg(seed, lanes.STREAM_ROTATION, everywhere, key).next_float32()
        layout = dataclasses.replace(setup, first_sample=0, samples=count * setup.n_times, spp_total=count * setup.n_times)
        place, n = lanes.stratum(layout, s, settings.wraps, rotation)
        return sample_times(
            settings.time_sampling, r_slice, r_own, place, n, count, mi.UInt32(member), setup.n_times,
            settings.shift, settings.stratify_intervals,
        )  # fmt: skip

    lanes.sample_time = sliced
    try:
        yield
    finally:
        lanes.sample_time = shipped


def measure(scene, cameras, count, args, reference, masks):
    """{(camera, region): (mse, z_spread, fraction of |z| > 3, variance over repeats / stated)}
    over ``args.repeats`` renders with ``count`` slices."""
    ref = reference.measurements.astype(np.float64)
    ref_var = reference.measurement_stderr.astype(np.float64) ** 2
    sq = {key: [] for key in ((i, r) for i in range(len(cameras)) for r in masks)}
    zs = {key: [] for key in sq}
    values, stated = ({key: [] for key in sq} for _ in range(2))
    seconds = []
    with slices(count):
        for rep in range(args.repeats):
            t = time.perf_counter()
            result = render_config(scene, cameras, *REFERENCE, args.spp, rep, args.max_depth)
            seconds.append(time.perf_counter() - t)
            x = result.measurements.astype(np.float64)
            var = result.measurement_stderr.astype(np.float64) ** 2
            for i, region in sq:
                m = masks[region]
                d = x[i][m] - ref[i][m]
                sq[(i, region)].append(d * d - ref_var[i][m])
                values[(i, region)].append(x[i][m])
                stated[(i, region)].append(var[i][m])
                both = var[i][m] + ref_var[i][m]
                zs[(i, region)].append(d[both > 0] / np.sqrt(both[both > 0]))  # not the pixels both renders determine exactly
    out = {
        key: (
            float(np.mean(sq[key])), float(np.std(np.concatenate(zs[key]))), float(np.mean(np.abs(np.concatenate(zs[key])) > 3)),
            float(np.var(values[key], axis=0, ddof=1).mean() / np.mean(stated[key])),
        )
        for key in sq
    }
    return out, statistics.median(seconds)


def bench_scene(name, args, log):
    scene, description = build_scene(name, args.resolution)
    cameras = [dopplertof.Camera(heterodyne=h, phase=psi) for h, psi in CAMERA_GRID]
    t = time.perf_counter()
    reference = render_config(scene, cameras, *REFERENCE, args.ref_spp, REFERENCE_SEED, args.max_depth)
    log(f"[{name}] {description}; reference {args.ref_spp} spp: {time.perf_counter() - t:.1f} s")
    masks = {"all": np.ones(reference.measurements.shape[1:], dtype=bool), "moving": moving_mask(reference)}
    log(f"[{name}] moving pixels: {int(masks['moving'].sum())} of {masks['moving'].size}")
    if not masks["moving"].any():
        del masks["moving"]
    results = {}
    for count in [PER_LANE, *args.slices]:
        results[count], seconds = measure(scene, cameras, count, args, reference, masks)
        label = "per-lane" if count == PER_LANE else f"{count} slices"
        log(f"[{name}] {label}: {seconds:.2f} s/render")
    rows = []
    for count, stats in results.items():
        for region in masks:
            for h in sorted({h for h, _ in CAMERA_GRID}):
                cams = [i for i, (hh, _) in enumerate(CAMERA_GRID) if hh == h]
                mse = sum(stats[(i, region)][0] for i in cams)
                base = sum(results[PER_LANE][(i, region)][0] for i in cams)
                rows.append({
                    "scene": name, "config": "per-lane" if count == PER_LANE else f"{count} slices", "slices": count,
                    "groups": args.spp // 2, "region": region, "pixels": int(masks[region].sum()), "h": h, "mse": mse,
                    "mse_vs_per_lane": mse / base if base > 0 else float("nan"),
                    "z_spread": statistics.fmean(stats[(i, region)][1] for i in cams),
                    "beyond_3": statistics.fmean(stats[(i, region)][2] for i in cams),
                    "variance_vs_stated": statistics.fmean(stats[(i, region)][3] for i in cams),
                })  # fmt: skip
    return rows


def markdown_table(rows):
    lines = [
        "| scene | region | configuration | MSE / per-lane, h = 0 | h = ½ | h = 1 | z spread, h = 0 | h = ½ | h = 1 | variance / stated, h = 0 | h = ½ | h = 1 |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    keys = sorted({(r["scene"], r["region"], r["slices"]) for r in rows}, key=lambda k: (k[0], k[1] != "moving", k[2] != PER_LANE, -k[2]))
    for scene, region, count in keys:
        rs = sorted((r for r in rows if (r["scene"], r["region"], r["slices"]) == (scene, region, count)), key=lambda r: r["h"])
        lines.append(
            f"| {scene} | {region} | {rs[0]['config']} | " + " | ".join(f"{r['mse_vs_per_lane']:.3f}" for r in rs) + " | "
            + " | ".join(f"{r['z_spread']:.2f}" for r in rs) + " | "
            + " | ".join(f"{r['variance_vs_stated']:.2f}" for r in rs) + " |"
        )  # fmt: skip
    return "\n".join(lines)


def parse_args(argv=None):
    parser = _common.argument_parser(__doc__)
    parser.add_argument("--scenes", nargs="+", choices=SCENE_NAMES, default=list(SCENE_NAMES))
    parser.add_argument("--resolution", type=int, default=None, help="film side, pixels (default 64)")
    parser.add_argument("--spp", type=int, default=None, help="paths per pixel, even (default 64: 32 antithetic groups)")
    parser.add_argument("--repeats", type=int, default=None, help="renders per configuration, seeds 0.. (default 12)")
    parser.add_argument("--ref-spp", type=int, default=None, help="paths per pixel of the reference (default 16384)")
    parser.add_argument("--slices", type=int, nargs="+", default=None, help="slice counts, each dividing spp/2 (default: spp/2, then /2 down to 2)")
    parser.add_argument("--max-depth", type=int, default=4)
    _common.add_output_options(parser, "slice_variance", "16x16, 16 spp x 3 repeats, reference 1024 spp (smoke test)", plot=False)
    args = parser.parse_args(argv)
    _common.fill_defaults(args, dict(resolution=16, spp=16, repeats=3, ref_spp=1024) if args.quick else dict(resolution=64, spp=64, repeats=12, ref_spp=16384))
    _common.require_positive(parser, args, ["resolution", "spp", "repeats", "ref_spp"])
    if args.spp % 2:
        parser.error(f"--spp must be even (antithetic pairs), got {args.spp}")
    groups = args.spp // 2
    if args.slices is None:
        args.slices = [groups >> k for k in range(groups.bit_length()) if groups >> k >= 2 and groups % (groups >> k) == 0]
    bad = [s for s in args.slices if s < 1 or groups % s]
    if bad:
        parser.error(f"--slices must divide the {groups} groups of a pixel, got {bad}")
    _common.default_output_paths(args, "slice_variance")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = f"settings: {args.resolution}x{args.resolution}, spp {args.spp} ({args.spp // 2} groups), {args.repeats} repeats, reference {args.ref_spp} spp, max_depth {args.max_depth}, slices {args.slices}; load avg at start {_common.loadavg()}"
    run = _common.Run("slice_variance", args, argv, settings)
    rows = []
    for name in args.scenes:
        rows += bench_scene(name, args, run.log)
    print()
    print(markdown_table(rows))
    run.finish(rows, list(rows[0]))


if __name__ == "__main__":
    main()
