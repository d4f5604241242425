"""Choosing the Mitsuba variant and making Dr.Jit's CPU backend find a usable libLLVM.

Dr.Jit 1.5 needs libLLVM >= 16 for its LLVM (CPU) backend; versions 14 and 15 crash
with "Cannot select fminimum". Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` once, when it
starts, so :func:`configure_llvm_path` must run before ``import drjit``: importing
:mod:`dopplertof` does that. Dr.Jit itself accepts LLVM 15 (found by its own search or
named by the user), so :func:`set_variant` and :func:`ensure_variant` refuse a loaded
libLLVM < 16 with a :class:`BackendError` before any kernel runs (:func:`check_loaded_llvm`).

:func:`find_libllvm` looks in this order and takes the first place that has a libLLVM
>= 16 (the newest there, if it has several):

=========================  =======================================================
``DRJIT_LIBLLVM_PATH``     environment variable, the user's choice; used as is, an
                           error if it is not a file or names an LLVM < 16
``$CONDA_PREFIX/lib``      the active conda environment (its libstdc++ matches)
``llvm-config``            ``--libdir`` of ``llvm-config`` and every
                           ``llvm-config-NN`` on ``PATH``
system directories         Debian/Ubuntu multiarch and ``/usr/lib/llvm-NN/lib``,
                           Fedora ``/usr/lib64``, ``/usr/local/lib``, Homebrew
``ldconfig -p``            whatever else the dynamic linker knows
=========================  =======================================================

Variant selection (:func:`set_variant`):

==========================  ====================================================
``DOPPLERTOF_VARIANT``      environment variable; forces a variant by name
default                     ``cuda_ad_rgb`` when a CUDA device works and OptiX
                            traces a probe ray (:func:`optix_problem`: a tiny
                            scene, one ray), otherwise ``llvm_ad_rgb`` (with a
                            one-line warning where CUDA works but OptiX does not)
``mono=True``               the ``*_ad_mono`` variant of the chosen backend
==========================  ====================================================

This module imports nothing outside the standard library at module level:
``scripts/setup.sh`` loads it on its own, before Dr.Jit is installed, so that the
libLLVM search has one home.
"""

from __future__ import annotations

import contextlib
import ctypes
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import warnings

MIN_LLVM_MAJOR = 16
SUPPORTED_VARIANTS = ("llvm_ad_rgb", "llvm_ad_mono", "cuda_ad_rgb", "cuda_ad_mono")
LLVM_PATH_ENV = "DRJIT_LIBLLVM_PATH"

LLVM_INSTALL_HINT = (
    f"libLLVM >= {MIN_LLVM_MAJOR} not found; install it with 'sudo apt-get install libllvm19' "
    "(Debian/Ubuntu), 'conda install -c conda-forge libllvm19', "
    f"or set {LLVM_PATH_ENV}=/path/to/libLLVM.so"
)

_SYSTEM_LLVM_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib/llvm-*/lib",
    "/usr/lib64",
    "/usr/lib64/llvm*/lib",
    "/usr/lib",
    "/usr/local/lib",
    "/opt/homebrew/opt/llvm/lib",
    "/opt/homebrew/opt/llvm@*/lib",
    "/usr/local/opt/llvm/lib",
    "/usr/local/opt/llvm@*/lib",
)

# ldconfig lives in /sbin, which a normal user's PATH often lacks.
_LDCONFIG_FALLBACKS = ("/sbin/ldconfig", "/usr/sbin/ldconfig")

# The one shared library of LLVM (not its static parts libLLVMCore.a, ...): libLLVM.so,
# libLLVM-19.so, libLLVM-14.0.6.so.1, libLLVM.so.19.1, libLLVM.dylib, libLLVM-19.dylib.
_LIBLLVM_NAME = re.compile(r"^libLLVM(?:-(\d+)[\w.]*)?\.(?:so(?:\.(\d+)[\w.]*)?|dylib)$")
# Where an unversioned name (libLLVM.so, libLLVM.dylib) still tells its version by its
# directory: /usr/lib/llvm-19/lib, Fedora's /usr/lib64/llvm17/lib, Homebrew's llvm@17 and
# Cellar/llvm/19.1.7.
_LLVM_DIR_VERSION = re.compile(r"(?:/llvm-|/llvm@|/llvm|/Cellar/llvm/)(\d+)[./]")


