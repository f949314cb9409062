"""Study engine edge cases a new user meets: options another executor ignores, damaged stores."""

import json
import sqlite3

import pytest
from repertoire.studies.engine import load_records, run_study, study_main
from test_study_engine import ToyConfig, _kw, toy_studies  # noqa: F401  (toy_studies: fixture)

from repertoire.errors import RepertoireError

pytestmark = pytest.mark.usefixtures("toy_studies")  # the test-only studies of test_study_engine


@pytest.mark.parametrize(
    ("executor", "where"),
    [("inline", "one at a time in this process"), ("dask", "on the cluster")],
)
def test_workers_with_another_executor_than_the_pool_is_refused_not_ignored(
    tmp_path, capsys, executor, where
):
    # `-j 2 --executor dask` ran as if -j were not given, as --scheduler without dask is not.
    message = (
        "--workers (workers) is only used with --executor process (executor='process'); "
        f"--executor {executor} runs its episodes {where}"
    )
    extra = {"scheduler_address": "tcp://127.0.0.1:1"} if executor == "dask" else {}
    with pytest.raises(RepertoireError) as error:
        run_study("_toy", episodes=2, executor=executor, workers=2, **extra, **_kw(tmp_path))
    assert str(error.value) == message
    argv = ["_toy", "-n", "2", "--executor", executor, "-j", "2", "--no-progress"]
    argv += ["--scheduler", "tcp://127.0.0.1:1"] if executor == "dask" else []
    assert study_main(None, [*argv, "--out-dir", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err == f"error: {message}\n"
    assert list(tmp_path.iterdir()) == []
    if executor == "inline":  # one worker is what inline is
        result = run_study("_toy", episodes=2, executor="inline", workers=1, **_kw(tmp_path))
        assert (result.workers, result.n_run) == (1, 2)


def test_load_records_names_the_store_when_its_meta_is_damaged_or_its_config_drifted(tmp_path):
    # These were "unknown study 'None'", a bare KeyError 'config_json', and
    # "config: unknown keys [...]" without the store's name.
    run_study("_toy", ToyConfig(scale=4.0), episodes=2, executor="inline", **_kw(tmp_path))
    path = tmp_path / "s.sqlite"
    with sqlite3.connect(path) as db:
        old = dict(db.execute("SELECT key, value FROM meta"))["config_json"]
    drifted = json.dumps({**json.loads(old), "gain": 1.0})
    damages = [  # applied in turn, each on top of the last: (SQL, parameters, the error)
        (
            "UPDATE meta SET value = ? WHERE key = 'config_json'",
            (drifted,),
            f"store '{path}': its config no longer fits study '_toy' (ToyConfig): config: "
            "unknown keys ['gain'] for ToyConfig; expected ['offsets', 'scale']",
        ),
        (
            "DELETE FROM meta WHERE key = 'config_json'",
            (),
            f"store '{path}' has no config_json in its meta table, so its 2 episodes cannot "
            "be read as a study's records",
        ),
        (
            "DELETE FROM meta",
            (),
            f"store '{path}' has no study and no config_json in its meta table, so its 2 "
            "episodes cannot be read as a study's records",
        ),
    ]
    for sql, params, message in damages:
        with sqlite3.connect(path) as db:
            db.execute(sql, params)
        with pytest.raises(RepertoireError) as error:
            load_records(path)
        assert str(error.value) == message
