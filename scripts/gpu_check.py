#!/usr/bin/env python
"""The work of ``scripts/gpu-check.sh`` (see there): render every built-in scene on each
variant in a process of its own (stderr captured: any Dr.Jit warning fails the check),
compare the two halves, print the throughput rows."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GPU, CPU = "cuda_ad_rgb", "llvm_ad_rgb"
CORRELATIONS = ("replay", "reconnection")
# Per-pixel |z| bound of a measurement or intensity difference: each z is about Student's t
# with replicates − 1 degrees of freedom; 8 keeps a whole run's false alarms rare.
Z_BOUND = 8.0
MIN_SPP = 16  # 8 antithetic groups: 8 replicates, so per-pixel standard errors mean something
# Independent replicates, not the render's default strata: at a few spp two groups per stratum
# give the errors only G/2 degrees of freedom, and a moving edge caught by both groups of one
# stratum (or by neither) makes a pixel's error far too small; the check needs calibrated z.
REPLICATES = MIN_SPP // 2
MIN_BODY_PIXELS = 3  # a body on at least this many CPU pixels must show on the GPU


def render_half(variant: str, resolution: int, spp: int, seed: int, out: str) -> None:
    """Render every built-in scene × correlation on ``variant``; arrays to ``out`` (npz),
    written again after each scene, so a half stopped part way keeps what it finished (each
    write is a new file renamed over ``out``: a half stopped while writing leaves the last
    whole one)."""
    os.environ["DOPPLERTOF_VARIANT"] = variant
    import numpy as np

    import dopplertof as dt

    dt.set_variant(variant)
    import drjit as dr

    dr.set_log_level(dr.LogLevel.Warn)  # Dr.Jit's warnings (a disabled OptiX trace) reach stderr
    cameras = [dt.Camera(heterodyne=0.0), dt.Camera(heterodyne=1.0, phase=0.5)]
    arrays = {}
    for name in dt.scenes.SCENES:
        scene = dt.scenes.build(name, resolution=resolution)
        start = 0.5 * dt.scenes.clip_duration(name)
        for correlation in CORRELATIONS:
            began = time.perf_counter()
            r = dt.render(scene, cameras, spp=spp, seed=seed, max_depth=3, correlation=correlation, exposure_start=start,
                          stratify_intervals=False, replicates=REPLICATES)  # fmt: skip
            key = f"{name}/{correlation}"
            for field in ("intensity", "stderr", "measurements", "measurement_stderr", "instance_id"):
                arrays[f"{key}/{field}"] = np.asarray(getattr(r, field))
            print(f"{variant}: {key} done in {time.perf_counter() - began:.1f} s ({len(scene.bodies)} moving bodies, traversal {scene.traversal_in_use()})", flush=True)
        partial = out + ".partial.npz"  # ends in .npz: np.savez writes it under this name
        np.savez(partial, **arrays)
        os.replace(partial, out)


def compare(a: dict, b: dict, label_a: str, label_b: str) -> list[str]:
    """Failures (empty: the halves agree)."""
    import numpy as np

    failures = []
    keys_a, keys_b = ({k.rsplit("/", 1)[0] for k in half} for half in (a, b))
    failures += [f"{key}: rendered on {label_a} only (the other half stopped before it)" for key in sorted(keys_a - keys_b)]
    failures += [f"{key}: rendered on {label_b} only (the other half stopped before it)" for key in sorted(keys_b - keys_a)]
    for key in sorted(keys_a & keys_b):
        for value, error in (("intensity", "stderr"), ("measurements", "measurement_stderr")):
            x, y = a[f"{key}/{value}"].astype(np.float64), b[f"{key}/{value}"].astype(np.float64)
            se = np.sqrt(a[f"{key}/{error}"].astype(np.float64) ** 2 + b[f"{key}/{error}"].astype(np.float64) ** 2)
            diff = np.abs(x - y)
            scale = max(float(np.abs(x).max()), 1e-30)
            z = np.where(se > 0, diff / np.where(se > 0, se, 1.0), np.where(diff <= 1e-6 * scale, 0.0, np.inf))
            worst = float(np.nanmax(z)) if z.size else 0.0
            if not worst <= Z_BOUND:
                failures.append(f"{key}: {value} differ by up to {worst:.1f} standard errors ({label_a} vs {label_b})")
        ids_a, ids_b = a[f"{key}/instance_id"], b[f"{key}/instance_id"]
        seen_b = set(np.unique(ids_b).tolist())
        for body in np.unique(ids_a):
            if body >= 0 and (ids_a == body).sum() >= MIN_BODY_PIXELS and body not in seen_b:
                failures.append(f"{key}: body {int(body)} is on {(ids_a == body).sum()} pixels on {label_a} and on none on {label_b}")
    return failures


def run_half(variant: str, args, seed: int, out: str) -> list[str]:
    """Render a half in a process of its own, for at most ``args.half_timeout`` s;
    failures: its exit status, its warnings."""
    cmd = [sys.executable, __file__, "--half", variant, "--resolution", str(args.resolution), "--spp", str(args.spp), "--seed", str(seed), "--out", out]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=args.half_timeout)
    except subprocess.TimeoutExpired as exc:
        sys.stdout.write(_text(exc.stdout))
        warnings = [line for line in _text(exc.stderr).splitlines() if line.strip()]
        return [f"{variant}: stopped after {args.half_timeout:g} s (--half-timeout); the scenes it finished are compared"] + [f"{variant}: stderr: {line}" for line in warnings]
    sys.stdout.write(proc.stdout)
    if proc.returncode != 0:
        return [f"{variant}: the renders failed (exit {proc.returncode}): {proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ''}"]
    warnings = [line for line in proc.stderr.splitlines() if line.strip()]
    return [f"{variant}: stderr: {line}" for line in warnings]


def _text(output) -> str:
    """A TimeoutExpired's captured output (bytes, str or None) as text."""
    return output.decode(errors="replace") if isinstance(output, bytes) else output or ""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, as the dopplertof command line
        print(f"error: {message}", file=sys.stderr)
        sys.exit(2)


