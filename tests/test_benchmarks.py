"""The benchmarks that replace functions of the tracer (to switch parts of it off, or, in
``slices_built.py``, to time them) still run: they call internals by their signatures,
which the suite does not otherwise use, so a change of a signature broke
``static_overhead.py`` (its ``no-truth`` ablation) unseen."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.parametrize("script", ["static_overhead.py", "body_cost.py", "slices_built.py"])
def test_a_benchmark_that_patches_the_tracer_runs_its_quick_form(script, tmp_path):
    csv = tmp_path / "out.csv"
    run = subprocess.run([sys.executable, str(BENCHMARKS / script), "--quick", "--quiet", "--csv", str(csv)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    rows = csv.read_text().splitlines()
    assert len([r for r in rows if not r.startswith("#")]) >= 2, rows  # a header and a row at least
