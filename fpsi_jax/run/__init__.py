"""Running scenes: the host driver (compiled chunks, neighbour-overflow redo, the error
diagnosis, output), HDF5/XDMF io, observers and stability probes."""
from .driver import Result, setup, simulate

__all__ = ["Result", "setup", "simulate"]
