"""Test set-up: float64 JAX and the persistent compilation cache (explicit, as at every entry point)."""

import os

import numpy as np
import pytest

from contopt.config import setup_jax

os.environ.setdefault("CONTOPT_JAX_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "contopt", "jax"))
setup_jax()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
