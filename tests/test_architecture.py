"""The layers of docs/architecture.md: no module imports from a layer above its own."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).parents[1] / "shellform"

#: lowest first; a module may import from its own layer and those before it
LAYERS = [
    ("errors", "progress", "model", "geometry"),
    ("effects",),
    ("sparse_pattern", "upper_tangent", "assembly", "fingerprint"),
    ("solvers",),
    ("rods", "mra", "gridshell"),
    ("io",),
    ("scene",),
    ("analyses",),
    ("api", "studies", "hops", "validation", "cli", "__main__", "__init__"),
]
RANK = {name: k for k, names in enumerate(LAYERS) for name in names}


def top_level(parts) -> str:
    return parts[0][:-3] if parts[0].endswith(".py") else parts[0]


def imported(path: Path):
    """The top-level shellform module of every import in ``path``."""
    here = path.relative_to(PACKAGE).parts[:-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = list(here[: len(here) - (node.level - 1)])
            target = base + (node.module.split(".") if node.module else [node.names[0].name])
            yield target[0]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("shellform."):
            yield node.module.split(".")[1]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("shellform."):
                    yield alias.name.split(".")[1]


def test_every_module_has_a_layer():
    modules = {top_level(p.relative_to(PACKAGE).parts) for p in PACKAGE.rglob("*.py")}
    assert modules <= set(RANK), f"modules without a layer: {sorted(modules - set(RANK))}"


def test_no_module_imports_from_a_layer_above_its_own():
    upward = []
    for path in sorted(PACKAGE.rglob("*.py")):
        source = top_level(path.relative_to(PACKAGE).parts)
        for target in imported(path):
            if target in RANK and RANK[target] > RANK[source]:
                upward.append(f"{path.relative_to(PACKAGE.parent)} imports shellform.{target}")
    assert not upward, "\n".join(upward)
