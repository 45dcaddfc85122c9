"""fpsi-jax: differentiable 2D fluid–particle–structure interaction (SPH + DEM) on JAX."""
from ._xla import configure as _configure_xla

__version__ = "0.1.0"
XLA_FAST_SUMS = _configure_xla()   # see fpsi_jax/_xla.py: XLA:CPU fusion setting
