"""A dam break on an elastic post, built from the public builders (README, "Your own case")."""
import numpy as np

from fpsi_jax import build
from fpsi_jax.model import DemParams, Params, Scene, SphParams
from fpsi_jax.run import simulate

dx, d = 0.01, 0.005                                  # fluid spacing, disc diameter [m]
h = 1.25 * dx                                        # smoothing length
v_max = build.dam_speed(0.3)                         # √(2 g H) of the 0.3 m column
c0 = build.sound_speed(v_max)                        # c0 = 10 v_max
tank = build.tank(0.8, 0.6, dx, h, rho0=1000.0, dem_walls=True)
water = build.fluid_rectangle(0.0, 0.0, 0.2, 0.3, dx, rho0=1000.0, c0=c0, h=h)
post = build.bonded_rectangle(0.5, 0.0, 0.02, 0.15, d, E=5.0e6, nu=0.3, rho=1200.0,
                              plane_strain=True)
build.clamp(post.solid, (0.49, 0.0, 0.53, 0.011))    # its two bottom rows are fixed
lo, hi = tank.domain(headroom=1.0)                 # room for the splash above the walls
scene = Scene(
    name="dam_break_on_post", domain_lo=lo, domain_hi=hi, v_max=v_max, t_end=0.6,
    params=Params(sph=SphParams(rho0=1000.0, c0=c0, mu=1.0e-3, dp=dx, alpha=0.02),
                  dem=DemParams(kn=post.kn, ks=post.ks, mu=0.3), bond=post.bond),
    fluid=water, boundary=tank.boundary, solid=post.solid, bonds=post.bonds,
    walls=tank.walls, open_sides=("top",),        # a splash over the top leaves, counted
    options={"fsi": "extrapolated", "boundary_pressure": "extrapolated",
             "delta_sph": True, "artificial_viscosity": True})

if __name__ == "__main__":
    res = simulate(scene, t_end=0.6, output="results/dam_break_on_post.h5", every=0.02)
    top = np.asarray(res.state.solid.x)[:, 1].argmax()
    print(f"post top displaced {1e3 * (res.state.solid.x[top, 0] - post.solid.x[top, 0]):.1f} mm"
          f" after {res.n_steps} steps, {res.wall_s:.0f} s")
