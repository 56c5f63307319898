"""Shared fixtures: paths to the repository, the shared data and the C reference tools."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SHARED = REPO.parent / "shared"


@pytest.fixture
def repo() -> Path:
    return REPO


@pytest.fixture
def shared_data() -> Path:
    d = SHARED / "data"
    if not d.is_dir():
        pytest.skip("../shared/data is not beside the repository")
    return d


def _c_tool(name: str) -> Path:
    """A C reference tool of the bit-for-bit checks (tests/tools/<name>.c, built by the f64
    preset). CI sets DV_<NAME> (e.g. DV_FEATURES_DUMP), and then a missing tool is a failure,
    not a skip."""
    var = "DV_" + name.removeprefix("dv_").upper()
    env = os.environ.get(var)
    p = Path(env) if env else REPO / "build" / "f64" / "tests" / name
    if not p.is_file():
        if env:
            pytest.fail(f"{var}={env} does not exist")
        pytest.skip(f"build the f64 preset for the C reference tool {name}")
    return p


@pytest.fixture
def features_dump() -> Path:
    return _c_tool("dv_features_dump")


@pytest.fixture
def ar_dump() -> Path:
    return _c_tool("dv_ar_dump")


@pytest.fixture
def model_dump() -> Path:
    return _c_tool("dv_model_dump")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The discover cases (most of a run's time, tens of seconds each) first, the rest in
    their order after them: on pytest-xdist the long tests then start early and the short
    ones fill the end, instead of one long test running alone on one core at the end."""
    items.sort(key=lambda it: not it.path.name.startswith("test_discover"))
