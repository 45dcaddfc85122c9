"""Small versions of the shipped scenes that several test modules share."""
import jax.numpy as jnp

from fpsi_jax import cases
from fpsi_jax.run.driver import setup
from fpsi_jax.solver import init


def coarse_plate(**kw):
    """The hydrostatic plate (a bonded disc plate under water, option fsi) at a coarse
    resolution: a fluid-coupled structure with DEM sub-steps."""
    return cases.build("hydrostatic_plate", dx=0.0035, d=0.0025, dx_boundary=0.0025, **kw)


def grain_scene(**kw):
    """One grain (d = 2.5 mm) in a 12 mm box of water (option fpi), float64; without the
    added mass (the engine's default) unless ``added_mass=True``."""
    base = dict(width=0.012, height=0.012, d=0.0025, y0=0.006, x0=0.006, dx=0.0015,
                h0=0.003, rho_grain=1000.0, x64=True, t_end=0.01, added_mass=False)
    return cases.build("sedimentation", **{**base, **kw})


def init_x64(scene, **opts):
    """(Physics, float64 Params, initial State) of ``scene``."""
    phys, params = setup(scene, **opts)
    p = params.as_arrays(jnp.float64)
    return phys, p, init.init_state(scene, phys, p)
