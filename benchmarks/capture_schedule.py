#!/usr/bin/env python
"""The motion artefact of a capture schedule: a moving edge, four cameras one after another
versus all four at once.

A box approaches the camera and slides sideways in front of a static wall, so that one
vertical edge of it crosses the film; a point light sits at the camera, direct light only
(``max_depth=2``). The four cameras h ∈ {0, 1} × ψ ∈ {0°, 90°} (f_g 30 MHz, T 1.5 ms)
are rendered twice:

* simultaneous: all four in one exposure window [0, T], from the same paths;
* sequential: camera i in its own window [iT, (i+1)T] (``Camera.exposure_start``), as a
  sensor that captures its correlation images one after another does.

Both are reconstructed with :func:`dopplertof.reconstruct.velocity` given the render (it
models the motion between the windows: a constant radial velocity and radiance per pixel)
and compared with the ground truth of the first window ([0, T], the result's reference
window). Pixels are classified from the geometry: *edge* where the box's edge passes
during the schedule [0, 4T] (± 1 pixel), *box* and *wall* elsewhere::

    python benchmarks/capture_schedule.py            # 64x64, 256 spp (~1 min, 2 cores)
    python benchmarks/capture_schedule.py --quick    # 32x32, 64 spp (< 30 s)

Printed and written to CSV, per schedule and region: the pixel count, the fraction with a
valid velocity, the RMSE and the largest |error| (m/s) of the valid ones. The PNG next to
the CSV shows the ground truth, both reconstructions and the column profile of the
velocity (median over the rows; NaN left out).
"""

from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

FOV_DEG = 30.0
EXPOSURE_S = 1.5e-3
WINDOWS = 4  # one camera per window in the sequential schedule
BOX_FRONT_M = 4.0  # distance of the box's front face at t = 0
BOX_SIZE_M = (2.0, 4.0, 1.0)  # x, y, z: taller than the film's view, its right edge near the centre
BOX_EDGE_X_M = -0.1  # the box's right edge at t = 0
WALL_M = 6.0
VELOCITY_M_S = (50.0, 0.0, 30.0)  # sideways (+x, right) and towards the camera (+z)
LIGHT_W_SR = 60.0


def scene(resolution):
    """The box in front of the wall (module docstring), moving over the whole schedule."""
    import mitsuba as mi

    from dopplertof import load_scene

    sx, sy, sz = (0.5 * s for s in BOX_SIZE_M)
    centre = (BOX_EDGE_X_M - sx, 0.0, -BOX_FRONT_M - sz)
    start = mi.ScalarTransform4d().translate(list(centre)) @ mi.ScalarTransform4d().scale([sx, sy, sz])
    duration = WINDOWS * EXPOSURE_S
    end = mi.ScalarTransform4d().translate([v * duration for v in VELOCITY_M_S]) @ start
    return load_scene({
        "type": "scene",
        "sensor": {
            "type": "perspective", "fov": FOV_DEG,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": resolution, "height": resolution, "rfilter": {"type": "box"}},
        },
        "light": {"type": "point", "position": [0, 0, 0], "intensity": {"type": "rgb", "value": [LIGHT_W_SR] * 3}},
        "wall": {"type": "rectangle", "to_world": _common.transform((0, 0, -WALL_M), scale=(8, 8, 1)), "bsdf": _common.diffuse((0.5, 0.5, 0.5))},
        "box": {"type": "cube", "bsdf": _common.diffuse((0.8, 0.8, 0.8)), "motion": {"type": "keyframes", "keys": [(0.0, start), (duration, end)]}},
    })  # fmt: skip


def edge_column(t_s, resolution):
    """Film column (pixels from the left, continuous) of the box's edge at time ``t_s``;
    the box covers the columns left of it."""
    x = BOX_EDGE_X_M + VELOCITY_M_S[0] * t_s
    depth = BOX_FRONT_M - VELOCITY_M_S[2] * t_s
    return 0.5 * resolution * (1.0 + x / depth / math.tan(math.radians(FOV_DEG) / 2))


def regions(resolution):
    """Column masks: ``edge`` where the box's edge passes during [0, 4T] (± 1 pixel), the
    ``box`` left of it, the ``wall`` right of it."""
    a, b = sorted(edge_column(t, resolution) for t in (0.0, WINDOWS * EXPOSURE_S))
    columns = np.arange(resolution) + 0.5
    edge = (columns > a - 1.5) & (columns < b + 1.5)
    return {"box": (columns < a) & ~edge, "edge": edge, "wall": (columns > b) & ~edge}


def cameras(sequential):
    base = [dopplertof.Camera(exposure=EXPOSURE_S, heterodyne=h, phase=psi) for h in (0.0, 1.0) for psi in (0.0, math.pi / 2)]
    if not sequential:
        return base
    return [dataclasses.replace(c, exposure_start=i * EXPOSURE_S) for i, c in enumerate(base)]


