"""Every registered scene ships as ``examples/<name>.toml``, and the file builds the same
run as the Python builder: the initial State (every leaf array, shape and dtype), the
Params, the Physics options, the domain, t_end, v_max and the time step are identical."""
import dataclasses
import pathlib

import jax
import numpy as np
import pytest

from fpsi_jax import cases, scenefile
from fpsi_jax.run.driver import setup
from fpsi_jax.solver import init, stages

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture(autouse=True)
def float32_start():
    """Each case starts in JAX's default float32 (``setup`` turns float64 on for the x64
    scenes and leaves it on); the setting is restored afterwards."""
    prev = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", False)
    yield
    jax.config.update("jax_enable_x64", prev)


def start(scene):
    """(Physics, Params, initial State) of a scene, as ``simulate`` prepares them."""
    phys, params = setup(scene)
    return phys, params, init.init_state(scene, phys, params.as_arrays(stages.dtype(phys)))


def leaves(state):
    """[(key path, numpy array)] of a State; the tree structures themselves are not compared
    (jax-md's neighbour lists hold closures, different objects in two builds)."""
    flat, _ = jax.tree_util.tree_flatten_with_path(state)
    return [(jax.tree_util.keystr(k), np.asarray(v)) for k, v in flat]


def differing_leaves(a, b):
    return [ka for (ka, x), (_, y) in zip(a, b)
            if x.shape != y.shape or x.dtype != y.dtype or not np.array_equal(x, y)]


def test_every_scene_has_an_example():
    missing = [n for n in cases.SCENES if not (EXAMPLES / f"{n}.toml").exists()]
    assert not missing


@pytest.mark.parametrize("name", list(cases.SCENES))
def test_file_builds_the_registered_scene(name):
    built = cases.build(name)
    filed = scenefile.load(str(EXAMPLES / f"{name}.toml")).scene
    phys_a, params_a, state_a = start(built)
    phys_b, params_b, state_b = start(filed)

    la, lb = leaves(state_a), leaves(state_b)
    assert [k for k, _ in la] == [k for k, _ in lb]
    assert differing_leaves(la, lb) == []

    fa, fb = params_a.flat(), params_b.flat()
    assert list(fa) == list(fb)
    assert [k for k in fa if not np.array_equal(np.asarray(fa[k]), np.asarray(fb[k]))] == []

    assert [f.name for f in dataclasses.fields(phys_a)
            if getattr(phys_a, f.name) != getattr(phys_b, f.name)] == []

    for key in ("domain_lo", "domain_hi"):
        assert tuple(map(float, getattr(built, key))) == tuple(map(float, getattr(filed, key)))
    assert (built.t_end, built.v_max, built.dt) == (filed.t_end, filed.v_max, filed.dt)
    assert float(params_a.dt) == float(params_b.dt)         # the step setup derives
