"""What the process may use of the machine (dopplertof.resources): a container's limits,
read from a fake control-group tree, bound the CPUs and memory the host shows."""

import os

import pytest

from dopplertof import resources

GIB = 1 << 30


def _write(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)


@pytest.fixture
def fake(tmp_path, monkeypatch):
    """A fake /sys/fs/cgroup, /proc/self/cgroup and /proc/meminfo (16 GiB available), 8 CPUs."""
    root = tmp_path / "cgroup"
    monkeypatch.setattr(resources, "CGROUP_ROOT", str(root))
    monkeypatch.setattr(resources, "PROC_CGROUP", str(tmp_path / "self_cgroup"))
    monkeypatch.setattr(resources, "MEMINFO", str(tmp_path / "meminfo"))
    _write(tmp_path / "meminfo", f"MemTotal: 33554432 kB\nMemAvailable: {16 * GIB // 1024} kB\n")
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(8)), raising=False)
    return tmp_path, root


def test_without_control_groups_the_host_counts(fake):
    tmp_path, _ = fake
    _write(tmp_path / "self_cgroup", "0::/\n")
    assert resources.available_memory_bytes() == 16 * GIB and resources.usable_cpus() == 8


def test_a_v2_container_limit_and_quota_bound_memory_and_cpus(fake):
    """cgroup v2: the tightest limit of the group and its parents, less what is used; the CPU
    quota rounded up; "max" is no limit."""
    tmp_path, root = fake
    _write(tmp_path / "self_cgroup", "0::/pod/box\n")
    _write(root / "pod" / "box" / "memory.max", "max\n")
    _write(root / "pod" / "box" / "memory.current", f"{GIB}\n")
    _write(root / "pod" / "memory.max", f"{4 * GIB}\n")
    _write(root / "pod" / "memory.current", f"{GIB}\n")
    _write(root / "pod" / "box" / "cpu.max", "250000 100000\n")
    _write(root / "pod" / "cpu.max", "max 100000\n")
    assert resources.available_memory_bytes() == 3 * GIB
    assert resources.usable_cpus() == 3


def test_a_v1_limit_is_read_and_an_unlimited_one_ignored(fake):
    tmp_path, root = fake
    _write(tmp_path / "self_cgroup", "4:memory:/job\n1:cpu,cpuacct:/job\n0::/\n")
    _write(root / "memory" / "job" / "memory.limit_in_bytes", f"{2 * GIB}\n")
    _write(root / "memory" / "job" / "memory.usage_in_bytes", f"{GIB // 2}\n")
    _write(root / "memory" / "memory.limit_in_bytes", "9223372036854771712\n")  # none
    _write(root / "memory" / "memory.usage_in_bytes", f"{10 * GIB}\n")
    _write(root / "cpu" / "job" / "cpu.cfs_quota_us", "-1\n")
    _write(root / "cpu" / "job" / "cpu.cfs_period_us", "100000\n")
    assert resources.available_memory_bytes() == GIB + GIB // 2
    assert resources.usable_cpus() == 8  # no quota: the affinity's
    _write(root / "cpu" / "job" / "cpu.cfs_quota_us", "50000\n")
    assert resources.usable_cpus() == 1  # half a CPU: one


def test_the_host_bounds_a_looser_limit_and_nothing_known_is_none(fake):
    tmp_path, root = fake
    _write(tmp_path / "self_cgroup", "0::/box\n")
    _write(root / "box" / "memory.max", f"{64 * GIB}\n")
    _write(root / "box" / "memory.current", "0\n")
    assert resources.available_memory_bytes() == 16 * GIB
    os.remove(tmp_path / "meminfo")
    os.remove(tmp_path / "self_cgroup")
    assert resources.available_memory_bytes() is None and resources.usable_cpus() == 8
