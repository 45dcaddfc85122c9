"""The solver: neighbour lists, the stages of a step, the step and rollouts, the initial
state, time-step bounds and health checks. Pure functions of (Physics, Params, State)."""
from .init import init_state, refresh_rates
from .stages import dtype, sph_positions
from .forward import advance, rollout, step
from .timestep import check_dt, dem_dt, sph_dt, stable_dt, substeps_for

__all__ = ["init_state", "refresh_rates", "dtype", "sph_positions", "advance", "rollout",
           "step", "check_dt", "dem_dt", "sph_dt", "stable_dt", "substeps_for"]
