"""Kernels read no unaligned host memory (:mod:`dopplertof.jitdata`): Dr.Jit writes
whether a mapped numpy array is 64-byte aligned into every LLVM kernel that reads it, so a
kernel's code, and whether Dr.Jit's kernel cache finds it, depended on where numpy had put
a table (the street's per-body kernel compiled anew, 30 s, in every test run)."""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import dopplertof as dt
from dopplertof.jitdata import ALIGNMENT_BYTES, jit_array

UNALIGNED_LOAD = ", align 1,"  # how Dr.Jit's LLVM backend loads an input it marked unaligned


def _kernels_reading_unaligned_memory(work) -> list:
    """The operation counts of the kernels ``work()`` launched whose code loads an input
    as unaligned."""
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        dr.kernel_history()
        work()
        history = dr.kernel_history()
    irs = [(k.get("operation_count"), k["ir"].getvalue() if hasattr(k["ir"], "getvalue") else str(k["ir"])) for k in history if "ir" in k]
    assert irs, "the kernel history holds no kernel code to check"
    return [ops for ops, ir in irs if UNALIGNED_LOAD in ir]


def test_a_numpy_array_off_alignment_is_seen_and_jit_array_aligns_it():
    """The check can fail: numpy data 8 bytes past an aligned address, mapped as it is,
    gives a kernel an unaligned load; the same values through ``jit_array`` do not."""
    backing = np.zeros(2 * ALIGNMENT_BYTES // 8 + 16)
    first = (-backing.ctypes.data % ALIGNMENT_BYTES) // 8 + 1  # 8 bytes past a 64-byte boundary
    values = backing[first : first + 16]
    values[:] = np.arange(16) + 0.5
    mapped = mi.Float64(values)
    assert _kernels_reading_unaligned_memory(lambda: dr.eval(mapped * 3.0 + 1.0))
    aligned = jit_array(mi.Float64, values)
    assert not _kernels_reading_unaligned_memory(lambda: dr.eval(aligned * 3.0 + 1.0))
    np.testing.assert_array_equal(np.asarray(aligned), values)


_FOUR_CAMERAS = [dt.Camera(heterodyne=h, phase=p) for h in (0.0, 1.0) for p in (0.0, 1.5707963267948966)]


@pytest.mark.parametrize(
    ("name", "traversal", "options"),
    [
        ("street", "auto", {}),
        ("rotating", "per-body", {}),
        ("falling-box", "atlas", {}),
        ("cornell-box", "slices", {}),
        ("street", "slices", {}),
        ("cornell-box", "auto", {"spp": 2}),
        ("glossy", "auto", {"spp": 2, "cameras": _FOUR_CAMERAS, "correlation": "reconnection"}),
        ("rotating", "auto", {"spp": 2, "cameras": _FOUR_CAMERAS, "time_sampling": "analytic", "correlation": "replay"}),
        ("cornell-box", "auto", {"spp": 8, "cameras": _FOUR_CAMERAS, "n_times": 4}),
        ("cornell-box", "auto", {"spp": 4, "cameras": _FOUR_CAMERAS, "time_sampling": "uniform", "correlation": "none"}),
    ],
)
def test_no_render_kernel_reads_unaligned_memory(name, traversal, options):
    """A built-in scene's render (the street: 24 bodies' motion tables, the tree; atlas
    cells; slices' hit tables and merged meshes; the film and material tables; the paired
    tracer, n_times 4, uniform times) compiles the same kernels wherever numpy put its
    tables. At 2 spp a pass holds one antithetic group, and the kernel reads each row of
    the strata table (``lanes.stratum``) as a scalar: unaligned numpy rows there made the
    same scene's path kernel differ between processes
    (``test_another_field_of_view_reuses_the_kernel`` failed now and then)."""
    scene = dt.scenes.build(name, resolution=8)
    scene.traversal = traversal
    assert _kernels_reading_unaligned_memory(lambda: dt.render(scene, **{"spp": 4, "seed": 1, **options})) == []


# Run in a new process for each field of view: a kernel's virtual calls are laid out over
# every live Mitsuba object of the process (Dr.Jit's registry), so two renders in the
# suite's own process can differ by what other tests left alive, not by the field of view.
_PATH_KERNELS = """
import sys
import drjit as dr
import dopplertof as dt
scene_dict = dt.scenes.cornell_box_dict(resolution=8)
next(v for v in scene_dict.values() if isinstance(v, dict) and v.get("type") == "perspective")["fov"] = float(sys.argv[1])
scene = dt.load_scene(scene_dict)
with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
    dr.kernel_history()
    dt.render(scene, spp=2, seed=0)
    history = dr.kernel_history()
print(sorted(k["hash"] for k in history if (k.get("operation_count") or 0) > 1000))
"""


def test_another_field_of_view_reuses_the_kernel():
    """The optical flow's projection scales (``tracing.path.pinhole_scales``) are kernel
    data: the moving Cornell box seen through another field of view is the same path
    kernel, found in Dr.Jit's cache. As literals they made every field of view compile
    anew. Each field of view renders in a new process (see above)."""
    import subprocess
    import sys

    runs = [subprocess.Popen([sys.executable, "-c", _PATH_KERNELS, fov], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for fov in ("20", "30")]
    outputs = [run.communicate(timeout=600) for run in runs]
    assert all(run.returncode == 0 for run in runs), [err for _, err in outputs]
    kernels = [out.strip().splitlines()[-1] for out, _ in outputs]
    assert kernels[0] != "[]" and kernels[0] == kernels[1], kernels
