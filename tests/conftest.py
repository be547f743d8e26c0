"""Shared fixtures: the paper's arm and study (l1 = 0.6 m, l2 = 0.4 m, q* = (60, 30) deg, F = (0, -1) N)."""

import os
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # before numpy is imported: small
    os.environ.setdefault(_var, "1")  # matrices, a shared machine (as the Makefile and the CLI do)
# progress lines (stiffcal.progress) every hour in the tests, not every 5 s: a slow run on a loaded machine must
# not add lines to the stderr that a test reads; the tests of progress set their own interval
os.environ.setdefault("STIFFCAL_PROGRESS_S", "3600")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from stiffcal.model.robot import load_robot  # noqa: E402
from stiffcal.planning.study import load_config, study_from_config  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def paper_robot():
    return load_robot(ROOT / "config/robots/paper_2r.yaml")


@pytest.fixture(scope="session")
def paper_config():
    return load_config(ROOT / "config/config.yaml")


@pytest.fixture(scope="session")
def paper_study(paper_config):
    return study_from_config(paper_config, ROOT)


@pytest.fixture(autouse=True)
def _own_design_cache(tmp_path_factory, monkeypatch):
    """Every test its own empty cache of approximate designs (stiffcal.planning.designcache) for ``stiffcal design``:
    no test reads another's entry (one that patches the certificate sees its patch), none writes to ~/.cache."""
    monkeypatch.setenv("STIFFCAL_CACHE_DIR", str(tmp_path_factory.mktemp("design-cache")))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def pytest_terminal_summary(terminalreporter):
    """Say that the browser test ran (CI's output shows it), and with which browser."""
    for rep in terminalreporter.stats.get("passed", []):
        if rep.nodeid.endswith("test_report_renders_in_headless_chromium") and rep.when == "call":
            browser = dict(rep.user_properties).get("browser", "a browser")
            terminalreporter.write_line(f"browser test ran and passed in {browser}: {rep.nodeid}")
