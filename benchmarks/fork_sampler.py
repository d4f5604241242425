#!/usr/bin/env python
"""Does the Mitsuba 3 fork's ``correlated`` sampler tie a sample's film position to its time?

The fork (juhyeonkim95/Mitsuba3DopplerToF, ``src/samplers/correlated.cpp``) seeds, per lane
``idx`` of the wavefront (pixel × spp + sample), a time stream PCG32(TEA(seed + 1, idx / 2))
and a path stream PCG32(TEA(seed + 2, idx / 2)); with path correlation the film position is
the path stream's first two numbers, and with per-interval stratification the time of
sample s lies in stratum s / 2 of spp / 2. A film position correlated with the stratum would
bias heterodyne pixels on sharp outlines only (docs/estimators.md, "Measured: moving
outlines"). This script draws the path stream's first two numbers with Mitsuba's own
``sample_tea_32`` and ``PCG32`` (the same algorithms as the fork's Dr.Jit) and measures,
per pixel, the moments mean((x − ½) g(u)) of each coordinate against g = cos 2πu, sin 2πu
and u − ½ of the stratum's centre u, as z-scores of their mean over the pixels (0 ± 1 if
uncorrelated) and the spread of the per-pixel moments relative to independence (1)::

    python benchmarks/fork_sampler.py            # 16384 pixels x 512 spp, seeds 0, 1, 5 (~10 s)
    python benchmarks/fork_sampler.py --quick    # 1024 pixels x 512 spp

Outputs: the table, and a CSV with one row per (seed, coordinate, moment).
"""

from __future__ import annotations

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

SPP = 512
SEEDS = (0, 1, 5)


def parse(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--pixels", type=int, default=None, help="pixels (default 16384; quick 1024)")
    _common.add_output_options(p, "fork_sampler", "1024 pixels", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, dict(pixels=1024 if args.quick else 16384))
    _common.require_positive(p, args, ("pixels",))
    _common.default_output_paths(args, "fork_sampler")
    return args


def main(argv=None):
    args = parse(argv)
    run = _common.Run("fork_sampler", args, argv, f"settings: {args.pixels} pixels x {SPP} spp, seeds {SEEDS}")
    import drjit as dr
    import mitsuba as mi

    pairs = SPP // 2
    u = (np.arange(pairs) + 0.5) / pairs  # the stratum's centre of each pair
    moments = {"cos": np.cos(2 * np.pi * u), "sin": np.sin(2 * np.pi * u), "linear": u - 0.5}
    rows = []
    for seed in SEEDS:
        key = dr.arange(mi.UInt32, args.pixels * pairs)  # idx / 2 = pixel * spp / 2 + pair
        v0, v1 = mi.sample_tea_32(mi.UInt32(seed + 2), key)
        rng = mi.PCG32()
        rng.seed(mi.UInt64(v0), mi.UInt64(v1))
        coordinates = {"x": np.array(rng.next_float32()), "y": np.array(rng.next_float32())}
        for name, values in coordinates.items():
            values = values.reshape(args.pixels, pairs) - 0.5
            for moment, g in moments.items():
                per_pixel = (values * g).mean(axis=1)
                null = np.sqrt(np.mean(g**2) / 12 / pairs)  # its standard deviation if uncorrelated
                rows.append(dict(seed=seed, coordinate=name, moment=moment, z_of_mean=float(per_pixel.mean() / (null / np.sqrt(args.pixels))), spread_ratio=float(per_pixel.std() / null)))
    print("\n| seed | coordinate | moment | z of the mean over pixels | per-pixel spread / independent |\n|---:|---|---|---:|---:|")
    for r in rows:
        print(f"| {r['seed']} | {r['coordinate']} | {r['moment']} | {r['z_of_mean']:+.2f} | {r['spread_ratio']:.3f} |")
    return run.finish(rows, list(rows[0]))


if __name__ == "__main__":
    raise SystemExit(main())
