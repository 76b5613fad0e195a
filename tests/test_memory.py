"""The memory a run may use: the machine's available memory, no more than a container's
limit less its use."""

import pytest

from skfem_granular import memory


def test_available_is_positive_and_at_most_the_machine():
    left = memory.available()
    assert left is not None and left > 0
    import os

    total = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    assert left <= total


@pytest.mark.parametrize("limit, usage, expected", [
    ("4000000000", "1500000000", 2.5e9),      # a 4 GB container with 1.5 GB in use
    ("max", "1500000000", None),              # cgroup v2 without a limit
    ("9223372036854771712", "10", None),      # cgroup v1's "no limit"
    ("1000", "5000", 0.0),                    # over its limit: nothing left
])
def test_container_limit_less_its_use(tmp_path, monkeypatch, limit, usage, expected):
    (tmp_path / "max").write_text(limit + "\n")
    (tmp_path / "current").write_text(usage + "\n")
    monkeypatch.setattr(memory, "CGROUP_FILES", ((str(tmp_path / "max"),
                                                   str(tmp_path / "current")),))
    assert memory._cgroup_left() == expected
    machine = memory._meminfo_available()
    if expected is not None and machine is not None:
        assert memory.available() == min(machine, expected)
