"""List functions in sieve_mi/ longer than a limit (default 80 lines, docstring included).

Usage: python tools/long_functions.py [LIMIT]; exit status 1 when any is found.
"""

from __future__ import annotations

import ast
import pathlib
import sys


def long_functions(root: pathlib.Path, limit: int) -> list[tuple[str, str, int]]:
    """(file, qualified name, lines) of every function over ``limit`` lines under ``root``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text())
        stack = [(tree, "")]
        while stack:
            node, prefix = stack.pop()
            for child in ast.iter_child_nodes(node):
                name = getattr(child, "name", None)
                if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                    n = child.end_lineno - child.lineno + 1
                    if n > limit:
                        found.append((str(path), prefix + name, n))
                if name is not None:
                    stack.append((child, prefix + name + "."))
    return found


if __name__ == "__main__":
    limit = int(sys.argv[1]) if len(sys.argv) > 1 else 80
    rows = long_functions(pathlib.Path(__file__).resolve().parents[1] / "sieve_mi", limit)
    for path, name, n in rows:
        print(f"{path}: {name} {n} lines")
    sys.exit(1 if rows else 0)