def measure(args, log):
    from dopplertof import reconstruct

    sc = scene(args.resolution)
    masks = regions(args.resolution)
    rows, maps = [], {}
    for name, sequential in (("simultaneous", False), ("sequential", True)):
        result = dopplertof.render(sc, cameras=cameras(sequential), spp=args.spp, max_depth=2, seed=args.seed)
        log(f"{name}: rendered in {result.info['render_seconds']:.1f} s, windows {result.info['windows']}")
        rec = reconstruct.velocity(result)
        truth = result.velocity
        maps[name] = rec.velocity
        maps["truth"] = truth
        error = rec.velocity - truth
        for region, columns in masks.items():
            mask = np.broadcast_to(columns[None, :], truth.shape) & np.isfinite(truth)
            valid = mask & rec.valid
            e = error[valid]
            rows.append(dict(
                schedule=name, region=region, pixels=int(mask.sum()), valid_fraction=float(valid.sum() / max(mask.sum(), 1)),
                rmse_m_s=float(np.sqrt(np.mean(e * e))) if e.size else float("nan"),
                max_abs_error_m_s=float(np.abs(e).max()) if e.size else float("nan"), method=rec.method,
            ))  # fmt: skip
    return rows, maps, masks


def markdown_table(rows):
    lines = ["| schedule | region | pixels | valid | RMSE (m/s) | max abs error (m/s) |", "|---|---|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['schedule']} ({r['method']}) | {r['region']} | {r['pixels']} | {r['valid_fraction']:.0%} | {r['rmse_m_s']:.3g} | {r['max_abs_error_m_s']:.3g} |")
    return "\n".join(lines)


def plot(path, maps, masks):
    from matplotlib.figure import Figure

    vmax = 1.5 * abs(VELOCITY_M_S[2])
    figure = Figure(figsize=(13.0, 3.6), layout="constrained")
    axes = figure.subplots(1, 4, width_ratios=[1, 1, 1, 1.5])
    titles = {"truth": "ground truth, [0, T]", "simultaneous": "4 cameras in [0, T]", "sequential": "camera i in [iT, (i+1)T]"}
    for ax, (key, title) in zip(axes, titles.items()):
        image = ax.imshow(np.ma.masked_invalid(maps[key]), cmap="RdBu_r", vmin=-vmax, vmax=vmax, interpolation="nearest")
        image.cmap.set_bad("0.6")
        ax.set_title(title, fontsize=10)
        ax.set_axis_off()
    figure.colorbar(image, ax=list(axes[:3]), shrink=0.8, label="radial velocity (m/s)")
    profile = axes[3]
    columns = np.arange(maps["truth"].shape[1])
    for key, style in (("truth", "k-"), ("simultaneous", "C0o-"), ("sequential", "C3s-")):
        with np.errstate(all="ignore"):
            profile.plot(columns, np.nanmedian(maps[key], axis=0), style, markersize=3, label=titles[key])
    edge = columns[masks["edge"]]
    profile.axvspan(edge.min() - 0.5, edge.max() + 0.5, color="0.85", label="edge passes in [0, 4T]")
    profile.set_ylim(-vmax, vmax)
    profile.set_xlabel("film column")
    profile.set_ylabel("velocity, median over rows (m/s)")
    profile.grid(True, alpha=0.3)
    profile.legend(fontsize=8, loc="upper left")
    figure.suptitle(f"Capture schedule: a box edge moving at {VELOCITY_M_S[0]:g} m/s sideways and {VELOCITY_M_S[2]:g} m/s towards the camera")
    _common._make_folder_of(path)
    figure.savefig(path, dpi=110)


CSV_FIELDS = ["schedule", "method", "region", "pixels", "valid_fraction", "rmse_m_s", "max_abs_error_m_s"]


def parse_args(argv=None):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="square film side, pixels (default 64; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel per render (even; default 256; quick 64)")
    p.add_argument("--seed", type=int, default=1)
    _common.add_output_options(p, "capture_schedule", quick_help="smoke test: 32x32, 64 spp (< 30 s)")
    args = p.parse_args(argv)
    _common.fill_defaults(args, dict(resolution=32, spp=64) if args.quick else dict(resolution=64, spp=256))
    _common.require_positive(p, args, ("resolution", "spp"))
    _common.default_output_paths(args, "capture_schedule")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = (
        f"settings: {args.resolution}x{args.resolution}, spp {args.spp}, seed {args.seed}, max_depth 2, f_g 30 MHz, "
        f"T {EXPOSURE_S * 1e3:g} ms, box at {BOX_FRONT_M:g} m moving {VELOCITY_M_S} m/s, wall at {WALL_M:g} m"
    )
    run = _common.Run("capture_schedule", args, argv, settings)
    rows, maps, masks = measure(args, run.log)
    print()
    print(markdown_table(rows))
    return run.finish(rows, CSV_FIELDS, plot=lambda path: plot(path, maps, masks))


if __name__ == "__main__":
    sys.exit(main())
