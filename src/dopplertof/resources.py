"""What this process may use of the machine: its CPUs and its memory, a container's limits
included.

Linux puts a process's limits in its control groups, which ``/proc/meminfo`` and
``os.cpu_count()`` do not show: a container given 4 GiB and 2 CPUs on a 256 GiB, 64-core
host sees the host there. A limit may be set on the process's own group or on any group
above it; the tightest one holds.

=====================  ===================================================================
what                   where it is read
=====================  ===================================================================
memory                 ``MemAvailable`` (``/proc/meminfo``); a cgroup's limit less its use
                       (v2 ``memory.max`` − ``memory.current``, v1 ``memory.limit_in_bytes``
                       − ``memory.usage_in_bytes``)
CPUs                   the affinity mask (``os.sched_getaffinity``: a cpuset, a batch job's
                       share); a cgroup's quota (v2 ``cpu.max``, v1 ``cpu.cfs_quota_us`` /
                       ``cpu.cfs_period_us``), rounded up
=====================  ===================================================================
"""

from __future__ import annotations

import math
import os

CGROUP_ROOT = "/sys/fs/cgroup"  # where the control groups are mounted
PROC_CGROUP = "/proc/self/cgroup"  # this process's groups
MEMINFO = "/proc/meminfo"
_UNLIMITED = 1 << 60  # a v1 limit at or above this is none (the kernel writes about 2^63)


def _read_words(path: str) -> list[str] | None:
    try:
        with open(path, encoding="ascii") as f:
            return f.read().split()
    except (OSError, UnicodeDecodeError):
        return None


def _group_dirs(controller: str) -> list[str]:
    """The folders of this process's group for ``controller`` (v1; the unified hierarchy's
    where v1 does not list it) and of every group above it, innermost first; empty where
    there are none."""
    try:
        with open(PROC_CGROUP, encoding="ascii") as f:
            lines = [line.rstrip("\n").split(":", 2) for line in f if line.count(":") >= 2]
    except OSError:
        return []
    v1 = [path for _, controllers, path in lines if controller in controllers.split(",")]
    if v1:
        base, path = os.path.join(CGROUP_ROOT, controller), v1[0]
    else:
        unified = [path for hierarchy, controllers, path in lines if hierarchy == "0" and controllers == ""]
        if not unified:
            return []
        base, path = CGROUP_ROOT, unified[0]
    parts = [p for p in path.split("/") if p and p != ".."]
    return [os.path.join(base, *parts[:k]) for k in range(len(parts), -1, -1)]


def _cgroup_memory_left() -> int | None:
    """The bytes this process's groups let it use beyond what they use (the tightest), or
    None where none sets a limit."""
    left = None
    for folder in _group_dirs("memory"):
        for limit_file, usage_file in (("memory.max", "memory.current"), ("memory.limit_in_bytes", "memory.usage_in_bytes")):
            limit, usage = _read_words(os.path.join(folder, limit_file)), _read_words(os.path.join(folder, usage_file))
            if not limit or not usage or limit[0] == "max":
                continue
            try:
                limit_b, usage_b = int(limit[0]), int(usage[0])
            except ValueError:
                continue
            if limit_b < _UNLIMITED:
                left = max(limit_b - usage_b, 0) if left is None else min(left, max(limit_b - usage_b, 0))
    return left


def _cgroup_cpus() -> float | None:
    """The CPUs this process's groups' quotas allow (the tightest), or None where none sets one."""
    allowed = None
    for folder in _group_dirs("cpu"):
        quota = None
        v2 = _read_words(os.path.join(folder, "cpu.max"))
        if v2 and len(v2) == 2 and v2[0] != "max":
            quota = (v2[0], v2[1])
        else:
            q, p = _read_words(os.path.join(folder, "cpu.cfs_quota_us")), _read_words(os.path.join(folder, "cpu.cfs_period_us"))
            if q and p and q[0] != "-1":
                quota = (q[0], p[0])
        if quota is None:
            continue
        try:
            cpus = int(quota[0]) / int(quota[1])
        except (ValueError, ZeroDivisionError):
            continue
        if cpus > 0:
            allowed = cpus if allowed is None else min(allowed, cpus)
    return allowed


def available_memory_bytes() -> int | None:
    """The memory this process may still take (bytes): Linux's ``MemAvailable``, less where a
    control group's limit leaves less; None where neither is known (not Linux).

    Returns
    -------
    int or None
    """
    words = None
    try:
        with open(MEMINFO, encoding="ascii") as f:
            words = next((line.split() for line in f if line.startswith("MemAvailable:")), None)
    except OSError:
        pass
    try:
        system = int(words[1]) * 1024 if words else None
    except ValueError:
        system = None
    group = _cgroup_memory_left()
    known = [b for b in (system, group) if b is not None]
    return min(known) if known else None


def usable_cpus() -> int:
    """The CPUs this process may run on: its affinity mask (a cpuset, a batch job's share, not
    the machine's), at most a control group's CPU quota (rounded up).

    Returns
    -------
    int
        ≥ 1.
    """
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cpus = os.cpu_count() or 1
    quota = _cgroup_cpus()
    if quota is not None:
        cpus = min(cpus, math.ceil(quota))
    return max(1, cpus)
