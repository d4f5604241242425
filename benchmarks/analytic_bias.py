#!/usr/bin/env python
"""Bias of the analytic (closed-form, biased by design) time integration against an unbiased render.

For each scene it renders an unbiased reference (antithetic times, replayed paths, high spp)
and ``time_sampling="analytic"`` with each correlation (``replay``: the partner path replays
the primal at the exposure's end; ``reconnection``: it goes through the primal's vertices),
all with the cameras h ∈ {0, 1} × ψ ∈ {0, π/2} from the same paths, and measures per
camera and image region the relative bias of the region's sum::

    python benchmarks/analytic_bias.py            # 64x64, analytic 256 spp, reference 16384 spp, depth 4 (~2 min, 2 cores)
    python benchmarks/analytic_bias.py --quick    # 16x16, 64 / 1024 spp (< 30 s)

Definitions:

* relative bias of region R = Σ_R (analytic − reference) / Σ_R |reference|, in %; its noise
  (``bias_se``) from both renders' standard errors, √Σ_R (s_a² + s_ref²) / Σ_R |reference|;
  the signed ratio Σ_R analytic / Σ_R reference − 1 is in the CSV as ``sum_ratio_minus_1``;
* regions: ``all`` pixels, ``moving`` (reference ground-truth velocity above 1 mm/s) and one
  per moving body (pixels whose camera ray hits the body: ``instance_id``);
* the analytic mode takes each contribution X and optical length L at the exposure's start
  and end as linear in time between them; a contribution present at one end and missing at
  the other (shadowed, its partner path gone, an emitter seen at one end only) ramps
  linearly to or from zero (:meth:`dopplertof.tracing.sink.Sink.add_analytic`).

Scenes: ``cornell-box`` (boxes at ∓10 m/s, point light at the camera), ``rotating``
(merry-go-round, exposure opening at half its clip), and ``occluder``: the Cornell room
lit by a ceiling area light with a thin bar sliding sideways at 40 m/s in front of the back
wall, so that its silhouette and its shadow sweep about 1.6 pixels (at 64²) during the
exposure: occlusion changes.

Outputs: a CSV with one row per (scene, correlation, camera, region); the table of the
bias at h = 1 and h = 0 (ψ averaged) is printed.
"""

from __future__ import annotations

import math

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common
from _common import WHITE, diffuse, transform

SCENE_NAMES = ("cornell-box", "rotating", "occluder")
CAMERAS = [(h, psi) for h in (0.0, 1.0) for psi in (0.0, math.pi / 2)]
MOVING_THRESHOLD_M_S = 1e-3
REFERENCE_SEED = 1_000_003
OCCLUDER_SPEED_M_S = 40.0
EXPOSURE_S = 1.5e-3
DEFAULTS = {"resolution": 64, "spp": 256, "ref_spp": 16384}
QUICK = {"resolution": 16, "spp": 64, "ref_spp": 1024}


def occluder_scene(resolution):
    """The Cornell room under a ceiling area light with a bar (8 cm × 1.2 m × 8 cm) at
    z = 0.2 m sliding in +x at ``OCCLUDER_SPEED_M_S`` over [0, T]."""
    from dopplertof.scenes import _translation_keys

    scene = _common.cornell_room(resolution)
    scene["light"] = {
        "type": "rectangle",
        "to_world": transform((0, 1.99, 0), rotate_x_deg=90, scale=(0.25, 0.2, 1)),
        "bsdf": diffuse(WHITE),
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [17.0, 12.0, 4.0]}},
    }
    bar = transform((-0.2, 0.6, 0.2), scale=(0.04, 0.6, 0.04))
    scene["bar"] = {"type": "cube", "bsdf": diffuse(WHITE), "motion": _translation_keys(bar, (OCCLUDER_SPEED_M_S * EXPOSURE_S, 0, 0), EXPOSURE_S)}
    return dopplertof.load_scene(scene)


def build_scene(name, resolution):
    """(scene, exposure_start_s) of a benchmark scene."""
    from dopplertof import scenes

    if name == "occluder":
        return occluder_scene(resolution), 0.0
    start = scenes.clip_duration(name) / 2 if name == "rotating" else 0.0
    return scenes.build(name, resolution=resolution), start


def regions(scene, reference):
    """{name: boolean mask (H, W)}: all, moving, and one per moving body."""
    speeds = np.nan_to_num(np.maximum(np.abs(reference.velocity), np.abs(reference.point_velocity)), nan=0.0)
    masks = {"all": np.ones(speeds.shape, dtype=bool), "moving": speeds > MOVING_THRESHOLD_M_S}
    for index, body in enumerate(scene.bodies):
        mask = reference.instance_id == index
        if mask.any():  # a body of several shapes is named after its first
            masks[body.name.split(",")[0] + (", …" if "," in body.name else "")] = mask
    return masks


