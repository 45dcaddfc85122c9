import os
import sys

import jax
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)


@pytest.fixture
def tiny_tank():
    """A 10 cm tank of water, 2 cm spacing: ~25 fluid particles, compiles in seconds."""
    from fpsi_jax import scenes
    return scenes.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.02)


@pytest.fixture(scope="module")
def float64():
    """float64 for one test module (tight tolerances); restored afterwards so the other
    modules keep JAX's default float32. Use: pytestmark = usefixtures("float64")."""
    prev = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", prev)
