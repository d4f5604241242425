"""scripts/setup.sh as a new user meets it: a normal user on a machine that has libLLVM,
and the one line it prints where something is missing.

The script runs in a copy of the repository, with a clean environment (``env -i``) and fake
``apt-get``, ``apt`` and ``sudo`` first on ``PATH`` that record their calls. The normal-user
tests need root to create that user (``dtuser``) and run as it; elsewhere they skip.
"""

import os
import pwd
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from dopplertof import backend

REPO = Path(__file__).resolve().parent.parent
USER = "dtuser"
SYSTEM_PATH = "/usr/local/bin:/usr/bin:/bin"
# What setup.sh needs from the repository: itself, and what `pip install -e .` reads.
SETUP_FILES = ("pyproject.toml", "README.md", "scripts", "src")
# Network and pip settings of the machine (proxies, mirrors) still apply to the new user.
PASSED_ENV_PREFIXES = ("PIP_", "http_proxy", "https_proxy", "no_proxy",
                       "HTTP_PROXY", "HTTPS_PROXY", "NO_PROXY")
FAKE_TOOLS = ("apt-get", "apt", "sudo")


def _is_root():
    return hasattr(os, "geteuid") and os.geteuid() == 0


@pytest.fixture(scope="module")
def normal_user():
    """The name of a normal (non-root) user, created if it does not exist."""
    if not _is_root():
        pytest.skip("needs root to create and become a normal user")
    # Both live in /usr/sbin, which not every PATH has.
    search_path = f"{os.environ.get('PATH', '')}:/usr/sbin:/sbin"
    useradd = shutil.which("useradd", path=search_path)
    if useradd is None or shutil.which("runuser", path=search_path) is None:
        pytest.skip("needs useradd and runuser to run as a normal user")
    try:
        pwd.getpwnam(USER)
    except KeyError:
        subprocess.run([useradd, "--create-home", "--shell", "/bin/bash", USER], check=True)
    return USER


