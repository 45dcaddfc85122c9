"""The run's health record (fpsi_jax.model.state.Status): when the host must redo a chunk
with larger neighbour lists, and when it must diagnose the run instead."""
import jax.numpy as jnp
import pytest

from fpsi_jax.model.state import Status


@pytest.mark.parametrize("bad_step, overflow, h_exceeded, redo_step, expected", [
    (-1, True, False, 5, True),     # a plain overflow: regrow and redo
    (3, False, True, 4, False),     # bad at 3, h outgrew the cut-off at 3 (inexact from 4)
    (3, True, False, 3, True),      # bad in the very step whose list overflowed: redo
    (6, True, False, 5, True),      # bad after the overflow: maybe its consequence, redo
    (3, False, False, -1, False),   # bad, nothing overflowed: diagnose
])
def test_a_run_bad_before_its_lists_overflowed_is_diagnosed_not_regrown(
        bad_step, overflow, h_exceeded, redo_step, expected):
    st = Status.ok().replace(bad=jnp.asarray(bad_step >= 0), step=jnp.int32(bad_step),
                             overflow=jnp.asarray(overflow),
                             h_exceeded=jnp.asarray(h_exceeded),
                             redo_step=jnp.int32(redo_step))
    assert st.must_redo() is expected
