"""SQLite storage of study episodes, and plain-data conversion of configs and records.

One row per seed, each written in its own transaction the moment its episode
finishes (WAL journal, ``INSERT OR IGNORE`` on ``PRIMARY KEY (seed)``), so a
SIGKILL loses at most the episodes in flight and never duplicates or corrupts a
row. A ``meta`` table holds the study name, the canonical JSON of the config,
its SHA-256 and the record's field names; opening a store with another config
is refused unless ``fresh=True``. Each row keeps the episode's wall time
``episode_s`` and CPU time ``cpu_s`` (NULL in stores written before it was
measured: the column is added when such a store is opened). A ``crashes``
table lists seeds whose episode killed its worker process (a seed may appear
once per run that tried it); such seeds have no episode row, so a rerun tries
them again.

Configs and records cross process boundaries and land in the store only as
plain data (JSON): :func:`to_plain` and :func:`from_plain` convert dataclasses
both ways using their type hints. Nothing is pickled.
"""

import contextlib
import dataclasses
import hashlib
import json
import os
import sqlite3
import time
import types
import typing
import urllib.parse
from pathlib import Path
from typing import Any

from repertoire.errors import RepertoireError

SCHEMA_VERSION = "1"
_CREATE_CRASHES = (
    "CREATE TABLE IF NOT EXISTS crashes (seed INTEGER NOT NULL, exitcode INTEGER, "
    "message TEXT NOT NULL, worker TEXT NOT NULL, finished_unix REAL NOT NULL)"
)


