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


@pytest.fixture
def features_dump() -> Path:
    """The C reference tool (tests/tools/dv_features_dump.c, double build). CI sets
    DV_FEATURES_DUMP and then a missing tool is a failure, not a skip."""
    env = os.environ.get("DV_FEATURES_DUMP")
    p = Path(env) if env else REPO / "build" / "f64" / "tests" / "dv_features_dump"
    if not p.is_file():
        if env:
            pytest.fail(f"DV_FEATURES_DUMP={env} does not exist")
        pytest.skip("build the f64 preset for the C reference dump tool")
    return p


@pytest.fixture
def ar_dump() -> Path:
    """The AR reference tool (tests/tools/dv_ar_dump.c, double build). CI sets DV_AR_DUMP and
    then a missing tool is a failure, not a skip."""
    env = os.environ.get("DV_AR_DUMP")
    p = Path(env) if env else REPO / "build" / "f64" / "tests" / "dv_ar_dump"
    if not p.is_file():
        if env:
            pytest.fail(f"DV_AR_DUMP={env} does not exist")
        pytest.skip("build the f64 preset for the C reference dump tool dv_ar_dump")
    return p


@pytest.fixture
def model_dump() -> Path:
    """The model reference tool (tests/tools/dv_model_dump.c, double build). CI sets
    DV_MODEL_DUMP and then a missing tool is a failure, not a skip."""
    env = os.environ.get("DV_MODEL_DUMP")
    p = Path(env) if env else REPO / "build" / "f64" / "tests" / "dv_model_dump"
    if not p.is_file():
        if env:
            pytest.fail(f"DV_MODEL_DUMP={env} does not exist")
        pytest.skip("build the f64 preset for the C reference dump tool dv_model_dump")
    return p