class BackendError(RuntimeError):
    """No Dr.Jit backend (LLVM or CUDA) could be started."""


def _llvm_major(path: str, major_hint: int | None = None) -> int | None:
    """Major LLVM version of a libLLVM shared library.

    Parameters
    ----------
    path : str
        Path of a file; anything but LLVM's shared library gives None.
    major_hint : int, optional
        Version to assume when neither the name, the file the name links to, nor the
        directory tells it (``llvm-config --version`` for files in its ``--libdir``).

    Returns the major version, or None if the file is no libLLVM or its version is unknown.
    """
    if not _LIBLLVM_NAME.match(os.path.basename(path)):
        return None
    # libLLVM.so -> libLLVM.so.19.1: the link's target names the version.
    for candidate in (path, os.path.realpath(path)):
        match = _LIBLLVM_NAME.match(os.path.basename(candidate))
        if match and (match.group(1) or match.group(2)):
            return int(match.group(1) or match.group(2))
    for candidate in (path, os.path.realpath(path)):
        match = _LLVM_DIR_VERSION.search(candidate)
        if match:
            return int(match.group(1))
    return major_hint


def _libraries_in(directory: str, major_hint: int | None = None) -> list[tuple[int, str]]:
    """(major version, path) of every libLLVM shared library directly in ``directory``."""
    found = []
    for path in glob.glob(os.path.join(glob.escape(directory), "libLLVM*")):
        major = _llvm_major(path, major_hint)
        if major is not None:
            found.append((major, path))
    return found


def _run(argv: list[str]) -> str:
    """Standard output of a short command, or "" if it cannot run or fails."""
    try:
        result = subprocess.run(argv, capture_output=True, text=True, timeout=10, check=True)
    except (OSError, subprocess.SubprocessError):
        return ""
    return result.stdout


def _from_conda() -> list[tuple[int, str]]:
    prefix = os.environ.get("CONDA_PREFIX")
    return _libraries_in(os.path.join(prefix, "lib")) if prefix else []


def _from_llvm_config() -> list[tuple[int, str]]:
    tools = {shutil.which("llvm-config")}
    for directory in os.environ.get("PATH", "").split(os.pathsep):
        if directory:
            tools.update(glob.glob(os.path.join(glob.escape(directory), "llvm-config-*")))
    # /bin and /usr/bin are often one directory: ask each tool once.
    tools = {os.path.realpath(t) for t in tools if t and os.access(t, os.X_OK)}
    found = set()
    for tool in sorted(tools):
        libdir = _run([tool, "--libdir"]).strip()
        version = re.match(r"\s*(\d+)", _run([tool, "--version"]))
        if libdir:
            found.update(_libraries_in(libdir, int(version.group(1)) if version else None))
    return sorted(found)


def _from_system_dirs() -> list[tuple[int, str]]:
    found = []
    for pattern in _SYSTEM_LLVM_DIRS:
        for directory in glob.glob(pattern):
            found += _libraries_in(directory)
    return found


def _from_ldconfig() -> list[tuple[int, str]]:
    tool = shutil.which("ldconfig") or next(
        (t for t in _LDCONFIG_FALLBACKS if os.access(t, os.X_OK)), None
    )
    if tool is None:
        return []
    found = []
    # Lines look like "\tlibLLVM.so.19.1 (libc6,x86-64) => /lib/x86_64-linux-gnu/libLLVM.so.19.1".
    for line in _run([tool, "-p"]).splitlines():
        path = line.rpartition("=>")[2].strip()
        major = _llvm_major(path) if path else None
        if major is not None:
            found.append((major, path))
    return found


_LLVM_ROUTES = (_from_conda, _from_llvm_config, _from_system_dirs, _from_ldconfig)


