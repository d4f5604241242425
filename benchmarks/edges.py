#!/usr/bin/env python
"""Our renders of the moving boxes' outlines against an independent per-pixel oracle, in the
side-by-side protocol of the Mitsuba 3 fork comparison (issue 18, item 5).

The Cornell box (boxes at ∓10 m/s, point light at the camera), direct light (max_depth 2),
cameras h = 1 at ψ ∈ {0, π/2} and h = 0. The outline pixels are those a box covers partly
at the exposure's start or end, or differently at the two
(:func:`dopplertof.oracles.moving_outline_pixels`). There the oracle
(:func:`dopplertof.oracles.direct_light_pixels`: quadrature over stock ``mi.load_dict``
scenes with the boxes baked at fixed instants, stock rays and shading, W per ray) gives
each pixel with its standard error; ours is the mean of independent seeds, its error from
the renders' replicates. Also against the oracle of a geometry frozen at mid-exposure (W
still running): what a comparison that resolves the outlines' motion must reject::

    python benchmarks/edges.py            # 128x128, 16 seeds x 512 spp, as the fork comparison (~4 min, 2 cores)
    python benchmarks/edges.py --quick    # 32x32, 4 seeds x 256 spp (< 1 min)
    python benchmarks/edges.py --filter gaussian --resolution 64 --seeds 8 --spp 2048 --oracle-replicates 32 \
        --estimators antithetic+replay uniform --csv benchmarks/results/edges_gaussian.csv

Outputs: per estimator, camera and reference (``oracle``, ``frozen``) the z-scores'
mean, spread and share beyond |z| = 3, printed as a table and written to the CSV.
"""

from __future__ import annotations

import math

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

EXPOSURE_S = 1.5e-3
CAMERAS = [(1.0, 0.0), (1.0, math.pi / 2), (0.0, 0.0)]
ESTIMATORS = {"antithetic+replay": dict(time_sampling="antithetic", correlation="replay"), "uniform": dict(time_sampling="uniform", correlation="none")}
# film positions per side of the filter's support (1, 2 and 4 pixels) at each of the oracle's instants
ORACLE_GRID = {"box": 16, "tent": 24, "gaussian": 32}
DEFAULTS = dict(resolution=128, seeds=16, spp=512)
QUICK = dict(resolution=32, seeds=4, spp=256)


def parse(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="film side, pixels (default 128; quick 32)")
    p.add_argument("--seeds", type=int, default=None, help="independent renders per estimator (default 16; quick 4)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel of each render (default 512; quick 256)")
    p.add_argument("--estimators", nargs="+", choices=list(ESTIMATORS), default=["antithetic+replay"])
    p.add_argument("--filter", choices=list(ORACLE_GRID), default="box", help="the film's reconstruction filter (default box, the scene's)")
    p.add_argument("--oracle-replicates", type=int, default=16, help="independent replicates of the oracle (default 16)")
    _common.add_output_options(p, "edges", "small settings (< 1 min)", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, QUICK if args.quick else DEFAULTS)
    _common.require_positive(p, args, ("resolution", "seeds", "spp", "oracle_replicates"))
    _common.default_output_paths(args, "edges")
    return args


def z_summary(ours, ours_se, reference, reference_se):
    """(mean, std, share beyond 3) of the z-scores per camera."""
    z = (ours - reference) / np.sqrt(ours_se**2 + reference_se**2)
    return [(float(zc.mean()), float(zc.std()), float(np.mean(np.abs(zc) > 3))) for zc in z]


def main(argv=None):
    args = parse(argv)
    grid = ORACLE_GRID[args.filter]
    settings = (
        f"settings: cornell-box {args.resolution}x{args.resolution}, {args.filter} filter, max_depth 2, {args.seeds} seeds x {args.spp} spp per estimator, "
        f"oracle {args.oracle_replicates} replicates x 8 instants x {grid}x{grid} film positions over the filter's support (frozen: 4 replicates)"
    )  # fmt: skip
    run = _common.Run("edges", args, argv, settings)
    from dopplertof import oracles

    cameras = [dopplertof.Camera(heterodyne=h, phase=psi) for h, psi in CAMERAS]
    scene_dict = dopplertof.scenes.cornell_box_dict(resolution=args.resolution)
    film = dict(scene_dict["sensor"]["film"], rfilter={"type": args.filter})
    scene_dict = dict(scene_dict, sensor=dict(scene_dict["sensor"], film=film))
    pixels = oracles.moving_outline_pixels(scene_dict, 0.0, EXPOSURE_S)
    run.log(f"{len(pixels)} outline pixels")
    references = {
        "oracle": oracles.direct_light_pixels(scene_dict, cameras, pixels, time_strata=4, grid=grid, replicates=args.oracle_replicates, seed=1),
        "frozen": oracles.direct_light_pixels(scene_dict, cameras, pixels, time_strata=4, grid=grid, replicates=4, seed=2, frozen_at_s=EXPOSURE_S / 2),
    }
    run.log("oracles done")
    scene = dopplertof.load_scene(scene_dict)
    rows = []
    for name in args.estimators:
        values, errors = [], []
        for seed in range(1, args.seeds + 1):
            result = dopplertof.render(scene, cameras, spp=args.spp, max_depth=2, seed=seed, **ESTIMATORS[name])
            values.append(result.measurements[:, pixels[:, 1], pixels[:, 0]])
            errors.append(result.measurement_stderr[:, pixels[:, 1], pixels[:, 0]])
        ours, ours_se = np.mean(values, axis=0), np.sqrt(np.sum(np.square(errors), axis=0)) / args.seeds
        run.log(f"{name} rendered")
        for reference, (value, se) in references.items():
            for (h, psi), (mean, std, beyond) in zip(CAMERAS, z_summary(ours, ours_se, value, se)):
                rows.append(dict(estimator=name, h=h, psi=psi, reference=reference, pixels=len(pixels), z_mean=mean, z_std=std, beyond_3=beyond))
    print("\n| estimator | camera | against | z mean | z spread | beyond \\|z\\| = 3 |\n|---|---|---|---:|---:|---:|")
    for r in rows:
        print(f"| {r['estimator']} | h={r['h']:g}, ψ={r['psi']:.3g} | {r['reference']} | {r['z_mean']:+.2f} | {r['z_std']:.2f} | {r['beyond_3']:.1%} |")
    return run.finish(rows, list(rows[0]))


if __name__ == "__main__":
    raise SystemExit(main())
