"""Robot and world models of repertoire.

All model files live beside this module and are referenced only as
``package://repertoire/<path>``. Call :func:`ConfigureParser` once on a
``pydrake.multibody.parsing.Parser`` to make those URIs resolve.
"""

from pathlib import Path

from repertoire.errors import RepertoireError

MODELS_DIR: Path = Path(__file__).resolve().parent
PACKAGE_NAME = "repertoire"


def ConfigureParser(parser) -> None:
    """Registers the ``repertoire`` package with a Drake Parser.

    Args:
        parser: a ``pydrake.multibody.parsing.Parser``. Safe to call twice.
    """
    package_map = parser.package_map()
    if not package_map.Contains(PACKAGE_NAME):
        package_map.AddPackageXml(str(MODELS_DIR / "package.xml"))


def package_url(relative_path: str) -> str:
    """Returns ``package://repertoire/<relative_path>`` after checking the file exists.

    Args:
        relative_path: path below ``models/``, e.g. ``"arm7/arm7.urdf"``.

    Raises:
        RepertoireError: if no such model file ships with repertoire.
    """
    path = MODELS_DIR / relative_path
    if not path.is_file():
        available = sorted(
            str(p.relative_to(MODELS_DIR))
            for p in MODELS_DIR.rglob("*")
            if p.suffix in (".urdf", ".sdf", ".xml") and p.name != "package.xml"
        )
        raise RepertoireError(
            f"model file '{relative_path}' not found under {MODELS_DIR}; "
            f"available models: {available}"
        )
    return f"package://{PACKAGE_NAME}/{relative_path}"


def model_path(relative_path: str) -> Path:
    """Absolute filesystem path of a model file (checked to exist)."""
    package_url(relative_path)
    return MODELS_DIR / relative_path
