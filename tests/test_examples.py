"""The README's own-scene examples: the Python one builds and runs (a few steps), and its
scene file builds the same initial state."""
import importlib.util
import pathlib

import numpy as np

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"


def test_own_scene_example_runs():
    spec = importlib.util.spec_from_file_location("own_scene", EXAMPLES / "own_scene.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)            # builds the scene; the run is under __main__
    from fpsi_jax.run import simulate
    res = simulate(mod.scene, t_end=0.01, progress=False)
    assert res.physics.has_fsi and res.physics.n_bonds == mod.post.bonds.n
    assert np.all(np.isfinite(np.asarray(res.state.fluid.x)))
    # the water has started to move; the clamped discs have not
    assert float(np.abs(np.asarray(res.state.fluid.v)).max()) > 0.05
    fixed = np.asarray(mod.post.solid.fixed)
    assert np.allclose(np.asarray(res.state.solid.x)[fixed], mod.post.solid.x[fixed])


def test_own_scene_file_builds_the_same_initial_state_as_the_python_example():
    import jax
    from fpsi_jax import scenefile
    from fpsi_jax.run import setup
    from fpsi_jax.solver import dtype, init_state

    spec = importlib.util.spec_from_file_location("own_scene", EXAMPLES / "own_scene.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    case = scenefile.load(str(EXAMPLES / "dam_break_on_post.toml"))
    states, params = [], []
    for sc in (mod.scene, case.scene):
        phys, p = setup(sc)
        params.append(p.flat())
        states.append(jax.tree_util.tree_flatten_with_path(init_state(sc, phys,
                                                                      p.as_arrays(dtype(phys))))[0])
    assert [jax.tree_util.keystr(k) for k, _ in states[0]] == \
        [jax.tree_util.keystr(k) for k, _ in states[1]]
    for (k, a), (_, b) in zip(*states):
        assert np.array_equal(np.asarray(a), np.asarray(b)), jax.tree_util.keystr(k)
    assert params[0] == params[1]
    assert [p.name for p in case.probes] == ["top", "load", "level"]
