"""Shared fixtures. The tests import the module from PYTHONPATH (CTest sets it to
<build>/python) and find the sources through MVKP_SOURCE_DIR (default: this
repository)."""
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import mvkp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))  # cxx_options.py

SOURCE_DIR = Path(os.environ.get("MVKP_SOURCE_DIR", Path(__file__).resolve().parents[2]))
SAMPLES = SOURCE_DIR / "samples"

# One thread, as the CLI: deterministic timings and no oversubscription under ctest -j.
mvkp.set_num_threads(1)


@pytest.fixture(scope="session")
def target():
    """starry_night.jpg as gray uint8, longest side 320."""
    return mvkp.prepare_target(mvkp.load_image(str(SAMPLES / "starry_night.jpg")), 320)


@pytest.fixture(scope="session")
def target_bgr():
    return mvkp.prepare_target(mvkp.load_image(str(SAMPLES / "starry_night.jpg"), color=True), 320)


@pytest.fixture(scope="session")
def model(target):
    return mvkp.train(target, seed=42)


@pytest.fixture(scope="session")
def rng():
    return np.random.default_rng(1234)
