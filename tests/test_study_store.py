"""Reading a study store where it lies: odd folder names, read-only folders."""

import contextlib
import os
import shutil
import sqlite3
import stat
import subprocess
from pathlib import Path

import pytest
from repertoire.studies.engine import run_study
from repertoire.studies.pendulum import smoke_config
from repertoire.studies.store import EpisodeStore, read_store

from repertoire.errors import RepertoireError

_FIELDS = ["value"]


def _fill(path: Path, seeds: range) -> EpisodeStore:
    """A store at ``path`` holding one row per seed (still open: the caller closes it)."""
    db = EpisodeStore.open(path, study="_s", config_json="{}", record_fields=_FIELDS)
    for seed in seeds:
        db.insert(seed, f'{{"value": {seed}}}', 0.5, "host:1", cpu_s=0.25)
    return db


@pytest.mark.parametrize("folder", ["run#2", "what?", "50%20done", "a b"])
def test_a_store_in_a_folder_named_with_uri_characters_reads_back(tmp_path, folder):
    store = tmp_path / folder / "episodes.sqlite"
    _fill(store, range(3)).close()
    before = sorted(tmp_path.rglob("*"))
    meta, rows = read_store(store)
    assert meta["study"] == "_s"
    assert [(r.seed, r.record_json, r.cpu_s) for r in rows] == [
        (0, '{"value": 0}', 0.25),
        (1, '{"value": 1}', 0.25),
        (2, '{"value": 2}', 0.25),
    ]
    # in a bare file: URI '#' or '?' ended the path: SQLite made and read an empty 'run';
    # a reader may leave the store's own -wal and -shm files, nothing else
    new = set(tmp_path.rglob("*")) - set(before)
    assert new <= {Path(f"{store}-wal"), Path(f"{store}-shm")}


@contextlib.contextmanager
def _read_only(folder: Path):
    """``folder`` made read-only for this process, even as root (skips where it cannot be)."""
    mode = folder.stat().st_mode
    folder.chmod(stat.S_IRUSR | stat.S_IXUSR)
    immutable = False
    try:
        if os.access(folder, os.W_OK):  # root ignores permission bits
            chattr = shutil.which("chattr")
            if chattr is None or subprocess.run([chattr, "+i", str(folder)]).returncode:
                pytest.skip("cannot make a folder read-only for this user")
            immutable = True
        yield folder
    finally:
        if immutable:
            subprocess.run([shutil.which("chattr"), "-i", str(folder)], check=True)
        folder.chmod(mode)


def test_a_store_in_a_read_only_folder_reads_back_and_nothing_is_written(tmp_path):
    folder = tmp_path / "archive"
    _fill(folder / "episodes.sqlite", range(4)).close()  # closed: no -wal left
    with _read_only(folder):
        meta, rows = read_store(folder / "episodes.sqlite")
        assert meta["study"] == "_s"
        assert [r.seed for r in rows] == [0, 1, 2, 3]
        assert sorted(p.name for p in folder.iterdir()) == ["episodes.sqlite"]


def test_a_read_only_store_with_rows_only_in_its_log_is_refused_not_read_short(tmp_path):
    live = tmp_path / "live" / "episodes.sqlite"
    db = _fill(live, range(5))  # open: its rows sit in the write-ahead log
    try:
        folder = tmp_path / "copy"
        folder.mkdir()
        shutil.copy(live, folder / "episodes.sqlite")
        shutil.copy(f"{live}-wal", folder / "episodes.sqlite-wal")
    finally:
        db.close()
    assert (folder / "episodes.sqlite-wal").stat().st_size > 0
    with _read_only(folder):
        with pytest.raises(RepertoireError) as err:
            read_store(folder / "episodes.sqlite")
    assert str(err.value) == (
        f"study store '{folder / 'episodes.sqlite'}' cannot be read in place: its folder is "
        "read-only and its write-ahead log 'episodes.sqlite-wal' holds rows not yet in the "
        "file; copy the store with its -wal file to a writable folder and read the copy"
    )
    meta, rows = read_store(folder / "episodes.sqlite")  # writable again: all five rows
    assert [r.seed for r in rows] == [0, 1, 2, 3, 4]


def test_a_run_with_its_store_in_a_read_only_folder_fails_first_naming_the_folder(tmp_path):
    folder = tmp_path / "archive"
    folder.mkdir()
    store = folder / "episodes.sqlite"
    sqlite3.connect(store).close()  # the file itself can be written, its folder cannot
    with _read_only(folder):
        with pytest.raises(RepertoireError) as err:
            run_study(
                "pendulum",
                smoke_config(),
                episodes=1,
                store=store,
                out_dir=tmp_path / "out",
                executor="inline",
                progress=False,
            )
    assert str(err.value).startswith(
        f"--store (store) '{store}': cannot write in folder '{folder}' (creating a file there "
        "failed: "
    )
    assert not (tmp_path / "out").exists()
