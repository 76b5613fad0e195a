"""The memory this machine has left, for refusals before work that would not fit."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["available"]

#: Where a container's memory limit and use are read (cgroup v2, then v1).
CGROUP_FILES = (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                 "/sys/fs/cgroup/memory/memory.usage_in_bytes"))


def available() -> float | None:
    """Bytes of memory available to a new allocation, or None where unknown.

    Linux: ``MemAvailable`` of ``/proc/meminfo`` (free memory plus what the kernel can
    reclaim from caches), and no more than a container's memory limit less its use
    (cgroup v2 or v1); elsewhere the free physical pages (``sysconf``), where the
    platform reports them.
    """
    machine = _meminfo_available()
    if machine is None:
        try:
            machine = float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return None
    container = _cgroup_left()
    return machine if container is None else min(machine, container)


def _meminfo_available() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_left() -> float | None:
    """A container's memory limit less its use, None without a limit."""
    for limit_file, usage_file in CGROUP_FILES:
        try:
            limit = Path(limit_file).read_text().strip()
            usage = Path(usage_file).read_text().strip()
        except OSError:
            continue
        if limit == "max" or not limit.isdigit() or not usage.isdigit():
            return None
        if int(limit) >= 2**60:  # v1's "no limit"
            return None
        return max(float(int(limit) - int(usage)), 0.0)
    return None
