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
