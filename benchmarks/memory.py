#!/usr/bin/env python
"""Peak memory of large films and the command line's start-up time::

    python benchmarks/memory.py            # 4096² and 8192² at 2 spp (~3 min on 2 cores)
    python benchmarks/memory.py --quick    # 1024² and 2048²

Each film renders the built-in Cornell box (intensity only, the default settings, 2 spp)
in a fresh subprocess; the peak is that process's maximum resident set size
(``resource.getrusage``), so it includes Python, Mitsuba, the Dr.Jit kernels and the
film's own buffers. Passes are tiles of at most ``lanes_per_pass`` lanes, so the tracing
memory is bounded and only the film's buffers grow with the film. Then
``dopplertof --help`` is timed (median of 5 runs, wall clock), the CLI being lazy.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import _common

CODE = """
import resource, time, dopplertof as dt
scene = dt.scenes.build("cornell-box", resolution={n})
start = time.perf_counter()
result = dt.render(scene, spp=2)
seconds = time.perf_counter() - start
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, seconds, result.intensity.shape)
"""


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--csv", default=None, help="CSV output (default benchmarks/results/memory.csv; quick: memory_quick.csv)")
    args = parser.parse_args(argv)
    _common.default_output_paths(args, "memory")
    sizes = (1024, 2048) if args.quick else (4096, 8192)
    print(_common.machine_line("llvm_ad_rgb", "2 spp", "Cornell box"))
    rows = []
    for n in sizes:
        run = subprocess.run([sys.executable, "-c", CODE.format(n=n)], capture_output=True, text=True)
        if run.returncode != 0:
            print(f"{n}²: failed: {run.stderr.strip().splitlines()[-1]}")
            continue
        peak, seconds, _ = run.stdout.split(maxsplit=2)
        rows.append({"film": f"{n}x{n}", "spp": 2, "peak_gib": int(peak) / 2**30, "render_s": float(seconds)})
        print(f"{n}x{n} at 2 spp: peak {int(peak) / 2**30:.2f} GiB, render {float(seconds):.1f} s", flush=True)
    times = []
    for _ in range(6):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "dopplertof.cli", "--help"], capture_output=True, check=True)
        times.append(time.perf_counter() - start)
    help_s = statistics.median(times[1:])
    print(f"dopplertof --help: {help_s:.2f} s (median of 5 after one warm-up)")
    rows.append({"film": "--help", "spp": 0, "peak_gib": float("nan"), "render_s": help_s})
    _common.write_csv(args.csv, rows, list(rows[0]), {"sizes": sizes})


if __name__ == "__main__":
    main()
