"""``fpsi validate``: run the registered validation cases and tabulate their records.

A case is a function ``(quick, overrides) -> list[Record]`` registered with
:func:`~fpsi_jax.cases.registry.validation` in its scene's module. Analytic references are
computed from the (possibly overridden) parameters, so ``--set`` checks a user's variant.
``quick`` is the coarse version the test suite runs; its resolution and tolerance are part
of the record (``params``), never hidden.
"""
from __future__ import annotations

from ..model.errors import ParameterError
from .registry import CASES, SCENE_OF, Record


def run(names=None, quick=False, overrides=None) -> list[Record]:
    """The records of the cases ``names`` (default: all), in order."""
    names = list(CASES) if not names else names
    for n in names:
        if n not in CASES:
            raise ParameterError(f"unknown validation case {n!r}; available: "
                                 f"{', '.join(CASES)}")
    for n in names:
        check_keys(n, overrides or {})
    out = []
    for n in names:
        out += CASES[n](quick=quick, overrides=dict(overrides or {}))
    return out


def check_keys(case: str, overrides: dict) -> None:
    """Every ``--set`` key must mean something to the scene of ``case`` (a builder keyword,
    a Params leaf, a Physics option or dt): checked for every selected case before any
    runs, so a key that fits only some of them is refused up front."""
    from ..model.config import Physics
    from . import registry
    scene = SCENE_OF[case]
    keys = set(registry.builder_keys(scene))
    params = None
    for k in overrides:
        if k in keys or k in Physics.OPTIONS or k == "dt":
            continue
        params = params or registry.build(scene).params
        try:
            params.resolve(k)
        except ParameterError:
            from .overrides import unknown_key
            raise unknown_key(k, f"the validation case {case!r} (scene {scene!r})", keys,
                              params, case) from None


def format_table(records) -> str:
    head = ("case", "quantity", "value", "reference", "rel_error", "tol", "pass", "wall_s")
    rows = [head] + [(r.case, r.quantity, f"{r.value:.5g}", f"{r.reference:.5g}",
                      f"{r.rel_error:.3%}", f"{r.tolerance:.2%}",
                      "PASS" if r.passed else "FAIL", f"{r.wall_s:.1f}") for r in records]
    widths = [max(len(str(r[i])) for r in rows) for i in range(len(head))]
    return "\n".join("  ".join(str(c).ljust(w) for c, w in zip(r, widths)) for r in rows)
