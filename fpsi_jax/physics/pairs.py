"""The pair primitive: one gather of the neighbours' data and one sum over them.

Every SPH pair sum uses jax-md's Dense neighbour format: ``idx`` has one row per row
particle and K slots holding indices into the concatenation of the particle families
([fluid; boundary; structure] for SPH); the padding index is N, which :func:`gather` and
:func:`pairs` map to a dummy particle placed :data:`FAR` away, so every kernel term of a
padded slot is exactly zero. :class:`Pairs` is the geometry and kinematics of one list,
computed once a step and shared by the density and momentum passes; :func:`sum_neighbours`
sums any number of (rows, K) pair terms in one reduction.

Notation: x_ij = x_i − x_j, v_ij = v_i − v_j, h_ij = (h_i + h_j)/2 (K37: symmetric pairs),
∇_i W_ij = x_ij F_ij with F = (1/r) dW/dr (physics/kernels.py).
"""
from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

FAR = 1.0e6  # position of the padding particle: farther than any cut-off


def safe_sqrt(r2):
    """√r2 with a finite derivative at r2 = 0 (double-where: the derivative there is taken
    as 0, which is the one-sided limit for the kernel terms that use it)."""
    ok = r2 > 0
    return jnp.where(ok, jnp.sqrt(jnp.where(ok, r2, 1.0)), 0.0)


def norm2(d):
    """|d|² of (…, 2) vectors, written as d_x² + d_y²: XLA:CPU emits a sum over a last axis
    of 2 as a reduction of its own, which writes the (rows, K) result out to memory, where
    the components stay inside the loop of the pair terms that read them (the coupled and
    dam-break steps 6–37 % faster: docs/performance.md, *Where a step's time goes*)."""
    return dot2(d, d)


def dot2(a, b):
    """a·b of (…, 2) vectors in components, a_x b_x + a_y b_y (see :func:`norm2`)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def perp(n):
    """t = (−n_y, n_x): n rotated by +90°."""
    return jnp.stack([-n[..., 1], n[..., 0]], axis=-1)


class Pairs(NamedTuple):
    """Geometry and kinematics of the (row, neighbour-slot) pairs of one list, shared by the
    density pass and the momentum pass of a step."""

    idx: jax.Array      # (n_rows, K) neighbour indices, padding = N
    fluid_j: jax.Array  # (n_rows, K) neighbour is a fluid particle
    dx: jax.Array       # x_ij (n_rows, K, 2)
    r2: jax.Array       # |x_ij|²
    hij: jax.Array      # (h_i + h_j)/2
    w: jax.Array        # W_ij
    f: jax.Array        # F_ij = (1/r) dW/dr, so ∇_iW_ij = x_ij F_ij
    vij: jax.Array      # v_ij (n_rows, K, 2)
    m_j: jax.Array      # m_j
    rho_j: jax.Array    # ρ_j at the start of the step
    vol_j: jax.Array    # m_j/ρ_j, the neighbour's volume (divided once per particle)
    row0: Any = 0       # index of the first row (a traced scalar inside :func:`over_row_blocks`)
    rows: Any = None    # (n_rows,) the rows' particles where they are not a run (pairs_at)

    def own(self, a):
        """The rows' own entries of an all-particle array ``a``: a[row0 : row0 + rows], or
        a[rows] for the rows of :func:`pairs_at`."""
        if self.rows is not None:
            return a[self.rows]
        return rows_of(a, self.row0, self.idx.shape[0])


def rows_of(a, row0, rows: int):
    """a[row0 : row0 + rows]: a plain slice for a Python int row0, a dynamic slice for a
    traced one (inside :func:`over_row_blocks`)."""
    if isinstance(row0, int):
        return a[row0:row0 + rows]
    return jax.lax.dynamic_slice_in_dim(a, row0, rows, axis=0)


def take_rows(a, rows):
    """a[rows], or ``a`` itself when ``rows`` is None (every row)."""
    return a if rows is None else a[rows]


@jax.custom_jvp
def sum_neighbours(*terms):
    """Σ_j of several (rows, K) pair arrays at once: one variadic reduction over the
    neighbour axis, so XLA evaluates the pair terms in one loop instead of writing a
    stacked (rows, K, c) array first. Returns a tuple of (rows,) arrays.

    Its derivative is the plain per-term sum (the JVP rule below): JAX's own transpose of
    a variadic reduce fails when one output's cotangent is a symbolic zero (e.g. a
    gradient that does not depend on the XSPH sums)."""
    zero = tuple(jnp.zeros((), t.dtype) for t in terms)
    return jax.lax.reduce(tuple(terms), zero,
                          lambda a, b: tuple(x + y for x, y in zip(a, b)), (1,))


@sum_neighbours.defjvp
def _sum_neighbours_jvp(primals, tangents):
    return sum_neighbours(*primals), tuple(jnp.sum(t, axis=1) for t in tangents)


def gather(a, idx, fill=1.0):
    """a[idx] with the padding index N mapped to ``fill`` (a may be (N,) or (N, c))."""
    pad = jnp.full((1,) + a.shape[1:], fill, a.dtype)
    return jnp.concatenate([a, pad], axis=0)[idx]


def pairs(kern, n_fluid, x, v, h, m, rho, idx, row0=0) -> Pairs:
    """Pair geometry for the rows ``idx`` (particles row0 … row0 + idx.shape[0] − 1 of x):
    :func:`pair_table` of the particles, then :func:`pairs_of`."""
    return pairs_of(kern, n_fluid, pair_table(x, v, h, m, rho), idx, row0)


def pair_table(x, v, h, m, rho):
    """The (N + 1, 8) table [x, y, vx, vy, h, m, ρ, m/ρ] that :func:`pairs_of` gathers the
    neighbours from, with the padding row N far away so that W = F = 0 there. The volume
    m/ρ is divided once per particle and gathered: XLA:CPU keeps true divides (docs/design.md,
    *XLA:CPU flags*), about ten times a multiply, so a divide in every pair term is a large
    part of a pass (docs/performance.md). Built once per pass, outside its row blocks."""
    table = jnp.concatenate([x, v, h[:, None], m[:, None], rho[:, None], (m / rho)[:, None]],
                            axis=1)
    dummy = jnp.array([FAR, FAR, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0], dtype=table.dtype)[None]
    return jnp.concatenate([table, dummy], axis=0)


def pairs_of(kern, n_fluid, table, idx, row0=0) -> Pairs:
    """Pair geometry for the rows ``idx`` (particles row0 … row0 + idx.shape[0] − 1) from a
    :func:`pair_table`: one packed gather of the neighbours' rows."""
    return _pairs(kern, n_fluid, rows_of(table, row0, idx.shape[0]), table[idx], idx, row0)


