"""libLLVM discovery (`backend.find_libllvm`): each place it looks, its order, and its errors.

Every test builds fake libraries (empty files named like libLLVM) in a temporary directory
and hides the machine's own: no ``CONDA_PREFIX``, a ``PATH`` with only the fake tools, no
system directories, no ``ldconfig`` outside that ``PATH``.
"""

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from dopplertof import backend


def _touch(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"")
    return path


def _tool(bin_dir, name, script):
    """An executable shell script ``bin_dir/name`` with the given body."""
    path = bin_dir / name
    path.write_text("#!/bin/sh\n" + script)
    path.chmod(0o755)
    return path


@pytest.fixture
def bare(tmp_path, monkeypatch):
    """A machine without any libLLVM; returns the directory on its (only) PATH."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for name in (backend.LLVM_PATH_ENV, "CONDA_PREFIX"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("PATH", str(bin_dir))
    monkeypatch.setattr(backend, "_SYSTEM_LLVM_DIRS", ())
    monkeypatch.setattr(backend, "_LDCONFIG_FALLBACKS", ())
    return bin_dir


@pytest.mark.parametrize(
    "relative, major",
    [
        ("lib/libLLVM-17.so", 17),
        ("lib/libLLVM-14.0.6.so.1", 14),
        ("lib/libLLVM.so.19.1", 19),
        ("lib/libLLVM-19.dylib", 19),
        ("llvm-18/lib/libLLVM.so", 18),
        ("llvm17/lib/libLLVM.so", 17),
        ("opt/llvm@17/lib/libLLVM.dylib", 17),
        ("Cellar/llvm/19.1.7/lib/libLLVM.dylib", 19),
        ("lib/libLLVM.so", None),
        ("lib/libLLVMCore.a", None),
        ("llvm-19/lib/libLLVMSupport.so", None),
    ],
)
def test_llvm_major_reads_name_and_directory(tmp_path, relative, major):
    assert backend._llvm_major(str(tmp_path / relative)) == major


def test_llvm_major_follows_an_unversioned_link(tmp_path):
    _touch(tmp_path / "libLLVM.so.19.1")
    (tmp_path / "libLLVM.so").symlink_to("libLLVM.so.19.1")
    assert backend._llvm_major(str(tmp_path / "libLLVM.so")) == 19


def test_nothing_found_is_none(bare):
    assert backend.find_libllvm() is None


def test_user_path_wins_over_everything(bare, tmp_path, monkeypatch):
    _touch(tmp_path / "sys" / "libLLVM-19.so")
    monkeypatch.setattr(backend, "_SYSTEM_LLVM_DIRS", (str(tmp_path / "sys"),))
    mine = _touch(tmp_path / "mine" / "libLLVM-17.so")
    monkeypatch.setenv(backend.LLVM_PATH_ENV, str(mine))
    assert backend.find_libllvm() == str(mine)


def test_user_path_of_unknown_version_is_trusted(bare, tmp_path, monkeypatch):
    mine = _touch(tmp_path / "custom" / "libLLVM.so")
    monkeypatch.setenv(backend.LLVM_PATH_ENV, str(mine))
    assert backend.find_libllvm() == str(mine)


@pytest.mark.parametrize("name, problem", [("missing/libLLVM-19.so", "is not a file"),
                                           ("libLLVM-15.so", "is LLVM 15")])
def test_unusable_user_path_is_an_error_naming_it(bare, tmp_path, monkeypatch, name, problem):
    path = tmp_path / name
    if "missing" not in name:
        _touch(path)
    monkeypatch.setenv(backend.LLVM_PATH_ENV, str(path))
    with pytest.raises(backend.BackendError, match=rf"^DRJIT_LIBLLVM_PATH={path} {problem}"):
        backend.find_libllvm()


def test_conda_prefix(bare, tmp_path, monkeypatch):
    _touch(tmp_path / "env" / "lib" / "libLLVM-15.so")
    lib = _touch(tmp_path / "env" / "lib" / "libLLVM-17.so")
    monkeypatch.setenv("CONDA_PREFIX", str(tmp_path / "env"))
    assert backend.find_libllvm() == str(lib)


def test_conda_prefix_comes_before_a_newer_system_llvm(bare, tmp_path, monkeypatch):
    # The environment's own libLLVM matches its libstdc++; a system one may not.
    lib = _touch(tmp_path / "env" / "lib" / "libLLVM-17.so")
    monkeypatch.setenv("CONDA_PREFIX", str(tmp_path / "env"))
    _touch(tmp_path / "sys" / "libLLVM-19.so")
    monkeypatch.setattr(backend, "_SYSTEM_LLVM_DIRS", (str(tmp_path / "sys"),))
    assert backend.find_libllvm() == str(lib)


def test_llvm_config_libdir_with_version_from_the_tool(bare, tmp_path):
    lib = _touch(tmp_path / "prefix" / "lib" / "libLLVM.so")
    _tool(bare, "llvm-config",
          f'case "$1" in --libdir) echo {lib.parent};; --version) echo 17.0.6;; esac\n')
    assert backend.find_libllvm() == str(lib)


def test_newest_llvm_config_nn_wins(bare, tmp_path):
    for major in (16, 18):
        lib = _touch(tmp_path / f"prefix{major}" / "lib" / f"libLLVM-{major}.so")
        _tool(bare, f"llvm-config-{major}",
              f'case "$1" in --libdir) echo {lib.parent};; --version) echo {major}.1.0;; esac\n')
    _tool(bare, "llvm-config", 'case "$1" in --libdir) echo /nonexistent;; esac\n')
    assert backend.find_libllvm() == str(tmp_path / "prefix18" / "lib" / "libLLVM-18.so")


def test_system_dirs_newest_at_least_16(bare, tmp_path, monkeypatch):
    sys_dir = tmp_path / "usr" / "lib"
    for name in ("libLLVM-15.so", "libLLVM-17.so", "libLLVMCore.a", "libLLVMX86Info.a"):
        _touch(sys_dir / name)
    llvm18 = _touch(tmp_path / "usr" / "lib" / "llvm-18" / "lib" / "libLLVM.so")
    monkeypatch.setattr(
        backend, "_SYSTEM_LLVM_DIRS", (str(sys_dir), str(tmp_path / "usr/lib/llvm-*/lib"))
    )
    assert backend.find_libllvm() == str(llvm18)


def test_only_too_old_versions_is_none(bare, tmp_path, monkeypatch):
    for name in ("libLLVM-14.so.1", "libLLVM-15.so"):
        _touch(tmp_path / "sys" / name)
    monkeypatch.setattr(backend, "_SYSTEM_LLVM_DIRS", (str(tmp_path / "sys"),))
    assert backend.find_libllvm() is None


def test_ldconfig_cache(bare, tmp_path):
    old = _touch(tmp_path / "cache" / "libLLVM-15.so")
    lib = _touch(tmp_path / "cache" / "libLLVM.so.17.1")
    cache = [
        "3 libs found in cache /etc/ld.so.cache",
        f"\tlibLLVM.so.17.1 (libc6,x86-64) => {lib}",
        f"\tlibLLVM-15.so (libc6,x86-64) => {old}",
        f"\tlibLLVM.so.18.1 (libc6,x86-64) => {tmp_path}/gone/libLLVM.so.18.1",
    ]
    # printf is a shell built-in: PATH holds nothing but the fake tools.
    _tool(bare, "ldconfig", "".join(f"printf '%s\\n' '{line}'\n" for line in cache))
    assert backend.find_libllvm() == str(lib)


def test_configure_llvm_path_keeps_the_users_choice(bare, tmp_path, monkeypatch):
    monkeypatch.setenv(backend.LLVM_PATH_ENV, "/where/I/put/it/libLLVM.so")
    assert backend.configure_llvm_path() == "/where/I/put/it/libLLVM.so"


def test_configure_llvm_path_sets_what_it_finds(bare, tmp_path, monkeypatch):
    lib = _touch(tmp_path / "env" / "lib" / "libLLVM-17.so")
    monkeypatch.setenv("CONDA_PREFIX", str(tmp_path / "env"))
    assert backend.configure_llvm_path() == str(lib)
    assert os.environ[backend.LLVM_PATH_ENV] == str(lib)


def test_backend_module_loads_alone_without_drjit():
    """scripts/setup.sh runs backend.py before Dr.Jit exists: it must import nothing heavy."""
    path = Path(backend.__file__)
    code = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('dopplertof_backend', {str(path)!r})\n"
        "module = importlib.util.module_from_spec(spec)\n"
        "spec.loader.exec_module(module)\n"
        "heavy = {'drjit', 'mitsuba', 'numpy', 'dopplertof'} & set(sys.modules)\n"
        "print(sorted(heavy))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            check=True)
    assert result.stdout.strip() == "[]"


def test_backend_failure_says_what_to_install_or_fix(bare, tmp_path, monkeypatch):
    assert backend._install_hint().endswith(backend.LLVM_INSTALL_HINT)
    missing = tmp_path / "libLLVM-19.so"
    monkeypatch.setenv(backend.LLVM_PATH_ENV, str(missing))
    assert f"DRJIT_LIBLLVM_PATH={missing} is not a file" in backend._install_hint()


def test_only_too_old_versions_are_named_in_the_hint(bare, tmp_path, monkeypatch):
    old = _touch(tmp_path / "sys" / "libLLVM-15.so.1")
    monkeypatch.setattr(backend, "_SYSTEM_LLVM_DIRS", (str(tmp_path / "sys"),))
    assert backend._install_hint().endswith(f"{backend.LLVM_INSTALL_HINT} (found only LLVM 15 ({old}), too old)")


@pytest.mark.parametrize("version, user_path, where", [((15, 0, 6), None, "found by Dr.Jit's own search"),
                                                       ((14, 0, 0), "/x/libLLVM-14.so", "DRJIT_LIBLLVM_PATH=/x/libLLVM-14.so")])
def test_a_loaded_llvm_older_than_16_is_refused(version, user_path, where):
    with pytest.raises(backend.BackendError, match=f"libLLVM {'.'.join(map(str, version))} \\({where}\\).*apt-get install libllvm19"):
        backend.check_loaded_llvm(version, user_path)
    backend.check_loaded_llvm((16, 0, 0), user_path)
    backend.check_loaded_llvm((-1, -1, -1), user_path)  # none loaded: CUDA only


def _system_llvm(major):
    path = f"/usr/lib/x86_64-linux-gnu/libLLVM-{major}.so.1"
    if not os.path.isfile(path):
        pytest.skip(f"needs {path}")
    return {**os.environ, backend.LLVM_PATH_ENV: path}


@pytest.mark.parametrize("major", [15, 14])
def test_an_old_libllvm_is_one_error_line_on_the_command_line(tmp_path, major):
    """LLVM 15 starts Dr.Jit and aborts on the first kernel (exit 134) unless refused first;
    LLVM 14 Dr.Jit refuses itself, with a message of its own that we hold back."""
    env = _system_llvm(major)
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "dopplertof.cli", "render", "cornell-box", "--resolution", "8", "--spp", "2", "-o", str(out), "--quiet"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 2, run.stderr[-2000:]
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and f"LLVM {major}" in lines[0], run.stderr[-2000:]
    assert "libllvm19" in lines[0] or "point it at a newer one" in lines[0]
    assert not (out / "metadata.json").exists()


def test_an_old_libllvm_is_an_exception_from_the_api():
    env = _system_llvm(15)
    code = ("import dopplertof as dt\n"
            "try:\n    dt.render(dt.scenes.build('cornell-box', resolution=8), spp=2)\n"
            "except dt.backend.BackendError as exc:\n    print(exc)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "Dr.Jit loaded libLLVM 15" in run.stdout and "libllvm19" in run.stdout, run.stdout


def test_a_ctrl_c_while_dr_jit_starts_arrives_after_it():
    """A KeyboardInterrupt raised inside Dr.Jit's extension initialisation crashes the
    process (SIGSEGV): set_variant holds SIGINT until the import is done."""
    code = (
        "import os, signal, sys, threading\n"
        "import dopplertof.backend as backend\n"
        "threading.Timer(0.02, os.kill, (os.getpid(), signal.SIGINT)).start()\n"
        "try:\n    backend.set_variant('llvm_ad_rgb')\n    print('not interrupted')\n"
        "except KeyboardInterrupt:\n    print('interrupted after the import:', 'mitsuba' in sys.modules and 'drjit' in sys.modules)\n"
        "import mitsuba as mi\nprint(backend.set_variant('llvm_ad_rgb'), mi.variant())\n"
    )
    # SIGINT's default back in the child: a shell without job control starts background commands
    # (this suite too, where so run) with SIGINT ignored, and Python then installs no handler.
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # fmt: skip
    assert run.returncode == 0, (run.returncode, run.stderr[-2000:])
    assert run.stdout.splitlines() == ["interrupted after the import: True", "llvm_ad_rgb llvm_ad_rgb"], run.stdout


# ----------------------------------------------------------------------------------------
# Default variant: OptiX is probed before CUDA is chosen


def test_cuda_without_a_working_optix_falls_back_to_llvm_with_one_warning(monkeypatch):
    """Where Dr.Jit reports a CUDA backend but OptiX cannot trace (here: no CUDA at all
    behind the claim), the default is LLVM, said in one warning; the active variant stays."""
    import warnings

    import mitsuba as mi

    monkeypatch.delenv("DOPPLERTOF_VARIANT", raising=False)
    monkeypatch.setattr(backend, "_backend_works", lambda name: True)
    active = mi.variant()
    if backend.optix_problem() is None:
        pytest.skip("OptiX works on this machine")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert backend.default_variant() == "llvm_ad_rgb"
        assert backend.default_variant(mono=True) == "llvm_ad_mono"
    messages = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]
    assert len(messages) == 2 and all("OptiX does not" in m and "\n" not in m for m in messages), messages
    assert mi.variant() == active


def test_working_optix_picks_cuda(monkeypatch):
    monkeypatch.delenv("DOPPLERTOF_VARIANT", raising=False)
    monkeypatch.setattr(backend, "_backend_works", lambda name: True)
    monkeypatch.setattr(backend, "optix_problem", lambda mono=False: None)
    assert backend.default_variant() == "cuda_ad_rgb"
    assert backend.default_variant(mono=True) == "cuda_ad_mono"


# ----------------------------------------------------------------------------------------
# Float64 directions: IEEE division and square root (gpu-notes §2.1)

APPROXIMATE = re.compile(r"dr\.(normalize|rcp|rsqrt)\(")
FLOAT64 = re.compile(r"Vector3d|Point3d|Float64|\w+64\b")


def _approximate_float64(line: str) -> bool:
    return bool(APPROXIMATE.search(line) and FLOAT64.search(line))


def test_no_approximate_float64_normalisation_in_the_source():
    """On CUDA ``dr.normalize``, ``dr.rcp`` and ``dr.rsqrt`` of Float64 are approximate
    (about 20 mantissa bits: µm errors in optical lengths); Float64 vectors are normalised
    as ``v / dr.norm(v)``. A lint over the source: no line that makes or holds a Float64
    value (``Vector3d``, ``Float64``, ``64``-suffixed names) may call them."""
    offenders = []
    for path in sorted(Path(backend.__file__).parent.rglob("*.py")):
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if _approximate_float64(line):
                offenders.append(f"{path.name}:{number}: {line.strip()}")
    assert not offenders, offenders


@pytest.mark.parametrize(
    "line, offends",
    [
        ("    d64 = dr.normalize(mi.Vector3d(direction))", True),
        ("    inv = dr.rcp(mi.Float64(x))", True),
        ("    d64 = mi.Vector3d(direction) / dr.norm(mi.Vector3d(direction))", False),
        ("    d = dr.normalize(pose.vector_to_world(ray.d))", False),
    ],
)
def test_the_lint_tells_approximate_float64_from_the_rest(line, offends):
    assert _approximate_float64(line) == offends