def bias_rows(name, correlation, analytic, reference, masks):
    rows = []
    for i, (h, psi) in enumerate(CAMERAS):
        a = analytic.measurements[i].astype(np.float64)
        r = reference.measurements[i].astype(np.float64)
        var = analytic.measurement_stderr[i].astype(np.float64) ** 2 + reference.measurement_stderr[i].astype(np.float64) ** 2
        for region, mask in masks.items():
            scale = float(np.abs(r[mask]).sum())
            difference = float((a[mask] - r[mask]).sum())
            rows.append(dict(
                scene=name, correlation=correlation, h=h, psi=psi, region=region, pixels=int(mask.sum()),
                bias_pct=100.0 * difference / scale, bias_se_pct=100.0 * math.sqrt(float(var[mask].sum())) / scale,
                sum_ratio_minus_1=float(a[mask].sum()) / float(r[mask].sum()) - 1.0,
            ))  # fmt: skip
    return rows


def parse_args(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help=f"square film side (default {DEFAULTS['resolution']}; quick {QUICK['resolution']})")
    p.add_argument("--spp", type=int, default=None, help=f"paths per pixel of the analytic render (default {DEFAULTS['spp']}; quick {QUICK['spp']})")
    p.add_argument("--ref-spp", type=int, default=None, help=f"paths per pixel of the reference (default {DEFAULTS['ref_spp']}; quick {QUICK['ref_spp']})")
    p.add_argument("--max-depth", type=int, default=4, help="path depth (default 4)")
    p.add_argument("--scenes", nargs="+", choices=SCENE_NAMES, default=list(SCENE_NAMES))
    p.add_argument("--correlations", nargs="+", choices=("replay", "reconnection", "adaptive"), default=["replay", "reconnection"])
    _common.add_output_options(p, "analytic_bias", "small settings (< 30 s)", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, QUICK if args.quick else DEFAULTS)
    _common.require_positive(p, args, ("resolution", "spp", "ref_spp"))
    _common.default_output_paths(args, "analytic_bias")
    return args


def main(argv=None):
    args = parse_args(argv)
    settings = (
        f"settings: {args.resolution}x{args.resolution}, analytic + {' / '.join(args.correlations)} {args.spp} spp (seed 0), reference antithetic + replay "
        f"{args.ref_spp} spp (seed {REFERENCE_SEED}), max_depth {args.max_depth}, cameras h in (0, 1) x psi in (0, pi/2)"
    )
    run = _common.Run("analytic_bias", args, argv, settings)
    cameras = [dopplertof.Camera(heterodyne=h, phase=psi) for h, psi in CAMERAS]
    rows = []
    for name in args.scenes:
        scene, start = build_scene(name, args.resolution)
        common = dict(cameras=cameras, max_depth=args.max_depth, exposure_start=start)
        reference = dopplertof.render(scene, spp=args.ref_spp, seed=REFERENCE_SEED, time_sampling="antithetic", correlation="replay", **common)
        masks = regions(scene, reference)
        for correlation in args.correlations:
            analytic = dopplertof.render(scene, spp=args.spp, seed=0, time_sampling="analytic", correlation=correlation, **common)
            rows += bias_rows(name, correlation, analytic, reference, masks)
        run.log(f"[{name}] rendered")
    print()
    print("relative bias of the region's sum, mean over ψ = 0, π/2, % of Σ|reference| (± noise)")
    print("| scene | correlation | region | pixels | h = 1 | h = 0 |")
    print("|---|---|---|---:|---:|---:|")
    for key in dict.fromkeys((r["scene"], r["correlation"], r["region"]) for r in rows):
        chosen = {h: [r for r in rows if (r["scene"], r["correlation"], r["region"]) == key and r["h"] == h] for h in (0.0, 1.0)}
        cells = []
        for h in (1.0, 0.0):
            bias = np.mean([r["bias_pct"] for r in chosen[h]])
            noise = math.sqrt(np.mean([r["bias_se_pct"] ** 2 for r in chosen[h]]) / len(chosen[h]))
            cells.append(f"{bias:+.2f} % ± {noise:.2f}")
        print(f"| {' | '.join(key)} | {chosen[1.0][0]['pixels']} | {cells[0]} | {cells[1]} |")
    return run.finish(rows, list(rows[0]))


if __name__ == "__main__":
    raise SystemExit(main())
