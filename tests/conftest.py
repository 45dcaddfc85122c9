import os
import sys

import jax
import pytest

import fpsi_jax  # noqa: F401  (sets its XLA:CPU flag before any JAX backend starts)

fpsi_jax.use_compile_cache()   # the workers share compiled programs (fpsi_jax/_xla.py)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)


@pytest.fixture(scope="module", autouse=True)
def _release_compiled_programs():
    """Drop JAX's compiled programs after each test module. One process that compiles the
    whole suite's programs (several hundred) otherwise runs out of the memory maps LLVM
    places its code in (vm.max_map_count = 65530) and XLA dies with a segmentation fault
    late in the run."""
    yield
    jax.clear_caches()


@pytest.fixture
def tiny_tank():
    """A 10 cm tank of water, 2 cm spacing: ~25 fluid particles, compiles in seconds."""
    from fpsi_jax import cases
    return cases.build("hydrostatic_tank", dx=0.02, depth=0.1, width=0.1, t_end=0.02)


@pytest.fixture(scope="module")
def float64():
    """float64 for one test module (tight tolerances); restored afterwards so the other
    modules keep JAX's default float32. Use: pytestmark = usefixtures("float64")."""
    prev = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", True)
    yield
    jax.config.update("jax_enable_x64", prev)


@pytest.fixture(scope="session")
def step_hlo():
    """``step_hlo(scene, dtype=float32, **physics_options) -> (text, scopes, files)``: the
    lowered ``fpsi_jax.solver.forward.step`` of a scene, the ``jax.named_scope`` components
    of its op locations ("jit(step)/dem.contacts/...") and the Python files its ops were
    traced from. Proves a mechanism is absent from the compiled program."""
    import re

    import jax.numpy as jnp

    from fpsi_jax.run.driver import setup
    from fpsi_jax.solver import forward, init

    def lower(scene, dtype=jnp.float32, **opts):
        phys, params = setup(scene, **opts)
        p = params.as_arrays(dtype)
        st = init.init_state(scene, phys, p)
        text = jax.jit(forward.step, static_argnums=0).lower(phys, st, p).as_text(
            debug_info=True)
        scopes = set()
        # absolute ("jit(step)/dem.contacts/...") and, inside loops such as the DEM
        # sub-steps, relative ("dem.contacts/...") op locations
        for loc in re.findall(r'loc\("([^"]*/[^"]*)"', text):
            if not loc.endswith(".py"):
                scopes.update(loc.split("/"))
        files = {os.path.basename(f) for f in re.findall(r'loc\("([^"]+\.py)"', text)}
        return text, scopes, files

    return lower
