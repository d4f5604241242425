#!/usr/bin/env python
"""What codes and sensors cost, and how well each sensor preset measures velocity.

Part 1 (``render``) renders the Cornell box (point light, two moving boxes) with six
cameras h ∈ {0, ½, 1} × ψ ∈ {0°, 90°} of one kind at a time, interleaved over repetitions
(median time): the named sinusoid (the closed form the kernel had before codes), the same
sinusoid as Fourier coefficients (harmonic form, M = 1), a band-limited code of 8
harmonics, a sampled square of 16 chips (the table form: two gathers per contribution), and
the sampled square in full-waveform mode; plus the render without cameras. Part 2
(``read_out``) reads out the MLX75027 preset's default schedule (4 frames × 2 taps) at
640×480 many times.

Part 3 (``frames``): a sensor of 8 raw frames in one exposure window (the MLX75027's 8
phases, 45° apart, 100 MHz) against one camera, the same scene, spp and seeds, interleaved
(the median of the per-repetition ratios; the sensor traces its 8 frames and the window's
mean-luminance camera from the same paths). Target: ≤ 1.2× one camera.

Part 4 (``velocity``): velocity RMSE of ``cornell-box`` (its boxes at ±10 m/s over the whole
schedule) and ``street`` for each preset at its legal best settings, rendered once and read
out with ``--draws`` noise draws (seeds 0 … draws − 1). Settings:

==============  ============================================================================
preset          schedule (all legal for the chip) and estimator
==============  ============================================================================
mlx75027        100 MHz square, 2 captures × 4 phases (0°, 90°, 180°, 270°) frame after
                frame, 999 µs each (< 1 ms; 8 frames): two-capture velocity
opt8241         100 MHz square, the same 2 × 4 phases, 1 ms each: two-capture velocity
imx556          100 MHz square, the same, 1 ms each: two-capture velocity
kinect-v2       130 MHz sinusoid (its highest), 2 captures × 3 phases (0°, 120°, 240°),
                1 ms each (6 of its 9 frames): two-capture velocity
dtof-prototype  100 MHz sinusoid, offsets h = ±½ (Hu et al.: +½ at 270°, 0°; −½ at 90°,
                180°) in one 1.5 ms window: two-offset differential heterodyne
==============  ============================================================================

Chips without a heterodyne offset see velocity only as the depth phase's change between two
captures (:func:`dopplertof.sensors.estimators.two_capture_velocity`, through the square
wave's own triangle correlation and the motion between sequential frames); the prototype
measures it within one exposure (:func:`~dopplertof.sensors.estimators.two_offset_velocity`).
Each sensor's light level is set so that both taps of its first frame collect one full
well at the 99th-percentile pixel (:meth:`dopplertof.Sensor.with_signal`): the brightest
legal light. The two captures of a chip are rendered as two renders with the same seed
(window by window), so their Monte Carlo errors correlate and cancel in the phase change,
as correlated paths do in D-ToF (the windows of one render are independent). Reported per
scene and preset: the velocity RMSE over pixels that hit something and give an estimate
whose own standard error (from the read-out's noise model) is at most ``--max-stderr``
(10 m/s: the confidence mask a pipeline applies; without it a few pixels where the
two-offset ratio nears 1 reach 10¹⁷ m/s) as the mean over draws and its spread, the
fraction of such pixels (weak, uncertain or saturated ones drop out), the median |error|
over every pixel with an estimate (no mask), and the
RMSE of the noiseless render alone over every pixel it gives (Monte Carlo and model error,
silhouettes that move between captures included: the floor below the sensor noise)::

    python benchmarks/sensors.py            # 64x64, 64 spp, 5 repetitions; velocity 32x32, 64 spp, 32 draws (a few min, 2 cores)
    python benchmarks/sensors.py --quick    # 32x32, 16 spp, 3 repetitions; velocity 16x16, 8 spp, 4 draws (< 1 min)

Printed and written to CSV (and the velocity RMSEs plotted): per configuration the median
render time (s) and its ratio to the named sinusoid's (part 1) or to one camera (part 3);
the read-out's time per sensor frame (ms) and its rate (Mpixel·taps/s); the velocity
errors (m/s) and the time of each sensor's render(s) (``render_s``). The machine is shared: compare ratios, not seconds.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import sys
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

PARTS = ("render", "read_out", "frames", "velocity")
CSV_FIELDS = ["part", "configuration", "median_s", "relative_to_named_sinusoid", "rate", "relative_to_one_camera",
              "scene", "render_s", "sensor", "rmse_m_s", "rmse_spread_m_s", "median_abs_error_m_s", "valid_fraction", "render_only_rmse_m_s"]
VELOCITY_SCENES = ("cornell-box", "street")
CORNELL_SPEED_M_S = 10.0  # the boxes' speed in dopplertof.scenes.cornell_box (15 mm over 1.5 ms)


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
    return [{"part": "render", "configuration": name, "median_s": statistics.median(t), "relative_to_named_sinusoid": statistics.median(t) / base} for name, t in times.items()]


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
    return [{"part": "read_out", "configuration": "mlx75027 default schedule, 640x480", "median_s": per_frame, "rate": raw[0].size / per_frame / 1e6}]


def measure_frames(args, log):
    """Part 3: 8 raw frames in one window against one camera (module docstring)."""
    scene = dopplertof.scenes.cornell_box(resolution=args.resolution)
    frames = [dopplertof.RawFrame(modulation_frequency=100e6, exposure=999e-6, phase=k * math.pi / 4, waveform="rectangular") for k in range(8)]
    configs = {"one camera": dict(cameras=[dopplertof.Camera()]), "sensor, 8 raw frames": dict(sensor=dopplertof.sensors.preset("mlx75027", frames=frames))}
    times = {name: [] for name in configs}
    for kw in configs.values():
        dopplertof.render(scene, spp=args.spp, max_depth=args.max_depth, seed=0, **kw)
    for rep in range(args.reps):
        for name, kw in configs.items():
            start = time.perf_counter()
            dopplertof.render(scene, spp=args.spp, max_depth=args.max_depth, seed=rep + 1, **kw)
            times[name].append(time.perf_counter() - start)
    # the ratio of each repetition's pair (run back to back) is steadier than a ratio of medians on a shared machine
    ratios = [s / c for s, c in zip(times["sensor, 8 raw frames"], times["one camera"])]
    log(f"8 frames / one camera: median {statistics.median(ratios):.3f} over {len(ratios)} pairs (min {min(ratios):.3f}, max {max(ratios):.3f})")
    return [{"part": "frames", "configuration": name, "median_s": statistics.median(t), "relative_to_one_camera": statistics.median(ratios) if name != "one camera" else 1.0}
            for name, t in times.items()]  # fmt: skip


def _captures(frequency_hz, exposure_s, phases_deg, waveform):
    """Two captures of ``phases_deg``, frame after frame."""
    n = len(phases_deg)
    return [dopplertof.RawFrame(modulation_frequency=frequency_hz, exposure=exposure_s, phase=math.radians(p), waveform=waveform,
                                exposure_start=(c * n + j) * exposure_s) for c in range(2) for j, p in enumerate(phases_deg)]  # fmt: skip


def velocity_schedules():
    """preset -> (frames, estimator name): the legal best settings of the module docstring."""
    hu = [dopplertof.RawFrame(modulation_frequency=100e6, exposure=1.5e-3, heterodyne=h, phase=math.radians(p), waveform="sinusoidal")
          for h, p in ((0.5, 270.0), (0.5, 0.0), (-0.5, 90.0), (-0.5, 180.0))]  # fmt: skip
    quad = (0.0, 90.0, 180.0, 270.0)
    return {
        "mlx75027": (_captures(100e6, 999e-6, quad, "rectangular"), "two_capture"),
        "opt8241": (_captures(100e6, 1e-3, quad, "rectangular"), "two_capture"),
        "imx556": (_captures(100e6, 1e-3, quad, "rectangular"), "two_capture"),
        "kinect-v2": (_captures(130e6, 1e-3, (0.0, 120.0, 240.0), "sinusoidal"), "two_capture"),
        "dtof-prototype": (hu, "two_offset"),
    }


def _velocity_scene(name, resolution, span_s):
    if name == "street":
        return dopplertof.scenes.street(resolution=resolution)
    # keyframed boxes hold still after their last key: keep them moving over the whole schedule
    return dopplertof.scenes.cornell_box(resolution=resolution, exposure=span_s, displacement=CORNELL_SPEED_M_S * span_s)


def _render_schedule(scene, sensor, estimator, args):
    """The measurements of ``sensor.cameras()``: one render, or (two captures) one render per
    capture with the same seed, merged in the order of ``sensor.cameras()``; and the
    ground-truth velocity of the first window."""
    render = dict(spp=args.velocity_spp, max_depth=args.max_depth, seed=1)
    if estimator == "two_offset":
        result = dopplertof.render(scene, sensor=sensor, **render)
        return result.measurements, result.velocity
    half = len(sensor.frames) // 2
    if len(sensor.cameras()) != 2 * len(sensor.frames):
        raise RuntimeError("the captures' frames must each have a window of their own (distinct exposure_start)")
    parts = [dopplertof.render(scene, sensor=dataclasses.replace(sensor, frames=frames), **render) for frames in (sensor.frames[:half], sensor.frames[half:])]
    # every frame is its own window here: cameras() = the frames, then one mean-luminance camera per frame
    m = np.concatenate([parts[0].measurements[:half], parts[1].measurements[:half], parts[0].measurements[half:], parts[1].measurements[half:]])
    return m, parts[0].velocity


def _estimate(estimator, measurements, cameras, stderr=None):
    """(velocity, its standard error or None) of the estimator named ``estimator``."""
    from dopplertof.sensors import estimators

    function = estimators.two_capture_velocity if estimator == "two_capture" else estimators.two_offset_velocity
    result = function(measurements, cameras, measurement_stderr=stderr)
    return result.velocity, result.velocity_stderr


def measure_velocity(args, log):
    """Part 4: velocity errors per scene and preset (module docstring)."""
    from dopplertof.sensors.estimators import measurements_from_readout

    schedules = velocity_schedules()
    span_s = max(max((f.exposure_start or 0.0) + f.exposure for f in frames) for frames, _ in schedules.values())
    rows = []
    for scene_name in args.scenes:
        scene = _velocity_scene(scene_name, args.velocity_resolution, span_s)
        for name, (frames, estimator) in schedules.items():
            sensor = dopplertof.sensors.preset(name, frames=frames)
            start = time.perf_counter()
            measurements, truth = _render_schedule(scene, sensor, estimator, args)
            spent = time.perf_counter() - start
            sensor = sensor.with_signal(measurements, sensor.noise.full_well_e)
            raw = sensor.raw(measurements)
            hit = np.isfinite(truth)
            render_only, _ = _estimate(estimator, measurements[: len(frames)], sensor.frames)
            per_draw, absolute, valid = [], [], []
            for seed in range(args.draws):
                read = measurements_from_readout(sensor, sensor.read_out(raw, seed=seed))
                velocity, stderr = _estimate(estimator, read.measurements, read.cameras, read.stderr)
                error = (velocity - truth)[hit]
                confident = np.isfinite(error) & (stderr[hit] <= args.max_stderr)
                per_draw.append(float(np.sqrt(np.mean(error[confident] ** 2))))
                absolute.append(np.abs(error[np.isfinite(error)]))
                valid.append(confident.mean())
            render_error = (render_only - truth)[hit]
            row = {
                "part": "velocity", "configuration": f"{scene_name} / {name}", "render_s": spent, "scene": scene_name, "sensor": name,
                "rmse_m_s": float(np.mean(per_draw)), "rmse_spread_m_s": float(np.std(per_draw)), "median_abs_error_m_s": float(np.median(np.concatenate(absolute))),
                "valid_fraction": float(np.mean(valid)), "render_only_rmse_m_s": float(np.sqrt(np.nanmean(render_error**2))),
            }  # fmt: skip
            rows.append(row)
            log(f"{scene_name:12s} {name:15s} RMSE {row['rmse_m_s']:8.3f} m/s (render alone {row['render_only_rmse_m_s']:.3f}), valid {row['valid_fraction']:.2f}, render {spent:.1f} s")
    return rows


def plot_velocity(path, rows):
    from matplotlib.figure import Figure

    velocity = [r for r in rows if r["part"] == "velocity"]
    sensors = list(dict.fromkeys(r["sensor"] for r in velocity))
    scenes = list(dict.fromkeys(r["scene"] for r in velocity))
    figure = Figure(figsize=(8, 3.6), layout="constrained")
    axes = figure.subplots()
    width = 0.8 / max(len(scenes), 1)
    for k, scene in enumerate(scenes):
        by_sensor = {r["sensor"]: r for r in velocity if r["scene"] == scene}
        x = np.arange(len(sensors)) + (k - (len(scenes) - 1) / 2) * width
        axes.bar(x, [by_sensor[s]["rmse_m_s"] for s in sensors], width, label=f"{scene}: with sensor noise")
        axes.plot(x, [by_sensor[s]["render_only_rmse_m_s"] for s in sensors], "k_", markersize=14, label=f"{scene}: render alone" if k == 0 else None)
    axes.set_xticks(np.arange(len(sensors)), sensors)
    axes.set_yscale("log")
    axes.set_ylabel("velocity RMSE (m/s)")
    axes.set_title("velocity RMSE per sensor preset at its legal best settings", fontsize=9)
    _common.save_figure(figure, axes, path)


def parse(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="film side (default 64; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel (default 64; quick 16)")
    p.add_argument("--reps", type=int, default=None, help="repetitions (default 5; quick 3)")
    p.add_argument("--max-depth", type=int, default=4, help="path depth (default 4)")
    p.add_argument("--velocity-resolution", type=int, default=None, help="film side of part 4 (default 32; quick 16)")
    p.add_argument("--velocity-spp", type=int, default=None, help="paths per pixel of part 4 (default 64; quick 8)")
    p.add_argument("--draws", type=int, default=None, help="noise draws of part 4 (default 32; quick 4)")
    p.add_argument("--max-stderr", type=float, default=10.0, help="part 4 keeps pixels whose estimate's own standard error is at most this, m/s (default 10)")
    p.add_argument("--scenes", nargs="+", choices=VELOCITY_SCENES, default=list(VELOCITY_SCENES), help="scenes of part 4 (default both)")
    p.add_argument("--parts", nargs="+", choices=PARTS, default=list(PARTS), help="parts to run (default all)")
    _common.add_output_options(p, "sensors", quick_help="smoke test: 32x32, 16 spp, 3 repetitions; velocity 16x16, 8 spp, 4 draws (< 1 min)")
    args = p.parse_args(argv)
    quick = dict(resolution=32, spp=16, reps=3, velocity_resolution=16, velocity_spp=8, draws=4)
    _common.fill_defaults(args, quick if args.quick else dict(resolution=64, spp=64, reps=5, velocity_resolution=32, velocity_spp=64, draws=32))
    _common.require_positive(p, args, ("resolution", "spp", "reps", "velocity_resolution", "velocity_spp", "draws"))
    _common.default_output_paths(args, "sensors")
    return args


def main(argv=None):
    args = parse(argv)
    settings = (f"settings: cornell-box {args.resolution}x{args.resolution}, {args.spp} spp, max_depth {args.max_depth}, {args.reps} repetitions; "
                f"velocity {' and '.join(args.scenes)} {args.velocity_resolution}x{args.velocity_resolution}, {args.velocity_spp} spp, {args.draws} draws; parts {' '.join(args.parts)}")  # fmt: skip
    run = _common.Run("sensors", args, argv, settings)
    measure = {"render": measure_render, "read_out": measure_readout, "frames": measure_frames, "velocity": measure_velocity}
    rows = [row for part in args.parts for row in measure[part](args, run.log)]
    print(f"\n{'configuration':40s} {'median':>10s} {'relative':>9s} {'rate':>14s}")
    for row in rows:
        if row["part"] == "velocity":
            continue
        ratio = row.get("relative_to_named_sinusoid", "") if row["part"] == "render" else row.get("relative_to_one_camera", "")
        relative = f"{ratio:.3f}" if ratio != "" else ""
        rate = f"{row['rate']:.1f} Mpx·tap/s" if row.get("rate", "") != "" else ""
        unit = "s/frame" if row["part"] == "read_out" else "s"
        print(f"{row['configuration']:40s} {row['median_s']:8.4f} {unit:<3s} {relative:>7s} {rate:>14s}")
    velocity = [r for r in rows if r["part"] == "velocity"]
    if velocity:
        print(f"\n{'scene':12s} {'sensor':15s} {'RMSE m/s':>9s} {'± draws':>8s} {'median |e|':>10s} {'valid':>6s} {'render alone':>12s}")
        for r in velocity:
            print(f"{r['scene']:12s} {r['sensor']:15s} {r['rmse_m_s']:9.3f} {r['rmse_spread_m_s']:8.3f} {r['median_abs_error_m_s']:10.3f} {r['valid_fraction']:6.2f} {r['render_only_rmse_m_s']:12.3f}")
    return run.finish(rows, CSV_FIELDS, plot=(lambda path: plot_velocity(path, rows)) if velocity else None)


if __name__ == "__main__":
    sys.exit(main())