def _check_user_libllvm(path: str) -> str:
    """``path`` from ``DRJIT_LIBLLVM_PATH`` if it can be used; BackendError naming it if not."""
    if not os.path.isfile(path):
        raise BackendError(
            f"{LLVM_PATH_ENV}={path} is not a file; point it at libLLVM >= {MIN_LLVM_MAJOR} "
            f"(e.g. /usr/lib/x86_64-linux-gnu/libLLVM-19.so) or unset it"
        )
    major = _llvm_major(path)
    # An unknown version is the user's call: Dr.Jit says so if it cannot use the library.
    if major is not None and major < MIN_LLVM_MAJOR:
        raise BackendError(
            f"{LLVM_PATH_ENV}={path} is LLVM {major}, but Dr.Jit needs libLLVM >= "
            f"{MIN_LLVM_MAJOR}; point it at a newer one or unset it"
        )
    return path


def find_libllvm() -> str | None:
    """Path of a libLLVM >= 16 for Dr.Jit's CPU backend, or None if there is none.

    Looks in the order of the module docstring and takes the first place that has one,
    the newest if it has several.

    Raises
    ------
    BackendError
        ``DRJIT_LIBLLVM_PATH`` is set but not a file, or names an LLVM older than 16.
    """
    user_path = os.environ.get(LLVM_PATH_ENV)
    if user_path:
        return _check_user_libllvm(user_path)
    for route in _LLVM_ROUTES:
        usable = [
            (major, path)
            for major, path in route()
            if major >= MIN_LLVM_MAJOR and os.path.isfile(path)
        ]
        if usable:
            return max(usable)[1]
    return None


def configure_llvm_path() -> str | None:
    """Set ``DRJIT_LIBLLVM_PATH`` to a libLLVM >= 16 unless the user already set it.

    Returns the path in use (None if none was found; the CUDA backend may still work).
    Never raises: a wrong ``DRJIT_LIBLLVM_PATH`` is reported when a variant is chosen,
    so that importing dopplertof works on a CUDA-only machine.
    """
    current = os.environ.get(LLVM_PATH_ENV)
    if current:
        return current
    path = find_libllvm()
    if path:
        os.environ[LLVM_PATH_ENV] = path
    return path


def cuda_device_count() -> int:
    """Number of CUDA devices the NVIDIA driver reports; 0 without a driver or a GPU.

    Asks the driver library directly (``cuInit``, ``cuDeviceGetCount``), so it works
    before Dr.Jit is installed; :func:`default_variant` asks Dr.Jit itself.
    """
    for name in ("libcuda.so.1", "libcuda.so", "libcuda.dylib", "nvcuda.dll"):
        try:
            cuda = ctypes.CDLL(name)
        except OSError:
            continue
        count = ctypes.c_int(0)
        if cuda.cuInit(0) != 0 or cuda.cuDeviceGetCount(ctypes.byref(count)) != 0:
            return 0
        return count.value
    return 0


def _too_old_libllvm() -> str:
    """The libLLVM < 16 that the routes find, as "LLVM 14 (path), ..."; "" if none."""
    found = sorted({(major, path) for route in _LLVM_ROUTES for major, path in route() if major < MIN_LLVM_MAJOR})
    return ", ".join(f"LLVM {major} ({path})" for major, path in found)


def _install_hint() -> str:
    """What to install (or fix) so that a Dr.Jit backend starts."""
    try:
        llvm_problem = None if find_libllvm() else LLVM_INSTALL_HINT
    except BackendError as exc:
        llvm_problem = str(exc)
    too_old = _too_old_libllvm() if llvm_problem == LLVM_INSTALL_HINT else ""
    if too_old:
        llvm_problem = f"{LLVM_INSTALL_HINT} (found only {too_old}, too old)"
    if llvm_problem is None:
        return (
            f"dopplertof needs Dr.Jit's LLVM backend (libLLVM >= {MIN_LLVM_MAJOR}) "
            "or a working CUDA GPU"
        )
    return f"dopplertof needs Dr.Jit's LLVM backend or a working CUDA GPU: {llvm_problem}"


# What Dr.Jit prints on its own, straight to the process's stderr, when it loads a libLLVM too
# old for it (14); the BackendError of set_variant says it in one line.
_DRJIT_OLD_LLVM_MESSAGE = "jit_llvm_init(): the located LLVM version"


