#!/usr/bin/env python
"""Render once, read out many sensors: the response record against direct renders.

On the Cornell box (point light, two moving boxes) this measures

* the plain render of the dtof-prototype's default schedule (3 frames, 2 taps) and the
  same render with ``record=`` (10–300 MHz at ``--step`` MHz, beats 0 and 1), ``--repeats``
  of each interleaved: the record's render overhead in wall-clock and in CPU time (medians)
  and its size (bytes, and per pixel);
* ``dopplertof.design.evaluate`` of ``--sensors`` random sensors (3 sinusoidal frames in the
  band, random phases, homodyne and heterodyne) from the record, against rendering 4 of
  them directly: the time per sensor and the speed-up;
* the agreement of the 4 direct renders with their read-outs (largest |difference| of the
  raw electrons relative to the largest raw value: same seed, so rounding only).

::

    python benchmarks/design.py            # 64x64, 16 spp, 1000 sensors (~2 min, 2 cores)
    python benchmarks/design.py --quick    # 32x32, 8 spp, 100 sensors (< 30 s)
    python benchmarks/design.py --resolution 256 --spp 64   # the issue's 256² setting

The machine is shared: compare ratios, not seconds.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

import dopplertof  # noqa: I001 - must precede the first `import drjit` (sets the libLLVM path)

import _common

CSV_FIELDS = ["quantity", "value", "unit"]


def random_sensor(rng, frequencies_hz):
    from dopplertof.sensors import RawFrame, preset

    f = float(rng.choice(frequencies_hz[(frequencies_hz >= 10e6) & (frequencies_hz <= 100e6)]))  # the prototype's range
    frames = [RawFrame(modulation_frequency=f, heterodyne=h, phase=float(rng.uniform(0, 2 * math.pi)), exposure=1.5e-3) for h in (0.0, 1.0, 1.0)]
    return preset("dtof-prototype", frames, radiance_unit=1e-3)


def measure(args, log):
    from dopplertof.design import RecordSpec, evaluate
    from dopplertof.sensors import preset

    scene = dopplertof.scenes.cornell_box(resolution=args.resolution)
    sensor = preset("dtof-prototype", radiance_unit=1e-3)
    spec = RecordSpec(band_hz=(10e6, 300e6), step_hz=args.step * 1e6, beats=(0.0, 1.0))
    common = dict(spp=args.spp, max_depth=args.max_depth, seed=7)
    dopplertof.render(scene, sensor=sensor, **dict(common, spp=2))  # compile the kernels first
    dopplertof.render(scene, sensor=sensor, record=spec, **dict(common, spp=2))
    plain, recorded = [], []  # (wall s, CPU s), interleaved: the machine's load hits both alike
    for _ in range(args.repeats):
        for times, extra in ((plain, {}), (recorded, {"record": spec})):
            w0, c0 = time.perf_counter(), time.process_time()
            result = dopplertof.render(scene, sensor=sensor, **common, **extra)
            times.append((time.perf_counter() - w0, time.process_time() - c0))
    record = result.record
    plain_s, plain_cpu = (float(np.median(x)) for x in zip(*plain))
    recorded_s, recorded_cpu = (float(np.median(x)) for x in zip(*recorded))
    log(f"plain render {plain_s:.2f} s (CPU {plain_cpu:.2f} s); with record {recorded_s:.2f} s (CPU {recorded_cpu:.2f} s; {record.info['kernels']} kernel(s) per window)")
    rng = np.random.default_rng(1)
    sensors = [random_sensor(rng, spec.frequencies_hz) for _ in range(args.sensors)]
    t0, c0 = time.perf_counter(), time.process_time()
    for s in sensors:
        evaluate(record, s)
    evaluate_s, evaluate_cpu = (time.perf_counter() - t0) / len(sensors), (time.process_time() - c0) / len(sensors)
    log(f"evaluate {evaluate_s * 1e3:.2f} ms per sensor (CPU {evaluate_cpu * 1e3:.2f} ms)")
    direct_times, errors = [], []
    for s in sensors[:4]:
        t0, c0 = time.perf_counter(), time.process_time()
        direct = dopplertof.render(scene, sensor=s, **common)
        direct_times.append((time.perf_counter() - t0, time.process_time() - c0))
        read = evaluate(record, s)
        errors.append(float(np.abs(read.raw - direct.raw).max() / np.abs(direct.raw).max()))
    direct_s, direct_cpu = (float(np.median(x)) for x in zip(*direct_times))
    pixels = args.resolution**2
    return [
        {"quantity": "plain render", "value": plain_s, "unit": "s"},
        {"quantity": "render with record", "value": recorded_s, "unit": "s"},
        {"quantity": "record overhead (render with record / plain)", "value": recorded_s / plain_s, "unit": "x"},
        {"quantity": "plain render, CPU time", "value": plain_cpu, "unit": "s"},
        {"quantity": "render with record, CPU time", "value": recorded_cpu, "unit": "s"},
        {"quantity": "record overhead in CPU time", "value": recorded_cpu / plain_cpu, "unit": "x"},
        {"quantity": "record size", "value": record.nbytes / 2**20, "unit": "MiB"},
        {"quantity": "record size per pixel", "value": record.nbytes / pixels, "unit": "B"},
        {"quantity": "256x256 record of this spec", "value": 256 * 256 * spec.bytes_per_pixel() / 2**20, "unit": "MiB"},
        {"quantity": "direct render per sensor (median of 4)", "value": direct_s, "unit": "s"},
        {"quantity": f"evaluate per sensor (mean of {len(sensors)})", "value": evaluate_s, "unit": "s"},
        {"quantity": "speed-up per sensor (direct / evaluate)", "value": direct_s / evaluate_s, "unit": "x"},
        {"quantity": "direct render per sensor, CPU time", "value": direct_cpu, "unit": "s"},
        {"quantity": "evaluate per sensor, CPU time", "value": evaluate_cpu, "unit": "s"},
        {"quantity": "speed-up per sensor in CPU time", "value": direct_cpu / evaluate_cpu, "unit": "x"},
        {"quantity": "largest raw difference, read-out vs direct (relative)", "value": max(errors), "unit": ""},
    ]


def parse(argv):
    p = _common.argument_parser(__doc__)
    p.add_argument("--resolution", type=int, default=None, help="film side (default 64; quick 32)")
    p.add_argument("--spp", type=int, default=None, help="paths per pixel (default 16; quick 8)")
    p.add_argument("--sensors", type=int, default=None, help="sensors read out of the record (default 1000; quick 100)")
    p.add_argument("--step", type=float, default=10.0, help="the record's frequency step, MHz (default 10)")
    p.add_argument("--max-depth", type=int, default=4, help="path depth (default 4)")
    p.add_argument("--repeats", type=int, default=5, help="interleaved plain and recording renders, medians reported (default 5)")
    _common.add_output_options(p, "design", quick_help="smoke test: 32x32, 8 spp, 100 sensors (< 30 s)", plot=False)
    args = p.parse_args(argv)
    _common.fill_defaults(args, dict(resolution=32, spp=8, sensors=100) if args.quick else dict(resolution=64, spp=16, sensors=1000))
    _common.require_positive(p, args, ("resolution", "spp", "sensors", "repeats"))
    _common.default_output_paths(args, "design")
    return args


def main(argv=None):
    args = parse(argv)
    settings = f"settings: cornell-box {args.resolution}x{args.resolution}, {args.spp} spp, max_depth {args.max_depth}, record 10-300 MHz at {args.step:g} MHz, beats 0 and 1"
    run = _common.Run("design", args, argv, settings)
    rows = measure(args, run.log)
    print(f"\n{'quantity':56s} {'value':>12s}")
    for row in rows:
        print(f"{row['quantity']:56s} {row['value']:12.4g} {row['unit']}")
    return run.finish(rows, CSV_FIELDS)


if __name__ == "__main__":
    sys.exit(main())
