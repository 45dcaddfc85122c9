"""The package's layers import only downwards, and no two modules import each other.

    model → physics → solver → run → build → cases → cli        (calibrate on top)

Each physics module imports only ``model`` and the pair primitive ``physics.pairs``, never
another physics module; nothing in ``fpsi_jax`` imports the top-level ``calibrate``
package. Every import counts, including those inside functions.
"""
from __future__ import annotations

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
PKG = ROOT / "fpsi_jax"
LAYERS = {"model": 1, "physics": 2, "solver": 3, "run": 4, "build": 5, "cases": 6,
          "scenefile": 7, "cli": 8}


def module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, pathlib.Path]:
    return {module_name(p): p for p in PKG.rglob("*.py")}


def imports_of(name: str, path: pathlib.Path, known: set[str]) -> set[str]:
    """Modules of ``fpsi_jax`` or ``calibrate`` that ``name`` imports (anywhere in it)."""
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[:len(base) - node.level + (1 if is_pkg else 0)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            for a in node.names:
                sub = f"{mod}.{a.name}"
                out.add(sub if sub in known else mod)
    return {m for m in out if m.split(".")[0] in ("fpsi_jax", "calibrate")}


def layer(name: str) -> int:
    parts = name.split(".")
    if len(parts) == 1 or parts[1] == "_xla":
        return 0                      # the package root: it configures XLA, imports nothing
    return LAYERS[parts[1]]


def graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {n: imports_of(n, p, known) for n, p in mods.items()}


def test_every_module_has_a_layer():
    for name in modules():
        layer(name)


def test_layers_import_only_downwards():
    upward = [(a, b) for a, deps in graph().items() for b in deps
              if b.startswith("fpsi_jax") and layer(b) > layer(a)]
    assert upward == []


def test_physics_modules_import_only_the_model_and_the_pair_primitive():
    bad = [(a, b) for a, deps in graph().items() if a.startswith("fpsi_jax.physics.")
           for b in deps if b.startswith("fpsi_jax.physics")
           and b not in ("fpsi_jax.physics", "fpsi_jax.physics.pairs")]
    assert bad == []


def test_the_package_never_imports_calibrate():
    bad = [(a, b) for a, deps in graph().items() for b in deps if b.startswith("calibrate")]
    assert bad == []


def test_no_import_circle():
    g = graph()
    # a package's __init__ importing its own submodules is not a circle
    edges = {a: {b for b in deps if b in g and not b.startswith(a + ".")}
             for a, deps in g.items()}
    state, circles = {}, []

    def visit(n, path):
        state[n] = 1
        for m in edges[n]:
            if state.get(m) == 1:
                circles.append(path[path.index(m):] + [m])
            elif m not in state:
                visit(m, path + [m])
        state[n] = 2

    for n in sorted(edges):
        if n not in state:
            visit(n, [n])
    assert circles == []


def test_the_check_sees_an_upward_import(tmp_path):
    """The test itself: a physics module importing the solver is found."""
    bad = tmp_path / "fpsi_jax" / "physics" / "x.py"
    bad.parent.mkdir(parents=True)
    bad.write_text("from ..solver import step\nfrom . import sph\n")
    known = {"fpsi_jax.solver", "fpsi_jax.physics.sph"}
    global ROOT
    old, ROOT = ROOT, tmp_path
    try:
        deps = imports_of(module_name(bad), bad, known)
    finally:
        ROOT = old
    assert deps == {"fpsi_jax.solver", "fpsi_jax.physics.sph"}
    assert layer("fpsi_jax.solver") > layer("fpsi_jax.physics.x")
