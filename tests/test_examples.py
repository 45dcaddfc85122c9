"""The README's own-scene example builds and runs (a few steps)."""
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
