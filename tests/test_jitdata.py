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


@pytest.mark.parametrize(("name", "traversal"), [("street", "auto"), ("rotating", "per-body"), ("falling-box", "atlas"), ("cornell-box", "slices"), ("street", "slices")])
def test_no_render_kernel_reads_unaligned_memory(name, traversal):
    """A built-in scene's render (the street: 24 bodies' motion tables, the tree; atlas
    cells; slices' hit tables and merged meshes; the film and material tables) compiles
    the same kernels wherever numpy put its tables."""
    scene = dt.scenes.build(name, resolution=8)
    scene.traversal = traversal
    assert _kernels_reading_unaligned_memory(lambda: dt.render(scene, spp=4, seed=1)) == []

