"""SPH fluid: particle blocks, the fluid's parameters and the sound-speed rule.

The weakly compressible fluid needs a numerical sound speed c0 well above the fastest flow:
:func:`sound_speed` is the seeds' rule c0 = 10 v_max (W46, K35), which keeps density
fluctuations near 1 %. :func:`hydrostatic_fluid` starts a still block with the hydrostatic
density of the Tait EOS, so nothing moves at t = 0.
"""
from __future__ import annotations

import jax
import numpy as np

from ..model.errors import check_positive
from ..model.params import SphParams
from ..model.scene import FluidBlock
from ..physics import fpi, kernels
from ..physics.eos import density
from .geometry import fit_spacing, lattice, polygon_lattice  # noqa: F401  (re-exported)

G = 9.81   # |g| [m/s²]; Params.gravity is (0, −G) unless a scene says otherwise


def in_float64(f, *args):
    """``f(*args)`` computed in float64 as a NumPy array, whatever JAX's process-wide x64 flag
    says when the scene is built: a builder that calls the step's own JAX functions (the
    Tait inverse, the grains' voidage) gives the same scene in every process, float32 runs
    and float64 runs alike (each run casts it to its precision)."""
    with jax.enable_x64(True):
        return np.asarray(f(*args), float)


def sound_speed(v_max: float, factor: float = 10.0) -> float:
    """c0 = 10 v_max (W46, K35: B = 100 ρ0 v_max²/γ), v_max the scene's velocity scale."""
    return factor * float(v_max)


def dam_speed(height: float, g: float = G) -> float:
    """v_max = √(2 g H): the speed of water falling from height H (a dam break's front)."""
    return float(np.sqrt(2 * g * height))


def hydrostatic_fluid(x, rho0, c0, gamma, surface_y, g=G, dx=None, h=None):
    """Fluid block at rest with hydrostatic density ρ(P = ρ0 g (H − y)) and mass ρ0 dx²."""
    check_positive(rho0=rho0, c0=c0, gamma=gamma)
    p = rho0 * g * np.maximum(surface_y - x[:, 1], 0.0)
    rho = in_float64(density, p, rho0, c0, gamma)
    n = x.shape[0]
    return FluidBlock(x=x, v=np.zeros_like(x), rho=rho, mass=np.full(n, rho0 * dx * dx),
                      h=np.full(n, h))


def sph_params(rho0, c0, mu, dx, r_clump, eps_xsph, delta, gamma=7.0, alpha=0.0):
    """SphParams with the initial spacing Δp = dx (the anti-clump term's reference), checked
    (SphParams.validate) before any particle is made."""
    return SphParams(rho0=rho0, c0=c0, gamma=gamma, mu=mu, r_clump=r_clump, dp=dx,
                     eps_xsph=eps_xsph, delta=delta, alpha=alpha).checked()


def fluid_block(points, dx, rho0, c0, h, surface_y=None, gamma=7.0, g=G):
    """Fluid particles at ``points`` (spacing ``dx``), at rest, mass ρ0 dx², smoothing length
    ``h``, with the hydrostatic density below the free surface ``surface_y`` (default: the
    top of the block plus dx/2, the height of water the lattice stands for)."""
    check_positive(dx=dx, rho0=rho0, c0=c0, h=h)
    points = np.asarray(points, float)
    if surface_y is None:
        surface_y = float(points[:, 1].max()) + 0.5 * dx
    return hydrostatic_fluid(points, rho0, c0, gamma, surface_y, g=g, dx=dx, h=h)


def fluid_rectangle(x0, y0, width, height, dx, rho0, c0, h, surface_y=None, gamma=7.0, g=G):
    """A still water block [x0, x0+width] × [y0, y0+height] on a dx lattice
    (:func:`fluid_block`)."""
    check_positive(width=width, height=height, dx=dx)
    return fluid_block(lattice(x0, y0, width, height, dx), dx, rho0, c0, h, surface_y, gamma, g)


def fluid_polygon(vertices, dx, rho0, c0, h, surface_y=None, gamma=7.0, g=G):
    """A still water body filling the polygon ``vertices`` (m, 2) on a dx lattice
    (:func:`fluid_block`)."""
    check_positive(dx=dx)
    return fluid_block(polygon_lattice(vertices, dx), dx, rho0, c0, h, surface_y, gamma, g)


def fluid_among_grains(fluid, x_grain, r_grain, voidage, eps_floor=0.0, walls=None):
    """Fluid particles among grains get the mass ε ρ0 Δx² of the fluid their lattice cell
    holds (ε the voidage the grains leave them, W2, at least ``eps_floor``), so the start is
    at rest. ``walls``: the scene's DEM walls (a WallBlock) when the step counts the grains'
    wall images in the voidage (Physics.wall_images, fpi.wall_images)."""
    w = None if walls is None else (walls.a, walls.b, walls.image_sides())
    eps = in_float64(fpi.voidage_at, kernels.get("wendland"), fluid.x, fluid.h, x_grain,
                     np.pi * np.asarray(r_grain) ** 2, voidage, w)
    eps = np.maximum(eps, eps_floor)
    fluid.mass = fluid.mass * eps
    return fluid
