"""The memory this machine has left, for refusals before work that would not fit."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["available"]


def available() -> float | None:
    """Bytes of memory available to a new allocation, or None where unknown.

    Linux: ``MemAvailable`` of ``/proc/meminfo`` (free memory plus what the kernel can
    reclaim from caches); elsewhere the free physical pages (``sysconf``), where the
    platform reports them.
    """
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None
