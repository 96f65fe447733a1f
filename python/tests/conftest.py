"""Finds the build tree: PENUMBRA_BUILD_DIR (as setup.sh), else ../../build."""
import os
import pathlib
import sys

import pytest

SOURCE = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("PENUMBRA_BUILD_DIR", SOURCE / "build")).resolve()
sys.path.insert(0, str(BUILD / "python"))


@pytest.fixture(scope="session")
def cli():
    """The penumbra executable of the same build."""
    path = BUILD / "penumbra"
    assert path.exists(), f"{path} not built"
    return path


@pytest.fixture(scope="session")
def examples():
    return SOURCE / "examples"
