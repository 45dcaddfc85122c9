"""fpsi-jax: differentiable 2D fluid–particle–structure interaction (SPH + DEM) on JAX."""
from ._xla import configure as _configure_xla
from ._xla import configure_cache as _configure_cache

__version__ = "0.1.0"
XLA_FAST_SUMS = _configure_xla()   # see fpsi_jax/_xla.py: XLA:CPU fusion setting
COMPILE_CACHE = _configure_cache()  # see fpsi_jax/_xla.py: compiled programs kept on disk
