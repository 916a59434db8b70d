"""Each package's ``__init__`` docstring and the README's layout table list exactly its modules."""

from __future__ import annotations

import ast
import pathlib
import re

import pytest
from helpers import REPO

ROOT = pathlib.Path(REPO) / "sieve_mi"
PACKAGES = sorted(p.parent.name for p in ROOT.glob("*/__init__.py"))


def modules(package: str) -> set[str]:
    """The modules of ``sieve_mi.<package>`` (its ``__init__`` aside)."""
    return {p.stem for p in (ROOT / package).glob("*.py")} - {"__init__"}


def docstring_modules(package: str) -> set[str]:
    """The names listed in the "Modules" section of the package's ``__init__`` docstring."""
    doc = ast.get_docstring(ast.parse((ROOT / package / "__init__.py").read_text(encoding="utf-8")))
    assert "\nModules\n-------\n" in doc, f"sieve_mi.{package}'s docstring has no Modules section"
    section = doc.split("\nModules\n-------\n", 1)[1]
    return set(re.findall(r"^([a-z_][a-z0-9_]*)$", section.split("\n\n", 1)[0], re.M))


def readme_table() -> dict[str, str]:
    """The README's layout table: each unit (``geometry/``, ``scene``, ...) -> its modules cell."""
    text = (pathlib.Path(REPO) / "README.md").read_text(encoding="utf-8")
    start = text.index("| unit | rule | modules |")
    rows = {}
    for line in text[start:].splitlines()[2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        for unit in re.findall(r"`([\w/]+)`", cells[0]):
            rows[unit] = cells[-1]
    return rows


def listed(cell: str) -> set[str]:
    """The module names a table cell lists: backticked names outside parentheses, before any dash."""
    cell = cell.split(" — ")[0]
    while re.search(r"\([^()]*\)", cell):
        cell = re.sub(r"\([^()]*\)", "", cell)
    return set(re.findall(r"`([a-z_][a-z0-9_]*)`", cell)) - {"__init__"}


@pytest.mark.parametrize("package", PACKAGES)
def test_package_docstring_lists_its_modules(package):
    assert docstring_modules(package) == modules(package)


def test_readme_table_has_every_top_level_module_and_package():
    top = {p.stem for p in ROOT.glob("*.py")} | {f"{p}/" for p in PACKAGES}
    assert set(readme_table()) == top


@pytest.mark.parametrize("package", PACKAGES)
def test_readme_table_lists_each_package_s_modules(package):
    assert listed(readme_table()[f"{package}/"]) == modules(package)
