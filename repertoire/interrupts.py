"""Ctrl-C in the command line: one line ``interrupted``, exit code 130, whenever it comes.

Ctrl-C in a terminal sends SIGINT to the whole process group: the engine, the
multiprocessing fork server and the pool workers. Only the command's own
process takes it (:func:`interruptible`); the processes it starts inherit a
blocked SIGINT (:func:`sigint_blocked`). This module imports nothing heavy: the
command line's entry point uses it before anything else is imported.
"""

import _thread
import contextlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any, NoReturn

_INTERRUPTED = threading.Event()  # Ctrl-C came while interruptible() ran a command
_ACTIVE = threading.Event()  # interruptible() has its handler installed
_ACTIVE_LOCK = threading.Lock()
# Ctrl-C is held back while this module runs its top level: pydrake's core (C++) module
# sets up pydrake's log sink there, and an interrupt in that set-up makes it print a
# critical error with a Python stack straight to the terminal, where no filter reaches
_UNINTERRUPTIBLE = os.path.join("pydrake", "__init__.py")
DEFERRED_RETRY_S = 0.05  # how often a held-back Ctrl-C tries again


def _in_uninterruptible_import(frame: Any) -> bool:
    """Whether ``frame`` runs inside pydrake's package initialisation (its top level)."""
    while frame is not None:
        code = frame.f_code
        if code.co_name == "<module>" and code.co_filename.endswith(_UNINTERRUPTIBLE):
            return True
        frame = frame.f_back
    return False


def _interrupt_again() -> None:
    with _ACTIVE_LOCK:
        if _ACTIVE.is_set():
            _thread.interrupt_main(signal.SIGINT)


def _on_sigint(signum: int, frame: Any) -> None:
    _INTERRUPTED.set()
    if _in_uninterruptible_import(frame):  # taken once that import has finished
        retry = threading.Timer(DEFERRED_RETRY_S, _interrupt_again)
        retry.daemon = True
        retry.start()
        return
    raise KeyboardInterrupt


def check_interrupted() -> None:
    """Raises KeyboardInterrupt if Ctrl-C came while :func:`interruptible` runs a command.

    A KeyboardInterrupt that lands in pydrake's module initialisation comes out
    of it as an ImportError, which an import fallback may swallow: the run then
    went on as if there had been no Ctrl-C. Executors call this between seeds.
    """
    if _INTERRUPTED.is_set():
        raise KeyboardInterrupt


def _not_after_ctrl_c(record: logging.LogRecord) -> bool:
    return not _INTERRUPTED.is_set()


def interruptible(command: Callable[[], int]) -> int:
    """Runs a command-line command; Ctrl-C anywhere in it prints ``interrupted``, returns 130.

    In the main thread SIGINT is recorded (see :func:`check_interrupted`) as
    well as raised for as long as the command runs, so an interrupt that some
    library turned into another exception still ends the command as an
    interrupt, and one it swallowed stops the run at the next seed. One that
    comes while pydrake's package initialises is raised as soon as that has
    finished (an interrupt inside it prints pydrake's critical error and stack).

    Args:
        command: the command; returns its exit code.

    Returns:
        The command's exit code, or 130 when interrupted.

    Raises:
        Whatever the command raised, when there was no Ctrl-C.
    """
    main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGINT) if main else None
    install = previous is signal.default_int_handler
    _INTERRUPTED.clear()
    if install:
        signal.signal(signal.SIGINT, _on_sigint)
        _ACTIVE.set()
    # pydrake logs "Could not initialize pydrake: KeyboardInterrupt" with a stack when
    # Ctrl-C lands in its initialisation: after a Ctrl-C, "interrupted" says it all
    drake_log = logging.getLogger("drake")
    drake_log.addFilter(_not_after_ctrl_c)
    try:
        try:
            code = command()
        except BaseException as e:
            if not isinstance(e, KeyboardInterrupt) and not _INTERRUPTED.is_set():
                raise
            print("interrupted", file=sys.stderr)
            return 130
        return code  # a command that handles Ctrl-C itself (the live view) says how it ended
    finally:
        if install:
            with _ACTIVE_LOCK:  # no held-back Ctrl-C comes back after this
                _ACTIVE.clear()
            signal.signal(signal.SIGINT, previous)
        drake_log.removeFilter(_not_after_ctrl_c)
        _INTERRUPTED.clear()


def exit_process(code: int) -> NoReturn:
    """Ends a command-line process with ``code``; after an interrupt, at once.

    Python ends a process by SIGINT (exit status -2, not 130) once a
    KeyboardInterrupt has left code it ran for C (pydrake's module
    initialisation), even if that interrupt was then caught; its shutdown can
    also be interrupted again. An interrupted command has closed its pool and
    store already, so it flushes its output and exits with 130 here; the fork
    server and the resource tracker end when this process does.

    Args:
        code: the exit code.
    """
    if code != 130:
        raise SystemExit(code)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(130)


@contextlib.contextmanager
def sigint_blocked() -> Iterator[None]:
    """A context in which this thread blocks SIGINT; processes it starts inherit the block.

    The mask survives fork and exec, so a fork server started here never sees
    the Ctrl-C that reaches the whole process group, not even during its
    preload imports (an interrupt there left pydrake half imported in every
    worker), and neither do the workers it forks. A SIGINT that comes while
    the main thread blocks it is delivered when the context ends.
    """
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
