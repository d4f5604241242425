"""scripts/gpu-check.sh: its dry run (the LLVM half, no GPU) as CI runs it, and its refusals."""

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "gpu-check.sh"


def _run(*args, env_dry=False):
    import os

    env = dict(os.environ, DOPPLERTOF_GPU_CHECK_DRY="1" if env_dry else "0")
    return subprocess.run(["bash", str(SCRIPT), "--no-setup", *args], capture_output=True, text=True, env=env, timeout=600)


@pytest.mark.slow
def test_the_dry_run_renders_every_scene_on_llvm_and_passes():
    proc = _run("--resolution", "8", "--spp", "16", "--no-throughput", env_dry=True)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "GPU check passed (dry run, LLVM only)" in proc.stdout
    assert "street/reconnection done" in proc.stdout


def test_the_comparison_fails_where_a_body_vanishes_or_values_differ():
    """The comparison itself (scripts/gpu_check.py): a body present on one half and absent
    on the other, and a difference far beyond the standard errors, are both reported."""
    import numpy as np

    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import gpu_check
    finally:
        sys.path.pop(0)
    ids = np.full((4, 4), -1, np.int32)
    ids[:2, :2] = 0
    ones = np.ones((4, 4, 3), np.float32)
    half = {"s/replay/intensity": ones, "s/replay/stderr": 0.01 * ones, "s/replay/measurements": ones[None, ..., 0],
            "s/replay/measurement_stderr": 0.01 * ones[None, ..., 0], "s/replay/instance_id": ids}  # fmt: skip
    assert gpu_check.compare(half, dict(half), "a", "b") == []
    vanished = dict(half, **{"s/replay/instance_id": np.full((4, 4), -1, np.int32)})
    assert any("body 0 is on 4 pixels on a and on none on b" in f for f in gpu_check.compare(half, vanished, "a", "b"))
    brighter = dict(half, **{"s/replay/intensity": 2 * ones})
    assert any("intensity differ" in f for f in gpu_check.compare(half, brighter, "a", "b"))
    stopped = dict(half)  # a half stopped before the second scene
    longer = dict(half, **{k.replace("s/", "t/"): v for k, v in half.items()})
    assert gpu_check.compare(longer, stopped, "a", "b") == ["t/replay: rendered on a only (the other half stopped before it)"]


def test_a_half_stopped_by_its_timeout_keeps_and_compares_what_it_finished():
    """One second is time to start and not to finish: the check fails, naming the timeout,
    and compares the scenes each half finished (none or some)."""
    proc = _run("--resolution", "8", "--spp", "16", "--no-throughput", "--half-timeout", "1", env_dry=True)
    assert proc.returncode == 1
    assert "llvm_ad_rgb: stopped after 1 s (--half-timeout)" in proc.stdout
    assert "GPU check FAILED" in proc.stdout and "Traceback" not in proc.stdout + proc.stderr


@pytest.mark.parametrize("args, message", [(["--spp", "3"], "--spp even and >= 16"), (["--resolution", "0"], "--resolution must be >= 1"),
                                           (["--half-timeout", "0"], "--half-timeout must be > 0 s")])  # fmt: skip
def test_bad_arguments_are_one_error_line(args, message):
    proc = _run(*args, "--dry-run", "--no-throughput")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], proc.stderr
