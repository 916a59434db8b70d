"""Check sieve_mi/'s floor plan: no import circle, no upward import, no private import.

Usage: python tools/layering.py [--graph]; exit status 1 when a rule is broken (each one printed).

Every import counts, at module level or inside a function. The units of the floor plan, bottom
to top (a unit may import only units below it, or modules of its own):

    _version < errors < settings < options < parsing < backend < telemetry < workers < progress < optim
    < geometry < objectives < shaker < scene < authors_config
    < certify < motion < game < outputs < api < shake < cascade < testing < cli < __main__
    < __init__

Rules
-----
1. No circle: the module graph (every import, function-level included) has no cycle.
2. No upward import: a module imports no module of a unit above its own.
3. No private import: no ``from m import _name`` and no ``m._name`` on an imported module,
   for ``m`` another module of sieve_mi.
4. Every module declares ``__all__``, and a name imported from another module of sieve_mi is in
   that module's ``__all__`` (or is one of its submodules).
``--graph`` prints the module graph's edges instead.
"""

from __future__ import annotations

import ast
import pathlib
import sys

#: The floor plan, bottom to top: a module's unit is its top-level module or package.
UNITS = (
    "_version",
    "errors",
    "settings",
    "options",
    "parsing",
    "backend",
    "telemetry",
    "workers",
    "progress",
    "optim",
    "geometry",
    "objectives",
    "shaker",
    "scene",
    "authors_config",
    "certify",
    "motion",
    "game",
    "outputs",
    "api",
    "shake",
    "cascade",
    "testing",
    "cli",
    "__main__",
    "__init__",
)
PACKAGE = "sieve_mi"


def modules(root: pathlib.Path) -> dict[str, pathlib.Path]:
    """Dotted module name -> file, for every module of the package at ``root``."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def unit(module: str) -> str:
    """The floor-plan unit of a dotted module name (``sieve_mi`` itself is ``__init__``)."""
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def _resolve(name: str, known: dict) -> str | None:
    """The longest known module that ``name`` (a dotted name, maybe module.attribute) lies in."""
    while name:
        if name in known:
            return name
        name = name.rpartition(".")[0]
    return None


def imports(module: str, path: pathlib.Path, known: dict) -> list[tuple[str, int, str | None]]:
    """(imported module, line, private name or None) for every sieve_mi import in one file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    base = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found, aliases, names = [], {}, []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                target = _resolve(a.name, known)
                if target:
                    found.append((target, node.lineno, None))
                    aliases[a.asname or a.name.split(".")[0]] = target if a.asname else PACKAGE
        elif isinstance(node, ast.ImportFrom):
            src = node.module or ""
            if node.level:
                src = ".".join(base.split(".")[: len(base.split(".")) - node.level + 1] + [src])
                src = src.rstrip(".")
            if _resolve(src, known) is None:
                continue
            for a in node.names:
                sub = f"{src}.{a.name}"
                if sub in known:  # a submodule
                    found.append((sub, node.lineno, None))
                    aliases[a.asname or a.name] = sub
                else:
                    private = a.name.startswith("_") and not a.name.startswith("__")
                    found.append((_resolve(src, known), node.lineno, a.name if private else None))
                    if not private and _resolve(src, known) == src:
                        names.append((src, node.lineno, a.name))
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in aliases
            and node.attr.startswith("_")
            and not node.attr.startswith("__")
            and aliases[node.value.id] != module
        ):
            found.append((aliases[node.value.id], node.lineno, node.attr))
    return found, names


def exported(path: pathlib.Path) -> list[str] | None:
    """The literal ``__all__`` of a module, or None where it declares none."""
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(
            getattr(t, "id", "") == "__all__" for t in node.targets
        ):
            return list(ast.literal_eval(node.value))
    return None


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def check(root: pathlib.Path) -> tuple[list[str], dict[str, set[str]]]:
    """Every broken rule as one line, and the module graph."""
    known = modules(root)
    graph: dict[str, set[str]] = {m: set() for m in known}
    problems = []
    public = {m: exported(p) for m, p in known.items()}
    for module, path in known.items():
        if unit(module) not in UNITS:
            problems.append(f"{path}: unit {unit(module)!r} is not in the floor plan (UNITS)")
            continue
        if public[module] is None and path.name != "__main__.py":
            problems.append(f"{path}: declares no __all__")
        found, names = imports(module, path, known)
        for target, line, name in names:
            if target != module and public[target] is not None and name not in public[target]:
                problems.append(f"{path}:{line}: {name} is not in {target}.__all__")
        for target, line, private in found:
            if target == module:
                continue
            graph[module].add(target)
            own = UNITS.index(unit(module))
            if UNITS.index(unit(target)) > own:
                problems.append(
                    f"{path}:{line}: upward import of {target} ({unit(module)} < {unit(target)})"
                )
            if private:
                problems.append(f"{path}:{line}: private name {private} imported from {target}")
    for comp in cycles(graph):
        problems.append("import circle: " + " -> ".join(comp))
    return problems, graph


if __name__ == "__main__":
    here = pathlib.Path(__file__).resolve().parents[1] / PACKAGE
    problems, graph = check(here)
    if "--graph" in sys.argv:
        for m in sorted(graph):
            for t in sorted(graph[m]):
                print(f"{m} -> {t}")
    for p in problems:
        print(p)
    sys.exit(1 if problems else 0)
