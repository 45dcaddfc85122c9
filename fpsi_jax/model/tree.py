"""A minimal frozen-dataclass pytree (fields are leaves unless marked static)."""
from __future__ import annotations

import dataclasses

import jax


def pytree_dataclass(cls=None, *, static=()):
    """Frozen dataclass registered as a JAX pytree. Fields named in ``static`` are metadata."""

    def wrap(c):
        c = dataclasses.dataclass(frozen=True)(c)
        names = [f.name for f in dataclasses.fields(c)]
        data = [n for n in names if n not in static]
        meta = [n for n in names if n in static]
        jax.tree_util.register_dataclass(c, data_fields=data, meta_fields=meta)
        c.replace = lambda self, **kw: dataclasses.replace(self, **kw)
        return c

    return wrap if cls is None else wrap(cls)
