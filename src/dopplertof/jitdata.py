"""Host data (numpy) handed to Dr.Jit as kernel inputs.

Dr.Jit maps a numpy array's memory without a copy, and on the CPU whether that address is
aligned as Dr.Jit aligns its own (64 bytes, the vector width) is written into every kernel
that reads the array: ``align 1`` loads instead of aligned ones. numpy's addresses are
aligned to 16 bytes, so which kernel a render compiles depended on where numpy put a table
(a street's 24 bodies' motion parameters: a different kernel, and a fresh compile, in
nearly every process: Dr.Jit's kernel cache rarely hit). :func:`jit_array` copies the data
into memory aligned as Dr.Jit's own first, so a kernel's code depends on the scene alone
(``tests/test_jitdata.py``).

=================  =======================================================================
:func:`jit_array`  a Dr.Jit array of a given type holding numpy data, 64-byte aligned
=================  =======================================================================
"""

from __future__ import annotations

import numpy as np

ALIGNMENT_BYTES = 64  # Dr.Jit's own allocations; its LLVM kernels ask min(64, 8 lanes × item) of an input


def jit_array(array_type, values, dtype=None):
    """A Dr.Jit array of ``array_type`` holding ``values``, its memory aligned as Dr.Jit
    aligns its own (module docstring).

    ==========  ================  ==============================================
    array_type  type              a flat Dr.Jit array type (``mi.Float``,
                                  ``mi.Float64``, ``mi.UInt32``, ``mi.Int32``)
    values      array_like        the data (flattened)
    dtype       numpy dtype|None  its element type (None: ``values``' own)
    ==========  ================  ==============================================

    Returns
    -------
    array_type
        Evaluated, mapping an aligned copy of ``values`` (kept alive by Dr.Jit).
    """
    flat = np.ascontiguousarray(values, dtype).ravel()
    buffer = np.empty(flat.nbytes + ALIGNMENT_BYTES, np.uint8)
    start = -buffer.ctypes.data % ALIGNMENT_BYTES
    aligned = buffer[start : start + flat.nbytes].view(flat.dtype)
    aligned[:] = flat
    return array_type(aligned)
