#!/usr/bin/env python
"""What codes and sensors cost: the render time of coded cameras against named waveforms,
and the throughput of the noise chain.

Part 1 renders the Cornell box (point light, two moving boxes) with six cameras
h ∈ {0, ½, 1} × ψ ∈ {0°, 90°} of one kind at a time, interleaved over repetitions (median
time): the named sinusoid (the closed form the kernel had before codes), the same sinusoid
as Fourier coefficients (harmonic form, M = 1), a band-limited code of 8 harmonics, a
sampled square of 16 chips (the table form: two gathers per contribution), and the sampled
square in full-waveform mode; plus the render without cameras. Part 2 reads out the
MLX75027 preset's default schedule (4 frames × 2 taps) at 640×480 many times::

    python benchmarks/sensors.py            # 64x64, 64 spp, 5 repetitions (~1 min, 2 cores)
    python benchmarks/sensors.py --quick    # 32x32, 16 spp, 3 repetitions (< 20 s)

Printed and written to CSV: per configuration the median render time (s) and its ratio to
the named sinusoid's; the read-out's time per sensor frame (ms) and its rate (Mpixel·taps/s).
The machine is shared: compare ratios, not seconds.
"""

from __future__ import annotations

import math
import statistics
import sys
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

CSV_FIELDS = ["part", "configuration", "median_s", "relative_to_named_sinusoid", "rate"]


def _square(n=16):
    return np.sign(np.cos(2 * math.pi * (np.arange(n) + 0.5) / n))


def configurations():
    """name -> the six cameras of that kind (module docstring)."""
    from dopplertof import Camera, codes

    rng = np.random.default_rng(0)
    band = codes.fourier(np.r_[0.0, rng.normal(size=8)] + 1j * np.r_[0.0, rng.normal(size=8)])
    kinds = {
        "named sinusoid": {},
        "Fourier sinusoid (M=1)": dict(light_code=codes.fourier([0, 1]), sensor_code=codes.fourier([0, 1])),
        "Fourier code (M=8)": dict(light_code=band, sensor_code=band),
        "sampled square (16 chips, table)": dict(light_code=_square(), sensor_code=_square()),
        "sampled square, full waveform": dict(light_code=_square(), sensor_code=_square(), low_pass=False),
    }
    out = {name: [Camera(heterodyne=h, phase=psi, **kw) for h, psi in _common.CAMERA_GRID] for name, kw in kinds.items()}
    out["no cameras (intensity only)"] = []
    return out


def measure_render(args, log):
    scene = dopplertof.scenes.cornell_box(resolution=args.resolution)
    configs = configurations()
    times = {name: [] for name in configs}
    for name, cameras in configs.items():  # warm-up: compile every kernel once
        dopplertof.render(scene, cameras=cameras, spp=args.spp, max_depth=args.max_depth, seed=0)
    for rep in range(args.reps):
        for name, cameras in configs.items():
            start = time.perf_counter()
            dopplertof.render(scene, cameras=cameras, spp=args.spp, max_depth=args.max_depth, seed=rep + 1)
            times[name].append(time.perf_counter() - start)
        log(f"repetition {rep + 1}/{args.reps} done (load {_common.loadavg()})")
    base = statistics.median(times["named sinusoid"])
    return [{"part": "render", "configuration": name, "median_s": statistics.median(t), "relative_to_named_sinusoid": statistics.median(t) / base, "rate": ""} for name, t in times.items()]


def measure_readout(args, log):
    sensor = dopplertof.sensors.preset("mlx75027")
    raw = np.random.default_rng(0).uniform(0, 1e5, (len(sensor.frames), sensor.taps, 480, 640)).astype(np.float32)
    times = []
    for seed in range(args.reps + 1):
        start = time.perf_counter()
        sensor.read_out(raw, seed=seed)
        times.append(time.perf_counter() - start)
    median = statistics.median(times[1:])
    log(f"read-out: {median * 1e3:.1f} ms for {len(sensor.frames)} frames")
    per_frame = median / len(sensor.frames)
    return [{"part": "read_out", "configuration": "mlx75027 default schedule, 640x480", "median_s": per_frame, "relative_to_named_sinusoid": "", "rate": raw[0].size / per_frame / 1e6}]


def parse(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="film side (default 64; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel (default 64; quick 16)")
    p.add_argument("--reps", type=int, default=None, help="repetitions (default 5; quick 3)")
    p.add_argument("--max-depth", type=int, default=4, help="path depth (default 4)")
    _common.add_output_options(p, "sensors", quick_help="smoke test: 32x32, 16 spp, 3 repetitions (< 20 s)", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, dict(resolution=32, spp=16, reps=3) if args.quick else dict(resolution=64, spp=64, reps=5))
    _common.require_positive(p, args, ("resolution", "spp", "reps"))
    _common.default_output_paths(args, "sensors")
    return args


def main(argv=None):
    args = parse(argv)
    settings = f"settings: cornell-box {args.resolution}x{args.resolution}, {args.spp} spp, max_depth {args.max_depth}, 6 cameras, {args.reps} repetitions"
    run = _common.Run("sensors", args, argv, settings)
    rows = measure_render(args, run.log) + measure_readout(args, run.log)
    print(f"\n{'configuration':40s} {'median':>10s} {'relative':>9s} {'rate':>14s}")
    for row in rows:
        relative = f"{row['relative_to_named_sinusoid']:.3f}" if row["relative_to_named_sinusoid"] != "" else ""
        rate = f"{row['rate']:.1f} Mpx·tap/s" if row["rate"] != "" else ""
        unit = "s" if row["part"] == "render" else "s/frame"
        print(f"{row['configuration']:40s} {row['median_s']:8.4f} {unit:<3s} {relative:>7s} {rate:>14s}")
    return run.finish(rows, CSV_FIELDS)


if __name__ == "__main__":
    sys.exit(main())