@pytest.fixture
def checkout(request):
    """A copy of what setup.sh needs, in a directory any user can reach, with fake apt tools.

    Returns (repository copy, fake-tool directory, call log). Owned by ``normal_user`` when
    the test asks for it.
    """
    # Not pytest's tmp_path: it lies under root's private /tmp/pytest-of-root.
    root = Path(tempfile.mkdtemp(prefix="dopplertof-setup-", dir="/tmp"))
    root.chmod(0o755)
    repo = root / "repo"
    repo.mkdir()
    for name in SETUP_FILES:
        source = REPO / name
        if source.is_dir():
            shutil.copytree(source, repo / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(source, repo / name)
    fake_bin = root / "fake-bin"
    fake_bin.mkdir()
    calls = root / "calls.log"
    calls.touch()
    calls.chmod(0o666)
    for tool in FAKE_TOOLS:
        path = fake_bin / tool
        path.write_text(f'#!/bin/sh\necho "{tool} $*" >> {calls}\nexit 1\n')
        path.chmod(0o755)
    if "normal_user" in request.fixturenames:
        user = request.getfixturevalue("normal_user")
        subprocess.run(["chown", "-R", f"{user}:", str(repo)], check=True)
    yield repo, fake_bin, calls
    shutil.rmtree(root)


def _run_setup(checkout, user=None, env=None, timeout_s=600):
    """Run ``bash scripts/setup.sh`` in the copy, as ``user`` (default: this process's)."""
    repo, fake_bin, _ = checkout
    clean_env = {key: value for key, value in os.environ.items()
                 if key.startswith(PASSED_ENV_PREFIXES)}
    clean_env.update(PATH=f"{fake_bin}:{SYSTEM_PATH}", LANG="C.UTF-8")
    if user is not None:
        clean_env["HOME"] = pwd.getpwnam(user).pw_dir
    clean_env.update(env or {})
    command = ["env", "-i", *(f"{k}={v}" for k, v in clean_env.items()),
               "bash", "scripts/setup.sh"]
    if user is not None:
        command = ["runuser", "-u", user, "--", *command]
    return subprocess.run(command, cwd=repo, capture_output=True, text=True, timeout=timeout_s)


def _stub_libllvm_search(repo, cuda_devices=0):
    """Make the copy's libLLVM search find nothing, and ``cuda_devices`` GPUs.

    Patches the copy of backend.py (the one place setup.sh asks), since no machine can
    hide its own libLLVM from the system directories without root and a container.
    """
    path = repo / "src" / "dopplertof" / "backend.py"
    with path.open("a") as module:
        module.write(f"\n_LLVM_ROUTES = ()\ndef cuda_device_count():\n    return {cuda_devices}\n")


@pytest.mark.slow
def test_normal_user_with_libllvm_needs_no_apt(normal_user, checkout, monkeypatch):
    monkeypatch.delenv(backend.LLVM_PATH_ENV, raising=False)
    monkeypatch.delenv("CONDA_PREFIX", raising=False)
    if backend.find_libllvm() is None:
        pytest.skip("no libLLVM >= 16 on this machine (setup.sh as root installs one)")
    result = _run_setup(checkout, user=normal_user)
    assert result.returncode == 0, result.stderr
    repo, _, calls = checkout
    assert calls.read_text() == ""
    # The new environment starts Dr.Jit's CPU backend, with the libLLVM the package found.
    check = subprocess.run(
        ["runuser", "-u", normal_user, "--", "env", "-i", f"PATH={SYSTEM_PATH}",
         ".venv/bin/python", "-c",
         "import dopplertof, os; print(dopplertof.set_variant('llvm_ad_rgb'), "
         "os.environ['DRJIT_LIBLLVM_PATH'])"],
        cwd=repo, capture_output=True, text=True, timeout=300,
    )
    assert check.returncode == 0, check.stderr
    variant, libllvm = check.stdout.split()
    assert variant == "llvm_ad_rgb"
    assert backend._llvm_major(libllvm) >= backend.MIN_LLVM_MAJOR


def test_normal_user_with_a_wrong_drjit_libllvm_path_gets_one_line(normal_user, checkout):
    result = _run_setup(checkout, user=normal_user,
                        env={backend.LLVM_PATH_ENV: "/nonexistent/libLLVM-19.so"})
    assert result.returncode != 0
    assert result.stderr.splitlines() == [
        "setup: DRJIT_LIBLLVM_PATH=/nonexistent/libLLVM-19.so is not a file; point it at "
        "libLLVM >= 16 (e.g. /usr/lib/x86_64-linux-gnu/libLLVM-19.so) or unset it"
    ]
    assert result.stdout == ""
    repo, _, calls = checkout
    assert calls.read_text() == ""
    assert not (repo / ".venv").exists()


def test_normal_user_without_libllvm_is_told_what_to_install(normal_user, checkout):
    repo, _, calls = checkout
    _stub_libllvm_search(repo)
    result = _run_setup(checkout, user=normal_user)
    assert result.returncode != 0
    assert result.stderr.splitlines() == [f"setup: {backend.LLVM_INSTALL_HINT}"]
    assert "sudo apt-get install libllvm19" in result.stderr
    assert calls.read_text() == ""


def test_root_without_libllvm_installs_libllvm19(checkout):
    if not _is_root():
        pytest.skip("setup.sh installs packages only as root")
    repo, _, calls = checkout
    _stub_libllvm_search(repo)
    result = _run_setup(checkout)
    # The fake apt-get fails, so the script stops with the same one line after trying.
    assert result.returncode != 0
    assert "setup: installing libllvm19" in result.stdout
    assert result.stderr.splitlines()[-1] == f"setup: {backend.LLVM_INSTALL_HINT}"
    assert "apt-get install -y -qq libllvm19" in calls.read_text()


def test_normal_user_without_venv_support_is_told_what_to_install(normal_user, checkout):
    repo, _, calls = checkout
    # Debian without python3-venv has venv but no ensurepip: shadow it with a broken one.
    hide = repo / "hide-ensurepip"
    hide.mkdir()
    (hide / "ensurepip.py").write_text("raise ImportError('not installed')\n")
    # Whatever this machine has, the libLLVM check before passes: the variable names a file.
    fake_llvm = repo / "libLLVM-19.so"
    fake_llvm.touch()
    result = _run_setup(checkout, user=normal_user,
                        env={"PYTHONPATH": str(hide), backend.LLVM_PATH_ENV: str(fake_llvm)})
    assert result.returncode != 0
    assert result.stderr.splitlines() == [
        "setup: python3 cannot make a virtual environment (no ensurepip); install it with "
        "'sudo apt-get install python3-venv' (Debian/Ubuntu) or set PYTHON=/path/to/python3"
    ]
    assert calls.read_text() == ""
    assert not (repo / ".venv").exists()


@pytest.mark.slow
def test_a_venv_made_elsewhere_is_made_again(normal_user, checkout, monkeypatch):
    """A checkout copied with its ``.venv`` (another user's, or moved: its interpreter link
    points where this user cannot go) used to stop setup with a bare ``Permission denied``;
    now setup makes the environment again and finishes."""
    monkeypatch.delenv(backend.LLVM_PATH_ENV, raising=False)
    if backend.find_libllvm() is None:
        pytest.skip("no libLLVM >= 16 on this machine (setup.sh as root installs one)")
    repo, _, calls = checkout
    bin_dir = repo / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    (bin_dir / "python3").symlink_to("/root/no-such-python/bin/python3")
    (bin_dir / "python").symlink_to("python3")
    subprocess.run(["chown", "-R", "--no-dereference", f"{normal_user}:", str(repo / ".venv")], check=True)
    result = _run_setup(checkout, user=normal_user)
    assert result.returncode == 0, result.stderr
    assert "setup: .venv's Python does not run here (a moved or copied checkout?); making .venv again" in result.stdout
    assert calls.read_text() == ""
    check = subprocess.run(["runuser", "-u", normal_user, "--", ".venv/bin/python", "-c", "import dopplertof"],
                           cwd=repo, capture_output=True, text=True, timeout=300)
    assert check.returncode == 0, check.stderr