def pairs_at(kern, n_fluid, table, rows, idx) -> Pairs:
    """Pair geometry of rows whose particles are ``rows`` (n,), any particles in any order,
    with the neighbours ``idx`` (n, K): term for term what :func:`pairs_of` gives those
    particles' own rows. The fluid's force on a structure is read this way, each
    fluid–structure pair a row of the fluid particle with the structure particle as its
    one neighbour (solver.stages.structure_reaction)."""
    return _pairs(kern, n_fluid, table[rows], table[idx], idx, 0, rows)


def _pairs(kern, n_fluid, own, nbr, idx, row0, rows=None) -> Pairs:
    """Pairs from the rows' own table entries ``own`` (n, 8) and their neighbours' ``nbr``
    (n, K, 8)."""
    dx = own[:, None, 0:2] - nbr[..., 0:2]
    r2 = norm2(dx)
    hij = 0.5 * (own[:, 4, None] + nbr[..., 4])
    w = kern.w(safe_sqrt(r2), hij)
    f = kern.grad_factor(r2, hij)
    vij = own[:, None, 2:4] - nbr[..., 2:4]
    return Pairs(idx, idx < n_fluid, dx, r2, hij, w, f, vij, nbr[..., 5], nbr[..., 6],
                 nbr[..., 7], row0, rows)


#: fewer blocks than this are done as one pass: below ~40k rows the arrays of all rows still
#: fit the cache well enough that the blocks' loop costs more than it saves (measured when
#: the pair passes still wrote (rows, K) arrays out and took blocks with the rebuild: dam
#: break, two cores, blocks of 1 024, interleaved chunks: 230–247 against 252–270 ns a
#: particle-step at 24k particles (20k fluid rows), 236 against 260 at 37k (32k rows); 291
#: against 275 at 53k (47k rows), 444 against 276 at 90k; docs/performance.md). The
#: rebuild's candidate pass uses it on a CPU; the pair passes only if Physics.pair_block
#: is set.
MIN_BLOCKS = 40


def over_row_blocks(fn, n_rows: int, block: int):
    """fn(row0, rows) → pytree of (rows, …) arrays, evaluated for all ``n_rows`` rows in
    blocks of ``block`` rows (a ``lax.map``), so that the (block, K) pair arrays of one
    block stay in cache instead of (n_rows, K) arrays streaming through memory
    (docs/performance.md, "Pair passes in row blocks"). The last block starts at
    n_rows − block and only its new rows are kept; the block is evened out to
    ⌈n_rows / ⌈n_rows / block⌉⌉ rows so that few rows are done twice. ``block`` 0, or
    fewer than :data:`MIN_BLOCKS` blocks of rows: one call fn(0, n_rows)."""
    if not block or n_rows < MIN_BLOCKS * block:
        return fn(0, n_rows)
    nb = -(-n_rows // block)
    block = -(-n_rows // nb)          # the fewest rows done twice in the last block
    starts = jnp.minimum(jnp.arange(nb, dtype=jnp.int32) * block, n_rows - block)
    out = jax.lax.map(lambda r0: fn(r0, block), starts)
    keep = n_rows - (nb - 1) * block

    def join(a):
        head = a[:-1].reshape(((nb - 1) * block,) + a.shape[2:])
        return jnp.concatenate([head, a[-1, block - keep:]], axis=0)
    return jax.tree_util.tree_map(join, out)