def to_plain(value: Any, path: str = "value") -> Any:
    """Converts a dataclass (recursively) to JSON-compatible plain data.

    Args:
        value: a dataclass instance, list, dict, scalar or numpy array/scalar.
        path: where ``value`` sits, for error messages.

    Raises:
        RepertoireError: a value that is not plain data (names the field).
    """
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: to_plain(getattr(value, f.name), f"{path}.{f.name}")
            for f in dataclasses.fields(value)
        }
    if isinstance(value, (list, tuple)):
        return [to_plain(v, f"{path}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise RepertoireError(f"{path} has a non-string key {k!r}; expected str keys")
            out[k] = to_plain(v, f"{path}.{k}")
        return out
    np = _numpy_if_loaded()
    if np is not None:
        if isinstance(value, np.ndarray):
            return to_plain(value.tolist(), path)
        if isinstance(value, np.generic):
            return value.item()
    raise RepertoireError(
        f"{path} has type {type(value).__name__}; expected float/int/str/bool, "
        "lists or dicts of those, or a dataclass"
    )


def _numpy_if_loaded():
    import sys

    return sys.modules.get("numpy")


def from_plain(tp: Any, value: Any, path: str = "value") -> Any:
    """Rebuilds a value of type ``tp`` from plain data made by :func:`to_plain`.

    Args:
        tp: the target type (a dataclass, ``list[X]``, ``dict[str, X]``,
            ``X | None``, float, int, str, bool, numpy.ndarray or Any).
        value: plain data.
        path: where ``value`` sits, for error messages.

    Raises:
        RepertoireError: the data does not fit the type.
    """
    if tp is Any or tp is None:
        return value
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise RepertoireError(f"{path}: expected a mapping for {tp.__name__}, got {value!r}")
        hints = typing.get_type_hints(tp)
        names = {f.name for f in dataclasses.fields(tp) if f.init}
        unknown = sorted(set(value) - names)
        if unknown:
            raise RepertoireError(
                f"{path}: unknown keys {unknown} for {tp.__name__}; expected {sorted(names)}"
            )
        kwargs = {k: from_plain(hints.get(k, Any), v, f"{path}.{k}") for k, v in value.items()}
        return tp(**kwargs)
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (list, typing.List):  # noqa: UP006
        if not isinstance(value, list):
            raise RepertoireError(f"{path}: expected a list, got {value!r}")
        item = args[0] if args else Any
        return [from_plain(item, v, f"{path}[{i}]") for i, v in enumerate(value)]
    if origin in (dict, typing.Dict):  # noqa: UP006
        if not isinstance(value, dict):
            raise RepertoireError(f"{path}: expected a mapping, got {value!r}")
        item = args[1] if len(args) == 2 else Any
        return {k: from_plain(item, v, f"{path}.{k}") for k, v in value.items()}
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return from_plain(arg, value, path)
            except RepertoireError as e:
                errors.append(str(e))
        raise RepertoireError(f"{path}: {value!r} fits none of {args}: {errors}")
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif tp is bool or tp is str:
        if isinstance(value, tp):
            return value
    elif getattr(tp, "__module__", "") == "numpy" and getattr(tp, "__name__", "") == "ndarray":
        import numpy as np

        return np.asarray(value, dtype=float)
    else:
        return value
    raise RepertoireError(f"{path}: expected {tp.__name__}, got {value!r}")


def canonical_json(plain: Any) -> str:
    """Canonical JSON text (sorted keys, no spaces) of plain data."""
    return json.dumps(plain, sort_keys=True, separators=(",", ":"))


def config_to_json(config: Any) -> str:
    """A study config (a dataclass) as the canonical JSON text stores and workers get."""
    return canonical_json(to_plain(config, "config"))


def config_from_json(config_type: type, config_json: str) -> Any:
    """The ``config_type`` instance that :func:`config_to_json` text stands for."""
    return from_plain(config_type, json.loads(config_json), "config")


def config_hash(config_json: str) -> str:
    """SHA-256 hex digest of a canonical config JSON text."""
    return hashlib.sha256(config_json.encode()).hexdigest()


def _flatten(plain: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(plain, dict):
        out: dict[str, Any] = {}
        for k, v in plain.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else k))
        return out
    return {prefix or "config": plain}


def describe_config_change(old_json: str, new_json: str) -> str:
    """Lists the fields that differ between two config JSON texts, one per clause."""
    old, new = _flatten(json.loads(old_json)), _flatten(json.loads(new_json))
    parts = []
    for key in sorted(set(old) | set(new)):
        a, b = old.get(key, "<absent>"), new.get(key, "<absent>")
        if a != b:
            parts.append(f"{key}: {a!r} -> {b!r}")
    return "; ".join(parts) if parts else "(no field differs)"


@dataclasses.dataclass
class StoredEpisode:
    """One stored row.

    Attributes:
        seed: the episode's seed.
        record_json: the record as JSON text.
        episode_s: wall time of run_episode measured by the engine.
        finished_unix: when the row was written (Unix time).
        worker: ``host:pid`` of the process that ran the episode.
        cpu_s: CPU time of run_episode in its process (None if not measured).
    """

    seed: int
    record_json: str
    episode_s: float
    finished_unix: float
    worker: str
    cpu_s: float | None = None


@dataclasses.dataclass
class StoredCrash:
    """One episode that killed its worker process.

    Attributes:
        seed: the episode's seed.
        exitcode: the worker's exit code (negative: killed by that signal).
        message: what the engine said about it.
        worker: ``host:pid`` of the process that died.
        finished_unix: when the crash was seen (Unix time).
    """

    seed: int
    exitcode: int | None
    message: str
    worker: str
    finished_unix: float


_EPISODE_COLUMNS = "seed, record, episode_s, finished_unix, worker, cpu_s"


class EpisodeStore:
    """An SQLite file holding the episodes of one study with one config.

    Use :meth:`open`; close with :meth:`close` (or as a context manager).
    """

    def __init__(self, path: Path, conn: sqlite3.Connection):
        self.path = path
        self._conn = conn

    @classmethod
    def open(
        cls,
        path: str | Path,
        *,
        study: str,
        config_json: str,
        record_fields: list[str],
        fresh: bool = False,
    ) -> "EpisodeStore":
        """Opens (or creates) the store at ``path`` for ``study`` with this config.

        Args:
            path: the SQLite file; parent folders are created.
            study: the study name.
            config_json: canonical JSON of the config.
            record_fields: field names of the study's record type.
            fresh: drop every stored episode and start afresh with this config.

        Raises:
            RepertoireError: the file is not a store, or holds another study,
                another config or another record layout and ``fresh`` is False.
        """
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            conn = sqlite3.connect(str(path), isolation_level=None, timeout=30.0)
            conn.execute("PRAGMA journal_mode=WAL")
            # WAL + NORMAL: a committed row survives any process crash (SIGKILL);
            # only an OS crash / power cut may lose the last commits.
            conn.execute("PRAGMA synchronous=NORMAL")
            rows = conn.execute("SELECT name FROM sqlite_master WHERE type='table'")
            tables = {r[0] for r in rows}
        except sqlite3.DatabaseError as e:
            raise RepertoireError(f"'{path}' is not a study store (SQLite said: {e})") from e
        store = cls(path, conn)
        try:
            store._init(tables, study, config_json, record_fields, fresh)
        except BaseException:
            conn.close()
            raise
        return store

    def _init(
        self, tables: set[str], study: str, config_json: str, record_fields: list[str], fresh: bool
    ) -> None:
        conn = self._conn
        if tables and not {"meta", "episodes"} <= tables:
            raise RepertoireError(
                f"'{self.path}' is an SQLite file but not a study store (tables {sorted(tables)})"
            )
        meta = self.meta() if tables else {}
        wanted = {
            "schema_version": SCHEMA_VERSION,
            "study": study,
            "config_json": config_json,
            "config_sha256": config_hash(config_json),
            "record_fields": json.dumps(record_fields),
        }
        hint = "pass --fresh (fresh=True) to start the store afresh"
        if tables and not meta and not fresh:
            n = self.count()
            if n:  # episodes of an unknown study and config: never wiped unasked
                raise RepertoireError(
                    f"store '{self.path}' holds {n} episodes but no meta (study, config); {hint}"
                )
        if meta and not fresh:
            if meta.get("study") != study:  # --fresh would wipe another study's data
                n = self.count()
                raise RepertoireError(
                    f"store '{self.path}' holds study '{meta.get('study')}', not '{study}' "
                    f"({n} episode{'' if n == 1 else 's'} of it); use another store path "
                    "(--store, or --out-dir for the default one); --fresh (fresh=True) "
                    "would discard them"
                )
            if meta.get("config_sha256") != wanted["config_sha256"]:
                change = describe_config_change(meta["config_json"], config_json)
                raise RepertoireError(
                    f"store '{self.path}' was filled with another config for study '{study}' "
                    f"(changed: {change}); {hint} or use another store path"
                )
            if meta.get("record_fields") != wanted["record_fields"]:
                raise RepertoireError(
                    f"store '{self.path}' holds records with fields {meta.get('record_fields')} "
                    f"but study '{study}' now returns {record_fields}; {hint}"
                )
            if meta.get("schema_version") != SCHEMA_VERSION:
                raise RepertoireError(
                    f"store '{self.path}' has schema version {meta.get('schema_version')}, "
                    f"this engine writes {SCHEMA_VERSION}; {hint}"
                )
            self._add_later_columns()
            return
        conn.execute("BEGIN IMMEDIATE")
        try:
            conn.execute(
                "CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)"
            )
            conn.execute(
                "CREATE TABLE IF NOT EXISTS episodes (seed INTEGER PRIMARY KEY, "
                "record TEXT NOT NULL, episode_s REAL NOT NULL, finished_unix REAL NOT NULL, "
                "worker TEXT NOT NULL, cpu_s REAL)"
            )
            conn.execute(_CREATE_CRASHES)
            conn.execute("DELETE FROM episodes")
            conn.execute("DELETE FROM crashes")
            conn.execute("DELETE FROM meta")
            wanted["created_unix"] = repr(time.time())
            conn.executemany("INSERT INTO meta (key, value) VALUES (?, ?)", wanted.items())
            conn.execute("COMMIT")
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        self._add_later_columns()

    def _add_later_columns(self) -> None:
        """Brings a store written by an older engine up to date (cpu_s, crashes)."""
        columns = {r[1] for r in self._conn.execute("PRAGMA table_info(episodes)")}
        if "cpu_s" not in columns:
            self._conn.execute("ALTER TABLE episodes ADD COLUMN cpu_s REAL")
        self._conn.execute(_CREATE_CRASHES)

    def seeds(self, first_seed: int, episodes: int) -> set[int]:
        """The stored seeds among ``first_seed .. first_seed + episodes - 1``."""
        rows = self._conn.execute(
            "SELECT seed FROM episodes WHERE seed >= ? AND seed < ?",
            (first_seed, first_seed + episodes),
        )
        return {r[0] for r in rows}

    def insert(
        self,
        seed: int,
        record_json: str,
        episode_s: float,
        worker: str,
        *,
        cpu_s: float | None = None,
    ) -> bool:
        """Writes one episode in its own transaction; never overwrites a stored seed.

        Returns:
            True if the row was new, False if the seed was already stored.
        """
        cur = self._conn.execute(
            f"INSERT OR IGNORE INTO episodes ({_EPISODE_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?)",
            (
                seed,
                record_json,
                float(episode_s),
                time.time(),
                worker,
                None if cpu_s is None else float(cpu_s),
            ),
        )
        return cur.rowcount == 1

    def record_crash(self, seed: int, exitcode: int | None, message: str, worker: str) -> None:
        """Notes that the episode of ``seed`` killed its worker (in its own transaction)."""
        self._conn.execute(
            "INSERT INTO crashes (seed, exitcode, message, worker, finished_unix) "
            "VALUES (?, ?, ?, ?, ?)",
            (seed, exitcode, message, worker, time.time()),
        )

    def crashes(self) -> list[StoredCrash]:
        """Every recorded crash, oldest first."""
        rows = self._conn.execute(
            "SELECT seed, exitcode, message, worker, finished_unix FROM crashes "
            "ORDER BY finished_unix, rowid"
        )
        return [StoredCrash(*r) for r in rows]

    def load(self, first_seed: int, episodes: int) -> list[StoredEpisode]:
        """The stored rows among the given seeds, sorted by seed."""
        rows = self._conn.execute(
            f"SELECT {_EPISODE_COLUMNS} FROM episodes WHERE seed >= ? AND seed < ? ORDER BY seed",
            (first_seed, first_seed + episodes),
        )
        return [StoredEpisode(*r) for r in rows]

    def count(self) -> int:
        """Number of stored episodes (all seeds)."""
        return self._conn.execute("SELECT COUNT(*) FROM episodes").fetchone()[0]

    def meta(self) -> dict[str, str]:
        """The meta table as a dict."""
        return dict(self._conn.execute("SELECT key, value FROM meta"))

    def close(self) -> None:
        """Closes the connection."""
        self._conn.close()

    def __enter__(self) -> "EpisodeStore":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _read_only_uri(path: Path, immutable: bool = False) -> str:
    """An SQLite URI that opens ``path`` read-only.

    The path is percent-encoded: in a bare ``file:`` URI a ``#`` or ``?`` in a folder
    name would end the path, and SQLite would open (and create) another file.
    """
    uri = "file:" + urllib.parse.quote(str(path.resolve()), safe="/") + "?mode=ro"
    return uri + "&immutable=1" if immutable else uri


def _connect_read_only(path: Path) -> sqlite3.Connection:
    """A read-only connection to the store at ``path``, also in a folder it cannot write.

    A store is in WAL mode, and reading one needs its ``-shm`` file next to it: in a
    folder that cannot be written (an archive, another user's results) without one,
    SQLite cannot open it. With no write-ahead log there (or an empty one) the file
    holds every committed row and nobody can be writing it, so it is read as immutable.

    Raises:
        sqlite3.DatabaseError: as SQLite raised it.
        RepertoireError: the folder is read-only and a write-ahead log holds rows
            not yet in the file.
    """
    try:
        conn = sqlite3.connect(_read_only_uri(path), uri=True, timeout=30.0)
        try:
            conn.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
        except BaseException:
            conn.close()
            raise
        return conn
    except sqlite3.OperationalError:
        wal = Path(f"{path}-wal")
        shm = Path(f"{path}-shm")
        if shm.exists() or os.access(path.parent, os.W_OK):  # not the read-only folder
            raise
        if wal.exists() and wal.stat().st_size > 0:
            raise RepertoireError(
                f"study store '{path}' cannot be read in place: its folder is read-only and "
                f"its write-ahead log '{wal.name}' holds rows not yet in the file; copy the "
                "store with its -wal file to a writable folder and read the copy"
            ) from None
    return sqlite3.connect(_read_only_uri(path, immutable=True), uri=True, timeout=30.0)


def read_store(path: str | Path) -> tuple[dict[str, str], list[StoredEpisode]]:
    """Reads a store without checking its config: (meta table, every row sorted by seed).

    Raises:
        RepertoireError: the file is missing or not a study store.
    """
    path = Path(path)
    if not path.is_file():
        raise RepertoireError(f"study store '{path}' does not exist")
    try:
        with contextlib.closing(_connect_read_only(path)) as conn:
            meta = dict(conn.execute("SELECT key, value FROM meta"))
            columns = {r[1] for r in conn.execute("PRAGMA table_info(episodes)")}
            cpu = "cpu_s" if "cpu_s" in columns else "NULL"  # older stores: not measured
            rows = conn.execute(
                "SELECT seed, record, episode_s, finished_unix, worker, "
                f"{cpu} FROM episodes ORDER BY seed"
            )
            episodes = [StoredEpisode(*r) for r in rows]
    except sqlite3.DatabaseError as e:
        raise RepertoireError(f"'{path}' is not a study store (SQLite said: {e})") from e
    return meta, episodes


def copy_store(src: str | Path, dst: str | Path) -> bool:
    """Copies the SQLite file ``src`` over ``dst`` with SQLite's backup API.

    The copy is consistent with ``src``'s write-ahead log, and ``dst`` (created or
    replaced) stays a valid SQLite file for its open connections. Used to put a store back
    when ``--fresh`` turns out to have nothing to replace it with.

    Returns:
        False when ``src`` is no SQLite file (nothing is copied).
    """
    try:
        with contextlib.closing(sqlite3.connect(str(src))) as a:
            with contextlib.closing(sqlite3.connect(str(dst))) as b:
                a.backup(b)
    except sqlite3.DatabaseError:
        return False
    return True
