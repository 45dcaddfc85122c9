"""The discs' displacement state (model.state.SolidState: x = x_ref + u, the bonds read u):
a stiff bonded structure far from the origin stands under its own weight in float32 as it
does in float64.

Before, the drift updated x itself: a coordinate of 0.6 m is held to 6·10⁻⁸ m in float32,
about half of a stiff wall disc's motion in one DEM step, and the rounding, read back
through the bonds' springs, heated the wall: this 3 × 12 disc wall reached 6.1 kPa of bond
tension in 0.05 s (0.22 kPa in float64) and its discs 2.3 times the float64 run's speed;
the full 0.12 m wall cracked under its own weight after 1 s.
"""
import numpy as np

import jax.numpy as jnp

from fpsi_jax.run import simulate
from fpsi_jax.scenefile import load

WALL = """
[scene]
t_end = 0.05
[tank]
width = 1.0
height = 0.2
[[structure]]
name = "wall"
box = [0.6, 0.0, 0.615, 0.06]
d = "5 mm"
E = "30 MPa"
nu = 0.2
rho = 2400.0
plane_strain = true
clamp = [0.6, 0.0, 0.615, 0.005]
sigma_c = "50 kPa"
tau_c = "50 kPa"
"""
R = 0.0025
AREA, INERTIA = 2 * R, 2.0 / 3.0 * R ** 3          # slab section per unit thickness, λ = 1


def _tension_and_speed(state):
    b, s = state.bonds, state.solid
    sigma = b.fn / AREA + jnp.abs(b.m) * R / INERTIA           # K21, β̄ = 1
    return jnp.max(sigma), jnp.sqrt(jnp.mean(jnp.sum(s.v * s.v, -1)))


def test_bonded_wall_at_0_6_m_stands_in_float32_as_in_float64(tmp_path):
    path = tmp_path / "wall.toml"
    path.write_text(WALL)
    scene = load(str(path)).scene
    out = {}
    for x64 in (False, True):
        res = simulate(scene, progress=False, observe=_tension_and_speed, x64=x64)
        sigma, speed = (np.asarray(o, float) for o in res.observations)
        out[x64] = sigma.max(), speed[len(speed) // 2:].max()
    rho_g_h = 2400.0 * 9.81 * 0.06                               # 1.41 kPa at the foot
    assert out[True][0] < 0.2 * rho_g_h                          # 0.22 kPa: the start's jolt
    assert out[False][0] < 0.7 * rho_g_h                         # 0.60 kPa (was 6.1)
    assert abs(out[False][1] / out[True][1] - 1.0) < 0.1         # +1.8 % (was +126 %)
