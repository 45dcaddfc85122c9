"""Running scenes: the host driver (compiled chunks, neighbour-overflow redo, the error
diagnosis, output), HDF5/XDMF io, observers and stability probes."""
from .driver import Result, check_rollout, setup, simulate

__all__ = ["Result", "check_rollout", "setup", "simulate"]
