"""Choosing the Mitsuba variant and making Dr.Jit's CPU backend find a usable libLLVM.

Dr.Jit 1.5 needs libLLVM >= 16 for its LLVM (CPU) backend; versions 14 and 15 crash
with "Cannot select fminimum". Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` once, when it
starts, so :func:`configure_llvm_path` must run before ``import drjit``: importing
:mod:`dopplertof` does that.

Variant selection (:func:`set_variant`):

==========================  ====================================================
``DOPPLERTOF_VARIANT``      environment variable; forces a variant by name
default                     ``cuda_ad_rgb`` when a CUDA device works, otherwise
                            ``llvm_ad_rgb``
``mono=True``               the ``*_ad_mono`` variant of the chosen backend
==========================  ====================================================
"""

from __future__ import annotations

import glob
import os
import re

MIN_LLVM_MAJOR = 16
SUPPORTED_VARIANTS = ("llvm_ad_rgb", "llvm_ad_mono", "cuda_ad_rgb", "cuda_ad_mono")

_LLVM_SEARCH_PATTERNS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM*.dylib",
    "/usr/local/opt/llvm/lib/libLLVM*.dylib",
)


class BackendError(RuntimeError):
    """No Dr.Jit backend (LLVM or CUDA) could be started."""


def _llvm_major(path: str) -> int | None:
    """Major LLVM version encoded in a library path, or None if it cannot be read."""
    name = os.path.basename(path)
    for pattern in (r"libLLVM-(\d+)", r"libLLVM\.so\.(\d+)", r"llvm-(\d+)/"):
        match = re.search(pattern, name if "/" not in pattern else path)
        if match:
            return int(match.group(1))
    return None


def find_libllvm() -> str | None:
    """Path of the newest libLLVM >= 16 on this machine, or None."""
    candidates = []
    for pattern in _LLVM_SEARCH_PATTERNS:
        for path in glob.glob(pattern):
            major = _llvm_major(path)
            if major is not None and major >= MIN_LLVM_MAJOR and os.path.isfile(path):
                candidates.append((major, path))
    if not candidates:
        return None
    return max(candidates)[1]


def configure_llvm_path() -> str | None:
    """Set ``DRJIT_LIBLLVM_PATH`` to a libLLVM >= 16 unless the user already set it.

    Returns the path in use (None if none was found; the CUDA backend may still work).
    """
    current = os.environ.get("DRJIT_LIBLLVM_PATH")
    if current:
        return current
    path = find_libllvm()
    if path:
        os.environ["DRJIT_LIBLLVM_PATH"] = path
    return path


_INSTALL_HINT = (
    "dopplertof needs Dr.Jit's LLVM backend (libLLVM >= 16; on Debian/Ubuntu: "
    "'apt-get install libllvm19', or set DRJIT_LIBLLVM_PATH) or a working CUDA GPU"
)


def _backend_works(name: str) -> bool:
    """True if Dr.Jit can start its ``CUDA`` or ``LLVM`` backend."""
    import drjit as dr

    try:
        return bool(dr.has_backend(getattr(dr.JitBackend, name)))
    except Exception:  # noqa: BLE001 - any failure means "not available"
        return False


def default_variant(mono: bool = False) -> str:
    """The variant dopplertof uses when none is asked for (see module docstring)."""
    forced = os.environ.get("DOPPLERTOF_VARIANT")
    if forced:
        return forced
    if _backend_works("CUDA"):
        backend = "cuda"
    elif _backend_works("LLVM"):
        backend = "llvm"
    else:
        raise BackendError(f"no Dr.Jit backend works: {_INSTALL_HINT}")
    return f"{backend}_ad_{'mono' if mono else 'rgb'}"


def set_variant(variant: str | None = None, mono: bool = False) -> str:
    """Activate a Mitsuba variant for dopplertof.

    Parameters
    ----------
    variant : str, optional
        One of ``llvm_ad_rgb``, ``llvm_ad_mono``, ``cuda_ad_rgb``, ``cuda_ad_mono``.
        Default: :func:`default_variant`.
    mono : bool
        With ``variant=None``, choose the monochrome variant.

    Returns the active variant name.
    """
    import mitsuba as mi

    name = variant or default_variant(mono)
    if name not in SUPPORTED_VARIANTS:
        raise ValueError(
            f"unsupported Mitsuba variant {name!r}; choose one of {', '.join(SUPPORTED_VARIANTS)}"
        )
    if mi.variant() != name:
        try:
            mi.set_variant(name)
        except Exception as exc:  # noqa: BLE001 - turn Dr.Jit's message into one line
            raise BackendError(f"cannot start Mitsuba variant {name!r} ({exc}); {_INSTALL_HINT}") from None
    return name


def ensure_variant() -> str:
    """The active dopplertof-compatible variant, choosing the default if none is set."""
    import mitsuba as mi

    current = mi.variant()
    if current in SUPPORTED_VARIANTS:
        return current
    return set_variant()
