"""The layering rule: each layer imports only the layers above it (README, DESIGN.md).

Layers, top to bottom: models, planning, systems, diagrams, studies. A module may import
its own layer and the layers above; an import of a lower layer (also one inside a
function) ties a reusable part to a consumer of it.
"""

import ast
from pathlib import Path

LAYERS = ["models", "planning", "systems", "diagrams", "studies"]
ROOT = Path(__file__).resolve().parents[1]


def _imported_modules(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name


def test_no_layer_imports_a_layer_below_it():
    wrong = []
    for rank, layer in enumerate(LAYERS):
        files = sorted((ROOT / layer).rglob("*.py"))
        assert files, f"no Python files under {layer}/"
        for path in files:
            for line, module in _imported_modules(ast.parse(path.read_text())):
                parts = module.split(".")
                if parts[0] == "repertoire" and len(parts) > 1 and parts[1] in LAYERS:
                    if LAYERS.index(parts[1]) > rank:
                        wrong.append(f"{path.relative_to(ROOT)}:{line} imports {module}")
    assert not wrong, "imports of a lower layer:\n" + "\n".join(wrong)
