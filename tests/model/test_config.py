"""The static configuration (fpsi_jax.model.config): Physics derived from a scene is
hashable and lists its mechanisms, bad options are refused before anything is compiled, and
the neighbour skin follows the time step. That switched-off mechanisms are absent from the
compiled step is tested in tests/solver/test_forward.py."""
import dataclasses

import numpy as np
import pytest

from fpsi_jax.model import motion
from fpsi_jax.model.config import Physics
from fpsi_jax.model.errors import ParameterError

from ..small_scenes import coarse_plate


def test_physics_is_hashable_and_lists_mechanisms(tiny_tank):
    a = Physics.for_scene(tiny_tank)
    b = Physics.for_scene(tiny_tank)
    assert hash(a) == hash(b) and a == b
    assert "sph.continuity" in a.mechanisms()
    assert "sph.delta" in Physics.for_scene(tiny_tank, delta_sph=True).mechanisms()


@pytest.mark.parametrize("opts, word", [
    ({"kernel": "gauss"}, "kernel"),
    ({"boundary_pressure": "magic"}, "boundary_pressure"),
    ({"h_margin": 5.0}, "h_margin"),
    ({"bogus": 1}, "bogus"),
    ({"coupling": "pressure_gradient"}, "'coupling' is the option 'fsi' here"),
    ({"pair_block": -1}, "pair_block"),
    ({"pair_block": 2.5}, "pair_block"),
    ({"rebuild_block": -1}, "rebuild_block"),
])
def test_bad_physics_options_are_refused(tiny_tank, opts, word):
    with pytest.raises((ParameterError, ValueError), match=word):
        Physics.for_scene(tiny_tank, **opts)


def test_disc_reaction_takes_held_discs_only():
    """Physics.disc_reaction lists held (clamped or kinematic) discs, sorted; a free disc,
    an index out of range or a bare number is refused with the allowed set."""
    sc = coarse_plate()
    fixed = np.flatnonzero(sc.solid.fixed)
    free = int(np.flatnonzero(~sc.solid.fixed)[0])
    got = Physics.for_scene(sc, disc_reaction=[int(fixed[1]), int(fixed[0])]).disc_reaction
    assert got == (int(fixed[0]), int(fixed[1]))
    for bad in ([free], [sc.solid.n], int(fixed[0])):
        with pytest.raises(ParameterError, match=r"disc_reaction = .*held at the start"):
            Physics.for_scene(sc, disc_reaction=bad)


def test_kinematic_motion_takes_motions_of_held_discs_only():
    """Plain 6-tuples become motion.Window; an Oscillation and a Track pass as given
    (their JSON lists read back by length); free discs, empty windows, a non-positive
    period and a track whose times do not increase are refused with what is wrong."""
    sc = coarse_plate()
    fixed = np.flatnonzero(sc.solid.fixed)
    a = int(fixed[0])
    w = Physics.for_scene(sc, kinematic_motion=[(a, a + 1, 0.0, 1.0, 0.1, float("inf"))])
    assert w.kinematic_motion == (motion.Window(a, a + 1, 0.0, 1.0, 0.1, float("inf")),)
    assert isinstance(w.kinematic_motion[0], motion.Window)
    osc = motion.Oscillation(a, a + 1, 0.01, 0.0, 0.5, 0.0, 0.2, 0.0, float("inf"))
    trk = motion.Track(a, a + 1, (0.0, 1.0), (0.0, 0.1), (0.0, 0.0))
    got = Physics.for_scene(sc, kinematic_motion=[osc, list(trk)]).kinematic_motion
    assert got == (osc, trk) and isinstance(got[1], motion.Track)
    free = int(np.flatnonzero(~sc.solid.fixed)[0])
    for bad, word in (([(free, free + 1, 0.0, 1.0, 0.0, 1.0)], "held discs"),
                      ([(a, a + 1, 0.0, 1.0, 0.2, 0.1)], "t_on < t_off"),
                      ([(a, a + 1, 0.0, 1.0)], "allowed"),
                      ([osc._replace(period=0.0)], "period > 0"),
                      ([trk._replace(t=(1.0, 0.5))], "strictly increasing")):
        with pytest.raises(ParameterError, match=r"kinematic_motion entry .*" + word):
            Physics.for_scene(sc, kinematic_motion=bad)


def test_neighbour_skin_follows_the_step():
    """0.4 h at the larger step of a scene without a fluid-coupled structure, 0.25 h with
    one (option fsi), which keeps physics.md's step."""
    sc = coarse_plate()
    assert sc.options.get("fsi") is not None
    bare = dataclasses.replace(sc, options={k: v for k, v in sc.options.items() if k != "fsi"})
    skin = lambda s: Physics.for_scene(s).neighbors.skin / float(np.max(s.fluid.h))
    assert skin(sc) == pytest.approx(0.25) and skin(bare) == pytest.approx(0.4)


def test_pair_passes_take_one_pass_and_the_rebuild_its_cpu_blocks(tiny_tank):
    """The pair passes run over all rows at once unless Physics.pair_block says otherwise;
    on a CPU the list rebuild runs in row blocks of CPU_REBUILD_BLOCK (``rebuild_block``,
    0: one pass), on an accelerator in one pass."""
    from fpsi_jax.model.config import CPU_REBUILD_BLOCK, default_rebuild_block
    import jax
    ph = Physics.for_scene(tiny_tank)
    want = CPU_REBUILD_BLOCK if jax.default_backend() == "cpu" else 0
    assert default_rebuild_block() == want
    assert ph.pair_block == 0 and ph.neighbors.row_block == want
    set_ = Physics.for_scene(tiny_tank, pair_block=256, rebuild_block=0)
    assert set_.pair_block == 256 and set_.neighbors.row_block == 0
