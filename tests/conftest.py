"""Every test runs in a fresh working directory of its own.

Scenes name output folders relative to the working directory
(``output.directory = "out/single_particle"``) and a folder belongs to one run:
two tests running the same bundled scene must not meet in the repository's
``out/``.
"""

import pytest


@pytest.fixture(autouse=True)
def _own_working_directory(tmp_path_factory, monkeypatch):
    monkeypatch.chdir(tmp_path_factory.mktemp("cwd"))


#: An environment variable naming the skips a run may have (reasons, separated by ";"): any
#: other skip fails the session. CI sets it, so a test that silently stops running (an
#: extra that failed to install, a changed import) is seen.
ALLOWED_SKIPS = "SKFEM_GRANULAR_ALLOWED_SKIPS"


def pytest_sessionfinish(session, exitstatus):
    import os

    allowed = os.environ.get(ALLOWED_SKIPS)
    if allowed is None:
        return
    reasons = {r.strip() for r in allowed.split(";") if r.strip()}
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    unexpected = []
    for report in (reporter.stats.get("skipped", []) if reporter else []):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        reason = reason.removeprefix("Skipped: ")
        if reason not in reasons:
            unexpected.append(f"{report.nodeid}: {reason}")
    if unexpected:
        reporter.write_line(f"{len(unexpected)} skips not named in {ALLOWED_SKIPS}:", red=True)
        for line in unexpected:
            reporter.write_line(f"  {line}", red=True)
        session.exitstatus = 1
