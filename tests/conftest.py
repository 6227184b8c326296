"""Shared fixtures, the hypothesis profile and the tiers of the test suite.

The corpus of real programs is read in place from ``../shared/corpus`` (relative to the
project root) and never copied into the project.

Tiers: ``python -m pytest`` runs the fast tier, every test without a tier marker (about
1800 tests: 2 min 50 s on two cores shared with other work, load average 3);
``python -m pytest --all-tiers`` runs every tier, what CI runs (about 3900 tests: 9 min
50 s on the same machine).
The markers (pyproject.toml): ``corpus`` (tests over the whole shared corpus), ``judge``
(LinuxCNC's rs274 or the simulator judging many programs), ``browser`` (headless
Chromium), ``slow`` (anything else that takes long).  ``-m EXPR`` selects by marker
instead (``-m judge`` runs the judge tier alone), and a test file named on the command
line runs whole (``pytest tests/test_judge.py``).  ``--update-golden`` rewrites the
expected files of tests/test_golden.py instead of comparing with them.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, settings

ROOT = Path(__file__).resolve().parents[1]
CORPUS = (ROOT / "../shared/corpus").resolve()
SAMPLES = ROOT / "samples"

# CI and local runs give the same examples (derandomize) and slow machines no flaky
# deadline errors; example counts stay small so that the fast tier stays fast.
settings.register_profile(
    "ncopt",
    derandomize=True,
    deadline=None,
    max_examples=40,
    print_blob=True,
    # the explain phase traces coverage line by line: minutes on a failing numpy test
    phases=[Phase.explicit, Phase.reuse, Phase.generate, Phase.target, Phase.shrink],
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                           HealthCheck.filter_too_much],
)
settings.load_profile(os.environ.get("NCOPT_HYPOTHESIS_PROFILE", "ncopt"))

# no colour and no terminal width guesses in anything rich renders during tests
os.environ.setdefault("NO_COLOR", "1")
os.environ.setdefault("TERM", "dumb")
os.environ.setdefault("COLUMNS", "100")
# a default machine set in the developer's shell would change what the tests plan
os.environ.pop("NCOPT_MACHINE", None)


TIERS = ("corpus", "judge", "browser", "slow")  # markers of the tests the fast tier leaves


def pytest_addoption(parser):
    parser.addoption("--all-tiers", action="store_true", default=False,
                     help="run every tier (corpus, judge, browser, slow), not only the fast one")
    parser.addoption("--update-golden", action="store_true", default=False,
                     help="rewrite the expected files of tests/test_golden.py instead of "
                          "comparing with them")


def pytest_collection_modifyitems(config, items):
    """The fast tier: without --all-tiers or a -m expression, leave the tests that carry
    a tier marker (they are reported as deselected), except in the files named on the
    command line (``pytest tests/test_judge.py`` runs the judge)."""
    if config.getoption("--all-tiers") or config.getoption("-m"):
        return
    named = {Path(a.split("::")[0]).resolve() for a in config.args}
    keep, left = [], []
    for item in items:
        tiered = any(item.get_closest_marker(m) for m in TIERS)
        (left if tiered and Path(item.path).resolve() not in named else keep).append(item)
    if left:
        config.hook.pytest_deselected(items=left)
        items[:] = keep


def pytest_report_header(config):
    if not (config.getoption("--all-tiers") or config.getoption("-m")):
        return (f"fast tier: tests marked {', '.join(TIERS)} are deselected; "
                "--all-tiers runs them")
    return None


@pytest.fixture(scope="session")
def update_golden(request) -> bool:
    """--update-golden: the golden tests write what they get as the expected files."""
    return request.config.getoption("--update-golden")


def load_module(rel: str, name: str):
    """Import a script of the project (samples/make_bowl.py) from its file path."""
    spec = importlib.util.spec_from_file_location(name, ROOT / rel)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def corpus_dir() -> Path:
    if not CORPUS.is_dir():
        pytest.fail(f"the shared corpus is missing at {CORPUS}")
    return CORPUS


@pytest.fixture(scope="session")
def make_bowl():
    """samples/make_bowl.py: the analytic bowl, its mesh and an exact ball drop-cutter."""
    return load_module("samples/make_bowl.py", "make_bowl_for_tests")


@pytest.fixture(scope="session")
def bowl_stl(make_bowl, tmp_path_factory) -> Path:
    """A 1 mm grid of the bowl surface as a binary STL (chord error < 0.04 mm)."""
    V, F = make_bowl.bowl_mesh(1.0)
    path = tmp_path_factory.mktemp("mesh") / "bowl_1mm.stl"
    make_bowl.write_stl(path, V, F)
    return path


@pytest.fixture(scope="session")
def bowl_index(bowl_stl):
    from ncopt.contacts.geometry import MeshIndex, load_stl

    return MeshIndex(load_stl(bowl_stl))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20240611)


def _without_dac_override() -> None:
    """In the child before exec: drop CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH from the
    bounding set, so that root, too, obeys permission bits in the program it runs."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    for cap in (1, 2):
        if libc.prctl(24, cap, 0, 0, 0) != 0:  # PR_CAPBSET_DROP
            raise OSError(ctypes.get_errno(), "cannot drop a capability")


@pytest.fixture(scope="session")
def obeys_permissions():
    """A preexec_fn for subprocess under which a chmod 000 file is really unreadable.

    Not root: None (permission bits hold anyway).  Root: the capabilities that let root
    ignore them are dropped in the child; a root without the right to drop them (no
    CAP_SETPCAP) skips the test, the only case where permission bits cannot be tested.
    """
    if os.name != "posix" or os.geteuid() != 0:
        return None
    import subprocess

    try:
        subprocess.run(["true"], preexec_fn=_without_dac_override, check=True)
    except (OSError, subprocess.SubprocessError):
        pytest.skip("running as root without CAP_SETPCAP: permission bits do not bind")
    return _without_dac_override
