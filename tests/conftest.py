"""Shared fixtures: fixed keys and seeds, hypothesis settings for jit-compiled code."""

import os

import jax
import numpy as np
import pytest
from hypothesis import HealthCheck, settings

import morphojax as mj

# Programs compiled before (by an earlier module, after `_release_compiled_programs`, or by
# an earlier run) are loaded from JAX's persistent compilation cache instead of compiled
# again; MORPHOJAX_CACHE_DIR chooses its folder, `off` turns it off.
mj.use_compilation_cache()

# Compilation dominates the first call of a property; deadlines would only measure it.
settings.register_profile(
    "morphojax", deadline=None, max_examples=12, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "morphojax"))


@pytest.fixture
def key():
    return jax.random.key(1234)


@pytest.fixture
def rng():
    return np.random.default_rng(20201)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs after each test module. XLA:CPU keeps every compiled
    program mapped in memory; a worker running a large share of the suite reached the
    kernel's default limit of 65,530 memory maps (56,843 counted in one worker) and crashed
    with a segmentation fault inside compilation. Programs are still shared within a module."""
    yield
    jax.clear_caches()
