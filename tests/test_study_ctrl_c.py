"""Ctrl-C at each start-up phase of a pool run: one line, exit 130, no process left.

Each case runs ``python -m repertoire study pendulum`` with a ``sitecustomize``
that pauses one kind of process (the engine, the fork server) inside
the import of one module (or, for ``logging.getLogger``, in the call pydrake's core
module makes while it initialises) until the test has sent SIGINT to the whole process
group, so the interrupt lands in that phase every time, whatever the machine's
load. (A fixed delay lands in a different phase on a loaded machine.)
"""

import logging
import os
import signal
import sqlite3
import textwrap
import time

import pytest
from conftest import group_alive, start_pool_study
from repertoire.studies.engine_pool import iter_inline
from repertoire.studies.store import read_store

from repertoire.interrupts import check_interrupted, interruptible

_PAUSE_HOOK = textwrap.dedent(
    """
    import os
    import sys
    import time

    _WHERE = os.environ.get("PAUSE_WHERE")
    _MODULE = os.environ.get("PAUSE_MODULE")
    _DIR = os.environ.get("PAUSE_DIR")


    def _role():  # the fork server runs `python -c`; its workers import no preloaded module
        return "forkserver" if sys.argv and sys.argv[0] == "-c" else "engine"


    def _pause():
        open(os.path.join(_DIR, f"paused-{os.getpid()}"), "w").close()
        go = os.path.join(_DIR, "go")
        deadline = time.monotonic() + 60.0
        while not os.path.exists(go) and time.monotonic() < deadline:
            time.sleep(0.02)


    class _Pause:
        busy = False

        def find_spec(self, name, path=None, target=None):
            if name != _MODULE or _Pause.busy:
                return None
            _Pause.busy = True
            try:
                if _role() == _WHERE:
                    _pause()
                return None
            finally:
                _Pause.busy = False


    def _pausing_get_logger(get_logger):
        def wrapper(name=None):  # pauses once: in the call an extension module's init makes
            if sys._getframe(1).f_code.co_name == "_call_with_frames_removed":
                logging.getLogger = get_logger
                if _role() == _WHERE:
                    _pause()
            return get_logger(name)

        return wrapper


    if _WHERE and _MODULE == "logging.getLogger" and _DIR:
        import logging

        logging.getLogger = _pausing_get_logger(logging.getLogger)
    elif _WHERE and _MODULE and _DIR:
        sys.meta_path.insert(0, _Pause())
    """
)


@pytest.mark.parametrize(
    ("where", "module"),
    [
        ("engine", "repertoire.cli"),  # the command line's own start-up imports
        ("engine", "repertoire.studies.pendulum"),  # study discovery: pydrake in the engine
        ("engine", "logging.getLogger"),  # pydrake's core (C++) initialisation, its log sink
        ("forkserver", "pydrake.multibody.plant"),  # the fork server's preload imports
    ],
)
def test_ctrl_c_at_each_start_up_phase_ends_the_run_with_one_line(tmp_path, where, module):
    hook = tmp_path / "hook"
    hook.mkdir()
    (hook / "sitecustomize.py").write_text(_PAUSE_HOOK)
    pause = tmp_path / "pause"
    pause.mkdir()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(hook), env.get("PYTHONPATH", "")) if p)
    env.update(PAUSE_WHERE=where, PAUSE_MODULE=module, PAUSE_DIR=str(pause))
    out = tmp_path / "out"
    proc = start_pool_study(400, out, tmp_path, env)
    try:
        deadline = time.monotonic() + 120.0
        while not any(pause.iterdir()):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, f"no {where} process imported {module}"
            time.sleep(0.02)
        os.killpg(proc.pid, signal.SIGINT)  # while that process waits in the import
        (pause / "go").touch()
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 130, err
        assert err.strip() == "interrupted", err
        for _ in range(50):  # the workers, fork server and resource tracker go too
            if not group_alive(proc.pid):
                break
            time.sleep(0.2)
        else:
            raise AssertionError("processes of the interrupted run are still alive")
    finally:
        if group_alive(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    store = out / "episodes.sqlite"
    if store.exists():  # created once the engine got that far: consistent, seeds unique
        try:
            _, rows = read_store(store)
        except sqlite3.OperationalError:  # created but not yet given its tables
            rows = []
        assert len({r.seed for r in rows}) == len(rows) < 400


@pytest.fixture(autouse=True)
def _terminal_sigint():
    """SIGINT's handler as in a terminal, also when the tests run with it ignored (nohup)."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def _swallowing_command(convert: bool):
    """A command in which Ctrl-C lands in code that turns it into an ImportError, or eats it."""

    def command() -> int:
        try:
            os.kill(os.getpid(), signal.SIGINT)  # delivered here, in the main thread
            time.sleep(5.0)  # the handler interrupts this at once
        except KeyboardInterrupt:
            if convert:  # as pydrake's module initialisation does, logging it first
                logging.getLogger("drake").critical("Could not initialize pydrake: ...")
                raise ImportError("cannot import name 'MultibodyPlant'") from None
        return 0

    return command


def test_an_interrupt_turned_into_another_error_still_ends_the_command(capsys, caplog):
    assert interruptible(_swallowing_command(convert=True)) == 130
    assert capsys.readouterr().err == "interrupted\n"
    assert caplog.records == []  # pydrake's log line about it is dropped
    logging.getLogger("drake").critical("no Ctrl-C: kept")
    assert [r.getMessage() for r in caplog.records] == ["no Ctrl-C: kept"]
    # the command's handler is gone, and with it the record of that Ctrl-C
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    check_interrupted()


def test_a_command_that_handles_ctrl_c_itself_says_how_it_ended(capsys):
    assert interruptible(_swallowing_command(convert=False)) == 0  # as the live view
    assert capsys.readouterr().err == ""


def test_an_interrupt_swallowed_before_a_pool_run_stops_it_before_its_first_seed(capsys):
    ran = []

    def command() -> int:
        _swallowing_command(False)()
        ran.extend(iter_inline("repertoire.studies.pendulum", "pendulum", "{}", [0, 1]))
        return 0

    assert interruptible(command) == 130
    assert ran == []
    assert capsys.readouterr().err == "interrupted\n"


def test_a_command_without_ctrl_c_keeps_its_code_and_its_errors():
    assert interruptible(lambda: 3) == 3
    with pytest.raises(ImportError, match="plain"):
        interruptible(_raise_import_error)


def _raise_import_error() -> int:
    raise ImportError("plain")


def test_ctrl_c_during_pydrakes_package_initialisation_waits_until_it_has_finished(
    tmp_path, capsys
):
    init = tmp_path / "pydrake" / "__init__.py"  # run as pydrake's top level would be
    code = compile(
        "import os, signal, time\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "time.sleep(0.3)  # not cut short: a held-back Ctrl-C\n"
        "steps.append('initialised')\n",
        str(init),
        "exec",
    )
    steps = []

    def command() -> int:
        exec(code, {"steps": steps})
        time.sleep(5.0)  # the held-back Ctrl-C interrupts this
        steps.append("not reached")
        return 0

    assert interruptible(command) == 130
    assert steps == ["initialised"]
    assert capsys.readouterr().err == "interrupted\n"