STOP_SIGNALS = tuple(s for s in (getattr(signal, n, None) for n in ("SIGINT", "SIGTERM", "SIGHUP")) if s is not None)
"""The signals that stop work (those of SIGINT, SIGTERM, SIGHUP this platform has): a render
stops after its pass (:class:`dopplertof.clitools.StopOnSignal`), a dataset at once
(:mod:`dopplertof.dataset.generate`), and loading the backend holds them."""


class Stopped(KeyboardInterrupt):
    """SIGTERM or SIGHUP turned into a KeyboardInterrupt.

    Parameters
    ----------
    signum : int
        The signal received; the command line exits with 128 + it.
    """

    def __init__(self, signum: int):
        super().__init__(f"signal {signum}")
        self.signum = signum


@contextlib.contextmanager
def signals_as_interrupt():
    """SIGTERM (e.g. from Slurm) and SIGHUP stop like Ctrl-C (a dataset keeps its finished
    shards, an experiment its cached results). What leaves is a :class:`Stopped` naming the
    signal, also where a render in progress caught it and raised a KeyboardInterrupt of
    its own."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []

    def handler(signum, frame):
        received.append(signum)
        raise Stopped(signum)

    previous = {s: signal.signal(s, handler) for s in STOP_SIGNALS if s != signal.SIGINT}  # SIGINT is one already
    try:
        yield
    except KeyboardInterrupt as exc:
        if received and not isinstance(exc, Stopped):
            raise Stopped(received[-1]) from None
        raise
    finally:
        for s, handler_before in previous.items():
            signal.signal(s, handler_before)


@contextlib.contextmanager
def signals_held():
    """Hold the Python-level handlers of SIGINT, SIGTERM and SIGHUP, and deliver what came
    when the block ends: a KeyboardInterrupt raised while Dr.Jit's extension initialises
    crashes the process (SIGSEGV), and one raised while a checkpoint is written leaves none
    (a second Ctrl-C during a render's first save lost every finished pass)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    saved = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    saved = {s: h for s, h in saved.items() if callable(h)}
    for s in saved:
        signal.signal(s, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        for s, handler in saved.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(received):
            signal.raise_signal(s)


def _import_mitsuba():
    """``import mitsuba`` (which starts Dr.Jit), with signals held (:func:`signals_held`) and
    Dr.Jit's own old-libLLVM message held back."""
    if "drjit" in sys.modules:  # started already: nothing left to protect or hold back
        import mitsuba

        return mitsuba
    import tempfile

    sys.stderr.flush()
    saved = os.dup(2)
    with signals_held(), tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 2)
        try:
            import mitsuba
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            capture.seek(0)
            lines = capture.read().decode(errors="replace").splitlines(keepends=True)
            sys.stderr.write("".join(line for line in lines if _DRJIT_OLD_LLVM_MESSAGE not in line))
    return mitsuba


def check_loaded_llvm(version: tuple, user_path: str | None = None) -> None:
    """BackendError unless the libLLVM Dr.Jit loaded is >= 16.

    Dr.Jit 1.5 accepts LLVM 15, whose first kernel then aborts the process ("LLVM ERROR:
    Cannot select ... fminimum", exit 134): this check must run before any kernel.

    Parameters
    ----------
    version : tuple of int
        (major, minor, patch) of the loaded libLLVM, ``drjit.detail.llvm_version()``;
        a negative major means none is loaded (nothing to check).
    user_path : str, optional
        ``DRJIT_LIBLLVM_PATH``, named in the message when set.
    """
    major = version[0]
    if 0 <= major < MIN_LLVM_MAJOR:
        where = f"{LLVM_PATH_ENV}={user_path}" if user_path else "found by Dr.Jit's own search"
        raise BackendError(
            f"Dr.Jit loaded libLLVM {'.'.join(map(str, version))} ({where}), which aborts on dopplertof's "
            f"kernels; dopplertof needs libLLVM >= {MIN_LLVM_MAJOR}: install it with 'sudo apt-get install "
            f"libllvm19' (Debian/Ubuntu) or 'conda install -c conda-forge libllvm19', "
            f"then unset {LLVM_PATH_ENV} or point it at the new library"
        )


def _check_llvm_variant(name: str) -> None:
    if name.startswith("llvm"):
        import drjit as dr

        check_loaded_llvm(tuple(dr.detail.llvm_version()), os.environ.get(LLVM_PATH_ENV))


def _backend_works(name: str) -> bool:
    """True if Dr.Jit can start its ``CUDA`` or ``LLVM`` backend."""
    import drjit as dr

    try:
        return bool(dr.has_backend(getattr(dr.JitBackend, name)))
    except Exception:  # noqa: BLE001 - any failure means "not available"
        return False


def optix_problem(mono: bool = False) -> str | None:
    """Why the CUDA variant cannot trace rays (one line), or None where it can: loads a
    scene of one rectangle on ``cuda_ad_rgb`` (``cuda_ad_mono``) and traces one ray at
    it. A CUDA device without a usable OptiX (no ``libnvoptix.so.1``, a driver that
    drjit-core refuses) fails at every scene load. The active variant is kept."""
    import drjit as dr
    import mitsuba as mi

    name = f"cuda_ad_{'mono' if mono else 'rgb'}"
    previous = mi.variant()
    try:
        mi.set_variant(name)
        scene = mi.load_dict({"type": "scene", "probe": {"type": "rectangle"}})
        hit = scene.ray_intersect_preliminary(mi.Ray3f(mi.Point3f(0, 0, 1), mi.Vector3f(0, 0, -1)))
        return None if bool(dr.all(hit.is_valid())) else "a probe ray at a rectangle missed it"
    except Exception as exc:  # noqa: BLE001 - any failure means "OptiX does not work"
        lines = str(exc).strip().splitlines()
        return f"{type(exc).__name__}: {lines[0] if lines else ''}"
    finally:
        if previous and previous != name:
            mi.set_variant(previous)


def default_variant(mono: bool = False) -> str:
    """The variant dopplertof uses when none is asked for (see module docstring)."""
    forced = os.environ.get("DOPPLERTOF_VARIANT")
    if forced:
        return forced
    cuda = _backend_works("CUDA")
    problem = optix_problem(mono) if cuda else None
    if cuda and problem is not None:
        warnings.warn(f"CUDA works but OptiX does not ({problem}); using the LLVM (CPU) backend", RuntimeWarning, stacklevel=2)
    if cuda and problem is None:
        backend = "cuda"
    elif _backend_works("LLVM"):
        backend = "llvm"
    else:
        raise BackendError(f"no Dr.Jit backend works; {_install_hint()}")
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

    Returns
    -------
    str
        The variant activated.

    Raises
    ------
    BackendError
        The variant cannot start, or its libLLVM is older than 16 (before any kernel runs).

    Examples
    --------
    >>> import dopplertof as dt
    >>> dt.set_variant("llvm_ad_rgb")
    'llvm_ad_rgb'
    """
    mi = _import_mitsuba()
    name = variant or default_variant(mono)
    if name not in SUPPORTED_VARIANTS:
        raise ValueError(
            f"unsupported Mitsuba variant {name!r}; choose one of {', '.join(SUPPORTED_VARIANTS)}"
        )
    if mi.variant() != name:
        try:
            with signals_held():  # the variant's modules are extensions too
                mi.set_variant(name)
        except Exception as exc:  # noqa: BLE001 - turn Dr.Jit's message into one line
            raise BackendError(
                f"cannot start Mitsuba variant {name!r} ({exc}); {_install_hint()}"
            ) from None
    _check_llvm_variant(name)
    return name


def ensure_variant() -> str:
    """The active dopplertof-compatible variant, choosing the default if none is set, or,
    with a warning, if the active one is not supported (BackendError as
    :func:`set_variant`, also for a variant the user set)."""
    mi = _import_mitsuba()
    current = mi.variant()
    if current in SUPPORTED_VARIANTS:
        _check_llvm_variant(current)
        return current
    chosen = set_variant()
    if current is not None:  # the user's own choice: changed, not silently
        warnings.warn(f"Mitsuba's active variant {current!r} is not one dopplertof renders in ({', '.join(SUPPORTED_VARIANTS)}: "
                      f"no scalar or spectral variant); switched to {chosen!r}", stacklevel=3)
    return chosen
