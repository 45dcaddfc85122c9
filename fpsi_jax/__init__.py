"""fpsi-jax: differentiable 2D fluid–particle–structure interaction (SPH + DEM) on JAX."""
from ._xla import configure as _configure_xla
from ._xla import configure_cache as use_compile_cache

__version__ = "0.1.0"
XLA_FAST_SUMS = _configure_xla()   # see fpsi_jax/_xla.py: XLA:CPU fusion setting
# use_compile_cache(): keep compiled programs on disk (fpsi_jax/_xla.py; the fpsi command does)
