"""The house's floors: no import, at module level or inside a function, runs up a floor.

core <- families (buckybot, beast, swarm, bumper) <- baselines and estimators <- evaluation <- training
<- command line. Every module under ``polyenvs/`` and ``baselines/`` is parsed with :mod:`ast` (nothing is
imported), so a function-level import that would hide a cycle is caught too.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FAMILIES = ("buckybot", "beast", "swarm", "bumper")

#: Floors, lowest first: module-name prefixes (the longest matching prefix decides).
CORE, FAMILY, BASELINES, EVALUATION, TRAINING, COMMANDS = range(6)
FLOORS: dict[str, int] = {
    "polyenvs": CORE,  # the package: registers the ids from the registry table
    "polyenvs.core": CORE,
    "polyenvs.registry": CORE,
    "polyenvs.errors": CORE,
    "polyenvs.limits": CORE,
    "polyenvs.files": CORE,
    "polyenvs.pool": CORE,
    **{f"polyenvs.{family}": FAMILY for family in FAMILIES},
    "baselines": BASELINES,
    "polyenvs.estimators": BASELINES,
    "polyenvs.evaluation": EVALUATION,
    "polyenvs.training": TRAINING,
    "polyenvs.cli": COMMANDS,
    "polyenvs.commands": COMMANDS,
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def floor_of(module: str) -> int | None:
    """The floor of ``module``, or ``None`` for a module outside the house (numpy, gymnasium, ...)."""
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        prefix = ".".join(parts[:n])
        if prefix in FLOORS:
            return FLOORS[prefix]
    return None


def imports_of(path: Path) -> list[tuple[int, str]]:
    """``(line, module)`` of every import in the file, wherever it stands (module level or inside a function)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found += [(node.lineno, imported_from(node.module, alias.name)) for alias in node.names]
    return found


def imported_from(package: str, name: str) -> str:
    """What ``from package import name`` imports: the submodule ``package.name`` where there is one (``from
    polyenvs.evaluation import charts``), else the package, whose ``__init__`` defines or re-exports ``name``."""
    folder = ROOT / package.replace(".", "/")
    is_submodule = (folder / name).is_dir() or (folder / f"{name}.py").is_file()
    return f"{package}.{name}" if is_submodule else package


MODULES = sorted(p for package in ("polyenvs", "baselines") for p in (ROOT / package).rglob("*.py"))


def family_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "polyenvs" and parts[1] in FAMILIES else None


def test_every_module_has_a_floor():
    assert [module_name(p) for p in MODULES if floor_of(module_name(p)) is None] == []


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_import_runs_up_a_floor(path: Path):
    source = module_name(path)
    floor = floor_of(source)
    upward = []
    for line, target in imports_of(path):
        target_floor = floor_of(target)
        if target_floor is None:
            continue
        if target_floor > floor:
            upward.append(f"{path.relative_to(ROOT)}:{line} imports {target}")
        elif floor == CORE and source.startswith("polyenvs.core") and not target.startswith("polyenvs.core"):
            upward.append(f"{path.relative_to(ROOT)}:{line}: polyenvs/core imports {target}")
        elif floor == FAMILY and target_floor == FAMILY and family_of(target) != family_of(source):
            upward.append(f"{path.relative_to(ROOT)}:{line}: one family imports another, {target}")
    assert upward == []


def _graph() -> dict[str, set[str]]:
    """module -> the house's modules it imports (a name resolved to its longest prefix that is a module; a package
    is its ``__init__``, so a package that re-exports a submodule imports it)."""
    names = {module_name(p) for p in MODULES}
    graph: dict[str, set[str]] = {}
    for path in MODULES:
        edges = graph.setdefault(module_name(path), set())
        for _, target in imports_of(path):
            parts = target.split(".")
            hit = next((".".join(parts[:n]) for n in range(len(parts), 0, -1) if ".".join(parts[:n]) in names), None)
            if hit is not None and hit != module_name(path):
                edges.add(hit)
    return graph


def test_no_import_cycles():
    """No module imports, at any level, one that imports it back: within a floor and a family too (the command line
    assembles its commands, no command imports it back), and through a package's ``__init__`` (``baselines``
    imports ``baselines.trained`` inside a function: nothing ``trained`` imports may import ``baselines``)."""
    graph = _graph()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(node: str) -> None:  # Tarjan's strongly connected components
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                cycles.append(" <-> ".join(sorted(component)))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    assert cycles == []
