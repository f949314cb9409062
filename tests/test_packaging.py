"""The distribution maps every subpackage under `repertoire` (DESIGN.md: no bare top-level)."""

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_subpackage_is_listed():
    setuptools = _pyproject()["tool"]["setuptools"]
    package_dir = setuptools["package-dir"]
    listed = set(setuptools["packages"])
    expected = set()
    for top, folder in package_dir.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder)
            if ".venv" in init.parts or "__pycache__" in init.parts:
                continue
            expected.add(".".join([top, *rel.parts]) if rel.parts else top)
    assert expected - listed == set(), f"add to pyproject packages: {sorted(expected - listed)}"
    # The rest are data-only packages (models, scenarios, configs): their folder holds files.
    for name in listed - expected:
        top, _, rest = name.partition(".")
        parent = ".".join([top, *rest.split(".")[:1]])
        folder = ROOT / package_dir[parent] / Path(*rest.split(".")[1:])
        assert folder.is_dir() and any(folder.iterdir()), f"listed but missing: {name}"
        assert name in setuptools["package-data"], f"data package {name} has no package-data"


def test_no_bare_top_level_packages():
    for name in _pyproject()["tool"]["setuptools"]["packages"]:
        assert name == "repertoire" or name.startswith("repertoire."), name


def test_models_package_xml_names_repertoire():
    text = (ROOT / "models" / "package.xml").read_text()
    assert "<name>repertoire</name>" in text


def test_every_diagram_module_imports():
    from repertoire.diagrams.registry import broken_modules, diagram_names

    assert broken_modules() == {}
    assert diagram_names()
