"""The model: errors, typed options, the static :class:`Physics`, the differentiable
:class:`Params`, the dynamic :class:`State` and the host-side :class:`Scene`."""
from .config import NeighborConfig, Physics
from .errors import ParameterError, SimulationError
from .params import BondParams, DemParams, FpiParams, Params, SphParams
from .scene import BondBlock, BoundaryBlock, FluidBlock, Scene, SolidBlock, WallBlock
from .state import State

__all__ = ["NeighborConfig", "Physics", "ParameterError", "SimulationError", "BondParams",
           "DemParams", "FpiParams", "Params", "SphParams", "BondBlock", "BoundaryBlock",
           "FluidBlock", "Scene", "SolidBlock", "WallBlock", "State"]
