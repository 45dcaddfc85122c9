"""calibrate.batch: a batch of parameter sets, run in sequence inside one compiled call
(the default) or vectorised, gives the same losses as one-by-one calls, sharded over two
(forced host) devices or not."""
import json
import os
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SCRIPT = r"""
import json, sys
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np
from calibrate import batch, cases, space as sp
from calibrate.fit import Calibration
from calibrate.rollout import prepare
from calibrate.targets import StaticDeflection
from fpsi_jax.cases import build

scene = build("cantilever", variant="tip", alpha=0.0, damping=20.0, d=0.0025, length=0.04)
pr = prepare(scene, 300 * 2.7e-6, cases.tracker(scene, cases.cantilever_tip(scene)),
             dt=2.7e-6, chunk=20)
space = sp.ParamSpace(pr.params, [sp.stiffness(0.25, 4.0)])
cal = Calibration(pr, space, [StaticDeflection(value=-1e-4)])
vals, losses, used = batch.landscape(cal, space.z0, "stiffness", np.geomspace(0.5, 2.0, 4))
_, unsharded, used1 = batch.landscape(cal, space.z0, "stiffness", vals, shard=False)
_, vec, used_v = batch.landscape(cal, space.z0, "stiffness", vals, vectorize=True)
_, vec1, _ = batch.landscape(cal, space.z0, "stiffness", vals, shard=False, vectorize=True)
single = [float(cal.value(space.z_of({"stiffness": v}))[0]) for v in vals]
print(json.dumps({"devices": jax.device_count(), "used": used, "batched": losses.tolist(),
                  "unsharded": unsharded.tolist(), "used_unsharded": used1,
                  "vectorized": vec.tolist(), "used_vectorized": used_v,
                  "vectorized_unsharded": vec1.tolist(),
                  "single": single}))
"""


def test_batched_losses_match_single_calls_in_sequence_or_vectorised_sharded_or_not():
    n_dev = 2
    env = dict(os.environ, PYTHONPATH=ROOT, JAX_PLATFORMS="cpu",
               XLA_FLAGS=f"--xla_force_host_platform_device_count={n_dev}")
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    rec = json.loads(out.stdout.strip().splitlines()[-1])
    assert rec["devices"] == n_dev and rec["used"] == n_dev
    assert rec["used_unsharded"] == 1
    np.testing.assert_allclose(rec["batched"], rec["single"], rtol=1e-10)
    np.testing.assert_allclose(rec["unsharded"], rec["single"], rtol=1e-10)
    assert rec["used_vectorized"] == n_dev
    np.testing.assert_allclose(rec["vectorized"], rec["single"], rtol=1e-10)
    np.testing.assert_allclose(rec["vectorized_unsharded"], rec["single"], rtol=1e-10)
    assert np.all(np.diff(rec["batched"]) != 0)      # the loss does vary along the sweep
