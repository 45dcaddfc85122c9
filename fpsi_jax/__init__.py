"""fpsi-jax: differentiable 2D fluid–particle–structure interaction (SPH + DEM) on JAX."""
__version__ = "0.1.0"
