"""The package's layers: no import cycles, no upward imports, and the size rule.

Every ``import`` of a ``jaxproj`` module anywhere in a module counts, also one hidden inside a
function (that is how the old ``bvh <-> readers`` cycle hid). The layers, lowest first (a module
may import its own layer and the ones below):

0. ``errors``, ``_internal``
1. ``human``
2. ``robots``, ``io``
3. ``projection``
4. ``motion``
5. ``eval``, ``testing``, ``timing``
6. ``viz``
7. ``paper``
8. ``cli``

``jaxproj/__init__.py`` (the public surface) sits above all of them: only the application layers
(``viz``, ``paper``, ``cli``) may import it (for ``__version__`` and the public names).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from jaxproj import robots

PKG = Path(__file__).resolve().parents[1] / "jaxproj"

LAYERS: dict[str, int] = {
    "errors": 0, "_internal": 0, "human": 1, "robots": 2, "io": 2, "projection": 3, "motion": 4,
    "eval": 5, "testing": 5, "timing": 5, "viz": 6, "paper": 7, "cli": 8,
}  # fmt: skip
"""Top-level part of the package -> layer."""

MAX_LINES = 500
"""A module longer than this says why at its top (a line of its docstring starting 'Size:')."""


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The module a dotted import name refers to (the longest known prefix)."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        cand = ".".join(parts[:i])
        if cand in MODULES:
            return cand
    return None


def _imports(module: str) -> set[str]:
    tree = ast.parse(MODULES[module].read_text())
    found: set[str] = set()
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # ``from pkg import sub`` needs the module ``pkg.sub``; ``from mod import name``
            # needs ``mod`` (a package's parents are imported first in any case, not counted)
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                names.append(sub if sub in MODULES else node.module)
        elif isinstance(node, ast.ImportFrom) and node.level:
            raise AssertionError(f"{module}: relative import (use absolute jaxproj.* imports)")
        for n in names:
            if n == "jaxproj" or n.startswith("jaxproj."):
                target = _resolve(n)
                if target and target != module:
                    found.add(target)
    return found


GRAPH = {m: _imports(m) for m in MODULES}


def _layer(module: str) -> int | None:
    parts = module.split(".")
    return LAYERS.get(parts[1]) if len(parts) > 1 else None


def test_every_part_has_a_layer() -> None:
    parts = {m.split(".")[1] for m in MODULES if "." in m}
    assert parts <= set(LAYERS), f"parts without a layer: {sorted(parts - set(LAYERS))}"


def test_no_upward_imports() -> None:
    bad = []
    for m, targets in GRAPH.items():
        lm = _layer(m)
        if lm is None:
            continue
        for t in targets:
            lt = _layer(t)
            if lt is None:
                if t == "jaxproj" and lm < LAYERS["viz"]:
                    bad.append(f"{m} -> jaxproj (the public surface)")
            elif lt > lm:
                bad.append(f"{m} (layer {lm}) -> {t} (layer {lt})")
    assert not bad, "upward imports:\n" + "\n".join(sorted(bad))


def _cycles(graph: dict[str, set[str]]) -> list[str]:
    """Every cycle a depth-first walk of ``graph`` closes, as ``a -> b -> a``."""
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for t in sorted(graph.get(m, ())):
            if t == "jaxproj":
                continue
            if state.get(t) == 1:
                cycles.append(" -> ".join([*stack[stack.index(t) :], t]))
            elif t not in state:
                visit(t)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    return cycles


def test_no_import_cycles() -> None:
    cycles = _cycles(GRAPH)
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_the_checks_can_fail() -> None:
    """The cycle and layer checks see an import hidden inside a function, and find a cycle."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a -> b -> c -> a"]
    assert _cycles({"a": {"b"}, "b": set()}) == []
    tree = ast.parse("def f():\n    from jaxproj.cli import main\n")
    node = next(n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom))
    assert node.module == "jaxproj.cli" and _resolve(node.module) == "jaxproj.cli"
    assert _layer("jaxproj.cli") > _layer("jaxproj.io.readers")


@pytest.mark.parametrize("module", sorted(MODULES))
def test_module_size(module: str) -> None:
    text = MODULES[module].read_text()
    n = text.count("\n")
    if n <= MAX_LINES:
        return
    doc = ast.get_docstring(ast.parse(text)) or ""
    assert any(line.startswith("Size:") for line in doc.splitlines()), (
        f"{module}: {n} lines and no 'Size:' line in its docstring saying why"
    )


def _robot_words() -> tuple[str, ...]:
    """Every registered robot's name and its upper-case constant (``nao_h25``, ``NAO_H25``)."""
    return tuple(w for name in robots.names() for w in (name, name.upper()))


def _docstrings(tree: ast.AST) -> set[int]:
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            first = node.body[0] if node.body else None
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def _names_a_robot(source: str) -> list[str]:
    """Where ``source`` imports a robot's package (``jaxproj.robots.<name>``), refers to a
    robot's constant or names a registered robot in a string (docstrings and comments aside:
    prose may give a robot as an example)."""
    words = _robot_words()
    tree = ast.parse(source)
    docs = _docstrings(tree)
    found = []
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
        for name in robots.names():
            if any(n.startswith(f"jaxproj.robots.{name}") for n in names):
                found.append(f"line {node.lineno}: imports jaxproj.robots.{name}")
        ident = node.id if isinstance(node, ast.Name) else getattr(node, "attr", None)
        if isinstance(node, (ast.Name, ast.Attribute)) and ident in words:
            found.append(f"line {node.lineno}: refers to {ident}")
        text = node.value if isinstance(node, ast.Constant) else None
        if isinstance(text, str) and id(node) not in docs and any(w in text for w in words):
            found.append(f"line {node.lineno}: names a robot in {text[:40]!r}")
    return found


def test_no_module_above_robots_names_a_robot() -> None:
    """Above ``robots/`` a robot comes from the caller, a model, a motion or the registry
    (``robots.get``): no import of a robot's package, no robot constant as a default, no
    robot's name in code (issues 44, 58). Every registered robot counts."""
    probe = (
        "from jaxproj.robots import nao_h25\n"
        "def f(robot=robots.UNITREE_G1, name='unitree_g1'):\n"
        '    """the NAO, nao_h25, in prose"""\n'
    )
    assert len(_names_a_robot(probe)) == 3
    bad = [
        f"{m} {where}"
        for m, path in MODULES.items()
        if m != "jaxproj.robots" and not m.startswith("jaxproj.robots.")
        for where in _names_a_robot(path.read_text())
    ]
    assert not bad, "modules above robots/ that name a robot:\n" + "\n".join(bad)