def main(argv=None) -> int:
    p = _Parser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dry-run", action="store_true", help="no GPU: the LLVM half against itself at another seed")
    p.add_argument("--resolution", type=int, default=32, help="square film side, pixels (default 32)")
    p.add_argument("--spp", type=int, default=32, help="paths per pixel (even; default 32)")
    p.add_argument("--no-throughput", action="store_true", help="skip the throughput rows")
    p.add_argument("--half-timeout", type=float, default=240.0, help="seconds each variant's renders may take; what finished is compared (default 240)")
    p.add_argument("--half", choices=(GPU, CPU), help=argparse.SUPPRESS)
    p.add_argument("--seed", type=int, default=1, help=argparse.SUPPRESS)
    p.add_argument("--out", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.resolution < 1 or args.spp < MIN_SPP or args.spp % 2:
        p.error(f"--resolution must be >= 1 and --spp even and >= {MIN_SPP}, got {args.resolution} and {args.spp}")
    if not args.half_timeout > 0:
        p.error(f"--half-timeout must be > 0 s, got {args.half_timeout:g}")
    if args.half:
        render_half(args.half, args.resolution, args.spp, args.seed, args.out)
        return 0

    import numpy as np

    first = CPU if args.dry_run else GPU
    with tempfile.TemporaryDirectory() as tmp:
        out_a, out_b = os.path.join(tmp, "a.npz"), os.path.join(tmp, "b.npz")
        failures = run_half(CPU, args, 1, out_a) + run_half(first, args, 1 if first == GPU else 2, out_b)
        if os.path.exists(out_a) and os.path.exists(out_b):
            with np.load(out_a) as a, np.load(out_b) as b:
                failures += compare(dict(a), dict(b), CPU, first + (" (seed 2)" if args.dry_run else ""))
        else:
            failures.append("a half finished no scene: nothing compared")
    if not args.no_throughput:
        for variant in (CPU,) if args.dry_run else (CPU, GPU):
            print(f"\nthroughput on {variant}:", flush=True)
            cmd = [sys.executable, str(ROOT / "benchmarks" / "throughput.py"), "--quick", "--quiet", "--variant", variant]
            if subprocess.run(cmd, cwd=ROOT).returncode != 0:
                failures.append(f"{variant}: benchmarks/throughput.py failed")
    if failures:
        print("\nGPU check FAILED:\n  " + "\n  ".join(failures))
        return 1
    print(f"\nGPU check passed ({'dry run, LLVM only' if args.dry_run else f'{GPU} = {CPU} within noise'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
