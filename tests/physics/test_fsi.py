"""Fluid–structure coupling (fpsi_jax.physics.fsi, and the extrapolated wall pressure of
physics.boundary on the structure): hand-computed two- and three-particle values for each
method, read off the SPH evaluation the step runs (solver.stages.evaluate_fluid), the
reaction law on a random configuration, and a gradient check."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fpsi_jax.model.config import NeighborConfig, Physics
from fpsi_jax.model.options import FsiMethod
from fpsi_jax.model.params import Params, SphParams
from fpsi_jax.model.state import FluidState, FsiState, SolidState, State, Status
from fpsi_jax.physics import eos, fsi, kernels, pairs, sph
from fpsi_jax.solver import stages

pytestmark = pytest.mark.usefixtures("float64")


KERN = kernels.get("wendland")
H = 0.01
RHO0, C0, GAMMA = 1000.0, 20.0, 7.0
G = (0.0, -9.81)
OFF = dict(xsph=False, anticlump=False, variable_h=False, delta_sph=False,
           artificial_viscosity=False)


def _sp(mu=0.0, **kw):
    d = dict(rho0=RHO0, c0=C0, gamma=GAMMA, mu=mu, r_clump=0.01, dp=H / 1.25, eps_xsph=0.5,
             delta=0.1, alpha=0.0)
    d.update(kw)
    return SphParams(**{k: jnp.float64(v) for k, v in d.items()})


def _phys(nf, ns, method, **flags):
    nb = NeighborConfig(r_cut=2 * H, skin=0.0, origin=(-1.0, -1.0), box=(2.0, 2.0))
    return Physics(n_fluid=nf, n_boundary=0, neighbors=nb, fsi=FsiMethod(method),
                   n_structure=ns, **{**OFF, **flags})


def _dense(x, r_cut):
    """Brute-force Dense list (padding = N) over all particles."""
    n = x.shape[0]
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    rows = [[j for j in range(n) if j != i and d[i, j] < r_cut] for i in range(n)]
    k = max(1, max(len(r) for r in rows))
    return jnp.asarray([r + [n] * (k - len(r)) for r in rows])


def _state(xf, vf, rhof, m_f, xs, vs, acc_s, fs, idx):
    """A State with the fluid rows and the structure discs (one per structure particle) that
    evaluate_fluid reads; the disc quantities it does not read are zero."""
    nf, ns = xf.shape[0], xs.shape[0]
    z = jnp.zeros_like
    fluid = FluidState(x=xf, v=vf, rho=rhof, h=jnp.full(nf, H), mass=m_f, acc=z(xf),
                       xsph=z(xf))
    zs = jnp.zeros(ns)
    solid = SolidState(x=xs, v=vs, omega=zs, theta=zs, acc=acc_s, alpha=zs, radius=zs,
                       mass=zs, inertia=zs, fixed=jnp.zeros(ns, bool), f_ext=z(xs),
                       shear=jnp.zeros((ns, 1)), wall_shear=jnp.zeros((ns, 0)))
    return State(t=jnp.zeros(()), step=jnp.zeros((), jnp.int32), fluid=fluid, boundary=None,
                 nbrs=Neighbours(idx), status=Status.ok(), solid=solid, fsi=fs)


class Neighbours:
    """The one field of a neighbour list that evaluate_fluid reads."""

    def __init__(self, idx):
        self.idx = idx


def _evaluate(method, xf, vf, rhof, xs, vs, acc_s=None, mu=0.0, flags=None, sp=None,
              p_s=None, rho_s=None):
    """stages.evaluate_fluid with Δt = 0 (no drift): (ρ, h, a, δv_XSPH, boundary, FsiState),
    the fluid masses and the FsiState it started from."""
    nf, ns = xf.shape[0], xs.shape[0]
    phys = _phys(nf, ns, method, **(flags or {}))
    params = Params(gravity=G, sph=sp or _sp(mu)).as_arrays(jnp.float64)
    m_f = jnp.full(nf, RHO0 * (H / 1.25) ** 2)
    fs = FsiState(idx=jnp.arange(ns), mass=jnp.full(ns, RHO0 * 0.006 ** 2),
                  h=jnp.full(ns, H), rho=jnp.full(ns, RHO0) if rho_s is None else rho_s,
                  p=jnp.zeros(ns) if p_s is None else p_s, force=jnp.zeros((ns, 2)))
    idx = _dense(np.concatenate([xf, xs]), 2 * H)
    acc_s = jnp.zeros_like(jnp.asarray(xs)) if acc_s is None else acc_s

    @jax.jit          # one compiled program instead of ~100 eagerly dispatched primitives
    def update(params, xf, vf, rhof, xs, vs, acc_s, fs):
        new = stages.evaluate_fluid(phys, params,
                                    _state(xf, vf, rhof, m_f, xs, vs, acc_s, fs, idx), 0.0)
        f = new.fluid
        return f.rho, f.h, f.acc, f.xsph, new.boundary, new.fsi

    out = update(params, *(jnp.asarray(a) for a in (xf, vf, rhof, xs, vs)), acc_s, fs)
    return out, m_f, fs


def _p(rho):
    return float(eos.pressure(rho, RHO0, C0, GAMMA))


# --- hand-computed pair values -------------------------------------------------------------
def test_pressure_gradient_two_particles_matches_K40():
    """K40: F_{F←S} = −(m_F m_S/(ρ_F ρ_S)) P_F ∇W(x_F − x_S); the structure gets −F."""
    rho_f = 1010.0
    xf, xs = np.array([[0.0, 0.008]]), np.array([[0.0, 0.0]])
    (_, _, acc, _, _, fs), m_f, fs0 = _evaluate("pressure_gradient", xf, np.zeros((1, 2)),
                                                 np.array([rho_f]), xs, np.zeros((1, 2)))
    r = 0.008
    grad = np.array([0.0, r]) * float(KERN.grad_factor(r * r, H))   # ∇_F W(x_F − x_S)
    m_s = RHO0 * 0.006 ** 2
    f_on_fluid = -(float(m_f[0]) * m_s / (rho_f * RHO0)) * _p(rho_f) * grad
    np.testing.assert_allclose(float(m_f[0]) * (np.asarray(acc[0]) - G), f_on_fluid, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(fs.force[0]), -f_on_fluid, rtol=1e-12)
    assert f_on_fluid[1] > 0                      # pushes the fluid away from the structure


def test_stationary_uses_the_symmetric_term_with_the_structure_state():
    rho_f, p_s = 1005.0, 300.0
    xf, xs = np.array([[0.003, 0.006]]), np.array([[0.0, 0.0]])
    (_, _, acc, _, _, fs), m_f, _ = _evaluate("stationary", xf, np.zeros((1, 2)),
                                              np.array([rho_f]), xs, np.zeros((1, 2)),
                                              p_s=jnp.array([p_s]))
    dx = xf[0] - xs[0]
    grad = dx * float(KERN.grad_factor(dx @ dx, H))
    m_s = RHO0 * 0.006 ** 2
    a = -m_s * (_p(rho_f) / rho_f ** 2 + p_s / RHO0 ** 2) * grad
    np.testing.assert_allclose(np.asarray(acc[0]) - G, a, rtol=1e-12)
    np.testing.assert_allclose(float(fs.p[0]), p_s)            # stationary: unchanged
    np.testing.assert_allclose(np.asarray(fs.force[0]), -float(m_f[0]) * a, rtol=1e-12)


def test_pressure_approximation_matches_K41():
    rho = np.array([1004.0, 1012.0])
    xf = np.array([[0.004, 0.005], [-0.006, 0.004]])
    xs = np.array([[0.0, 0.0]])
    (_, _, _, _, _, fs), m_f, _ = _evaluate("pressure_approximation", xf, np.zeros((2, 2)),
                                            rho, xs, np.zeros((1, 2)))
    want = sum(_p(rho[k]) * float(KERN.w(np.linalg.norm(xf[k]), H)) * float(m_f[k]) / rho[k]
               for k in range(2))
    np.testing.assert_allclose(float(fs.p[0]), want, rtol=1e-12)
    np.testing.assert_allclose(float(fs.rho[0]),
                               float(eos.density(want, RHO0, C0, GAMMA)), rtol=1e-12)


def test_extrapolated_adds_the_hydrostatic_and_acceleration_terms():
    """Adami et al. 2012: P_S = (Σ P_F W + (g − a_S)·Σ ρ_F x_SF W)/Σ W; one fluid particle
    r above the structure: P_S = P_F + ρ_F (|g| + a_y) r with structure_acceleration on,
    P_F + ρ_F |g| r (the disc's acceleration left out) by default."""
    rho_f, r = 1003.0, 0.007
    xf, xs = np.array([[0.0, r]]), np.array([[0.0, 0.0]])
    for with_acc in (True, False):
        for a_y in (0.0, 4.0):
            (_, _, _, _, _, fs), _, _ = _evaluate(
                "extrapolated", xf, np.zeros((1, 2)), np.array([rho_f]), xs,
                np.zeros((1, 2)), acc_s=jnp.array([[0.0, a_y]]),
                flags={"structure_acceleration": with_acc})
            want = _p(rho_f) + rho_f * (9.81 + (a_y if with_acc else 0.0)) * r
            np.testing.assert_allclose(float(fs.p[0]), want, rtol=1e-12)


def test_structure_velocity_enters_continuity_and_viscosity():
    """A structure particle moving towards a fluid particle compresses it (K32) and drags
    it along (K36)."""
    xf, xs = np.array([[0.0, 0.006]]), np.array([[0.0, 0.0]])
    (rho1, _, acc1, _, _, _), _, _ = _evaluate("stationary", xf, np.zeros((1, 2)),
                                               np.array([RHO0]), xs, np.array([[0.3, 0.2]]),
                                               mu=1e-3)
    (rho0, _, acc0, _, _, _), _, _ = _evaluate("stationary", xf, np.zeros((1, 2)),
                                               np.array([RHO0]), xs, np.zeros((1, 2)), mu=1e-3)
    assert float(acc1[0, 0] - acc0[0, 0]) > 0            # dragged in +x by the moving wall
    np.testing.assert_allclose(float(rho1[0]), float(rho0[0]))   # dt = 0: no drift
    # the density rate: K32 with v_FS = v_F − v_S
    x = jnp.asarray(np.concatenate([xf, xs]))
    v = jnp.asarray([[0.0, 0.0], [0.3, 0.2]])
    pr = pairs.pairs(KERN, 1, x, v, jnp.full(2, H), jnp.full(2, 0.064), jnp.full(2, RHO0),
                     jnp.asarray([[1]]))
    dx = xf[0] - xs[0]
    want = RHO0 * 0.064 / RHO0 * (np.array([-0.3, -0.2]) @ dx) * float(
        KERN.grad_factor(dx @ dx, H))
    np.testing.assert_allclose(float(sph.continuity(jnp.asarray([RHO0]), pr)[0]), want,
                               rtol=1e-12)
    assert want > 0                                       # approaching: compresses


# --- reaction law --------------------------------------------------------------------------
def _random(seed=0, nf=40, ns=25):
    rng = np.random.default_rng(seed)
    xf = rng.uniform(0.0, 0.05, (nf, 2))
    xs = np.stack([rng.uniform(0.0, 0.05, ns), rng.uniform(-0.006, 0.0, ns)], axis=1)
    xf[:, 1] = np.abs(xf[:, 1]) * 0.4
    vf = rng.normal(0, 0.3, (nf, 2))
    vs = rng.normal(0, 0.2, (ns, 2))
    rho = rng.uniform(990.0, 1015.0, nf)
    return xf, vf, rho, xs, vs


@pytest.mark.parametrize("method", list(FsiMethod))
def test_force_on_structure_is_the_exact_reaction(method):
    """Σ_F m_F (a_F − g) + Σ_S F_S = 0 to round-off: the fluid–fluid pairs cancel by
    antisymmetry, the fluid–structure ones by construction (every term on)."""
    xf, vf, rho, xs, vs = _random()
    flags = dict(anticlump=True, artificial_viscosity=True, xsph=True, delta_sph=True)
    (_, _, acc, _, _, fs), m_f, _ = _evaluate(method, xf, vf, rho, xs, vs, mu=1e-3,
                                              flags=flags, sp=_sp(1e-3, alpha=0.1),
                                              p_s=jnp.full(xs.shape[0], 50.0))
    ma = np.asarray(m_f)[:, None] * (np.asarray(acc) - np.asarray(G))
    f = np.asarray(fs.force)
    scale = np.abs(ma).sum()
    assert np.abs(f).sum() > 1e-3 * scale                 # the structure does feel the fluid
    np.testing.assert_allclose(ma.sum(0) + f.sum(0), 0.0, atol=1e-12 * scale)


def test_reaction_sums_minus_mass_times_pair_acceleration_over_found_slots():
    """Structure particle 0 lists fluid in slots 0 and 2, particle 1 in slot 1 only (the rest
    padding): F_S = −Σ m_F a_{F←S} over the slots that hold fluid."""
    acc = jnp.asarray(np.arange(12, dtype=float).reshape(2, 3, 2))
    mass = jnp.asarray([[1.0, 5.0, 2.0], [7.0, 3.0, 9.0]])
    found = jnp.asarray([[True, False, True], [False, True, False]])
    out = fsi.reaction(acc, mass, found)
    np.testing.assert_allclose(np.asarray(out), [[-(0 + 2 * 4), -(1 + 2 * 5)],
                                                 [-3 * 8, -3 * 9]])


def test_gradient_of_structure_force_matches_finite_differences():
    """d(Σ F_S)/d c0 through the EOS and the extrapolated pressure, vs a central
    difference."""
    xf, vf, rho, xs, vs = _random(1)

    def total(c0, method):
        (_, _, _, _, _, fs), _, _ = _evaluate(method, xf, vf, rho, xs, vs, mu=1e-3,
                                              sp=_sp(1e-3, c0=c0))
        return jnp.sum(fs.force[:, 1])

    for method in ("pressure_gradient", "extrapolated"):
        g = float(jax.grad(total)(20.0, method))
        e = 1e-4
        fd = (float(total(20.0 + e, method)) - float(total(20.0 - e, method))) / (2 * e)
        assert abs(g) > 0
        np.testing.assert_allclose(g, fd, rtol=1e-6)
