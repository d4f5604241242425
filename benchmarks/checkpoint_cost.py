#!/usr/bin/env python
"""What a periodic checkpoint costs: its size and the time of one atomic save::

    python benchmarks/checkpoint_cost.py           # 256², 1024² and 2048² films, 1 and 4 cameras (~1 min)
    python benchmarks/checkpoint_cost.py --quick   # 64² and 256²

A render with ``checkpoint=PATH`` saves its Float64 sums after the first pass that ends
``checkpoint_interval_s`` (default 60 s) after the last save (:mod:`dopplertof.render`);
each save is :func:`dopplertof.render.save_checkpoint` (temporary file, fsync, rename), timed
here on the accumulators of a real render's layout (default settings: 16 replicates, the
covariance of 4 cameras), median of 5 saves into ``--dir`` (default the system's temporary
folder). The time of a save divided by the interval is the checkpoints' share of a render.
"""

from __future__ import annotations

import math
import os
import statistics
import tempfile
import time

import _common


def main(argv=None):
    parser = _common.argument_parser(__doc__)
    parser.add_argument("--quick", action="store_true", help="64² and 256² only")
    parser.add_argument("--dir", default=tempfile.gettempdir(), help="where the checkpoints are written (default: the temporary folder)")
    parser.add_argument("--csv", default=None, help="default results/checkpoint_cost.csv (_quick.csv with --quick)")
    args = parser.parse_args(argv)
    _common.default_output_paths(args, "checkpoint_cost")

    import dopplertof as dt
    from dopplertof.passes import Accumulator, Reducer
    from dopplertof.render import save_checkpoint
    from dopplertof.settings import DEFAULT_CHECKPOINT_INTERVAL_S

    variant = dt.set_variant(_common.DEFAULT_VARIANT)
    print(_common.machine_line(variant, f"load {_common.loadavg()}", f"checkpoints in {args.dir}"))
    sizes = (64, 256) if args.quick else (256, 1024, 2048)
    rows = []
    print("| film | cameras | checkpoint MB | save s (median of 5) | share of a render at the default interval |")
    print("|---|---:|---:|---:|---:|")
    for n in sizes:
        for n_cameras in (1, 4):
            cameras = tuple(dt.Camera(heterodyne=h, phase=psi) for h in (0.0, 1.0) for psi in (0.0, math.pi / 2))[:n_cameras]
            acc = Accumulator(n * n, *Reducer.layout(dt.RenderSettings(cameras=cameras)))
            path = os.path.join(args.dir, f"checkpoint_cost_{os.getpid()}.npz")
            seconds = []
            for _ in range(5):
                start = time.perf_counter()
                save_checkpoint(path, [acc], "benchmark")
                seconds.append(time.perf_counter() - start)
            size_mb = os.path.getsize(path) / 1e6
            os.remove(path)
            median = statistics.median(seconds)
            share = median / (DEFAULT_CHECKPOINT_INTERVAL_S + median)
            rows.append({"film": f"{n}x{n}", "cameras": n_cameras, "checkpoint_mb": size_mb, "save_s": median, "save_s_min": min(seconds), "share_at_default_interval": share})
            print(f"| {n}x{n} | {n_cameras} | {size_mb:.1f} | {median:.3f} | {100 * share:.2f} % |", flush=True)
    _common.write_csv(args.csv, rows, list(rows[0]), {"sizes": sizes, "interval_s": DEFAULT_CHECKPOINT_INTERVAL_S})


if __name__ == "__main__":
    main()
