"""A benchmark's same-run peer: code run against the project as it was at a git revision.

The revision's tree is exported with ``git archive`` (from the repository the benchmark is
run from: a snapshot of the tree may run the benchmark) into a temporary folder laid out as
pyproject's package-dir, and ``code`` runs in a fresh Python that imports ``repertoire``
from there.
"""

import json
import os
import pathlib
import subprocess
import sys
import tempfile


def run_before(rev: str, code: str, *args: str, cwd: str | None = None):
    """Run ``code`` (``python -c``) with ``repertoire`` of ``rev``; returns its last line's JSON.

    Args:
        rev: a git revision of the repository at the current directory.
        code: the program; it prints its result as JSON on its last line.
        *args: its command-line arguments.
        cwd: where it runs (default: the temporary folder; the repository's root shares its
            ``out/`` caches, e.g. a recorded step library).
    """
    root = pathlib.Path.cwd()
    with tempfile.TemporaryDirectory() as tmp:
        src, pkg = pathlib.Path(tmp, "src"), pathlib.Path(tmp, "pkg", "repertoire")
        src.mkdir()
        archive = subprocess.run(
            ["git", "-C", str(root), "archive", rev], capture_output=True, check=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
        pkg.mkdir(parents=True)  # the package layout of pyproject's package-dir
        for f in (src / "repertoire").iterdir():
            (pkg / f.name).symlink_to(f)
        for sub in ("systems", "planning", "diagrams", "studies", "models"):
            (pkg / sub).symlink_to(src / sub)
        env = {**os.environ, "PYTHONPATH": str(pkg.parent)}
        out = subprocess.run(
            [sys.executable, "-P", "-c", code, *args],
            env=env, cwd=cwd or tmp, capture_output=True, text=True, check=True,
        )  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])
