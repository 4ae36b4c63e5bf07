"""Console-script entry point: Ctrl-C and termination signals become errors.

The command's modules (typer, rich, numpy) take a fraction of a second to
import; Ctrl-C in that time printed Python's traceback. Termination (SIGTERM,
as ``timeout`` and job schedulers send, and SIGHUP) killed the process with
its outputs still staged as temporary files beside their destinations. Here
both raise exceptions that the command's own handling turns into one error
line and an exit status of 128 plus the signal's number, after the staged
files are removed. This module imports nothing heavy.
"""

from __future__ import annotations

import importlib.abc
import signal
import sys


class Terminated(KeyboardInterrupt):
    """Raised by the SIGTERM / SIGHUP handler; a KeyboardInterrupt, so that every
    place that cleans up after Ctrl-C (staged outputs, numba's kernels, which
    re-raise it as a SystemError caused by it) does so for termination too.

    Attributes
    ----------
    signum : int
        The signal received.
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        """128 + the signal number, as a shell reports a process the signal killed."""
        return 128 + self.signum


_pending: KeyboardInterrupt | None = None
"""The last interruption a handler raised (:func:`install_signal_handlers`)
that no error line has reported yet (:func:`interruption_line`)."""


def interruption_line(exc: KeyboardInterrupt) -> tuple[str, int]:
    """The error line's text and the exit status for an interruption ``exc``,
    which is then no longer pending."""
    global _pending
    _pending = None
    if isinstance(exc, Terminated):
        return f"terminated ({signal.Signals(exc.signum).name})", exc.exit_code
    return "interrupted", 130


def unreported_interruption() -> KeyboardInterrupt | None:
    """A signal received that no error line reported: typer turns a Ctrl-C that
    arrives outside a command's body into a silent exit status of 130."""
    return _pending


_committed = False
"""Whether the running command's outputs are in place (:func:`outputs_committed`):
a terminating signal is then dropped."""


def _raise_interruption(signum, frame) -> None:
    global _pending, _deferred
    if _committed:
        return
    _pending = KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)
    if _deferring:  # an extension is loading: raised once it is (_SignalsDeferredLoader)
        _deferred = _deferred or _pending
        return
    raise _pending


def outputs_committed(done: bool = True) -> None:
    """The running command's outputs are in place (``done``; False when a
    command starts): until the next command starts, a terminating signal is
    dropped. The signals whose handler is :func:`install_signal_handlers`'
    are then ignored outright: Python's exit puts a Python handler back to
    the default action, which would kill a finished run (exit 143, no error
    line) in the time its exit still takes, but leaves an ignored signal
    ignored."""
    global _committed
    _committed = done
    for sig in _TERMINATING:
        if sig is None:
            continue
        try:
            if done and signal.getsignal(sig) is _raise_interruption:
                signal.signal(sig, signal.SIG_IGN)
                _ignored_when_done.add(sig)
            elif not done and sig in _ignored_when_done:
                signal.signal(sig, _raise_interruption)
                _ignored_when_done.discard(sig)
        except ValueError:  # not the main thread: the handler itself drops the signal
            pass


_ignored_when_done: set = set()
"""The signals :func:`outputs_committed` ignores until the next command starts."""


_TERMINATING = (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None))


def install_signal_handlers() -> None:
    """SIGINT raises KeyboardInterrupt, SIGTERM and SIGHUP :class:`Terminated`;
    each is remembered for :func:`unreported_interruption`. A signal the
    process was started with ignored (``nohup`` ignores SIGHUP, a shell's
    background job SIGINT) stays ignored. The handlers stay until the process
    ends (its exit included, where a signal after the outputs are in place is
    dropped); a program that runs commands in its own process calls
    ``geoproc_cli.main.main``, which installs none."""
    outputs_committed(False)
    for sig in _TERMINATING:
        if sig is not None and signal.getsignal(sig) in (signal.SIG_DFL, signal.default_int_handler):
            signal.signal(sig, _raise_interruption)


DEFERRED_IMPORTS = ("igl",)
"""Packages whose extension a signal must not interrupt while it loads: libigl's
nanobind module turns the exception a handler raises while it creates its
enumerations into a C++ exception that aborts the process (exit 134 and a
31-line traceback instead of the error line)."""

_deferring = 0
"""How many deferred imports are running: the handler then records the signal
(:data:`_deferred`) instead of raising."""
_deferred: KeyboardInterrupt | None = None


class _SignalsDeferredLoader(importlib.abc.Loader):
    """A module loader during which the terminating signals' handler only
    records what arrived; the interruption is raised once the module is loaded,
    in the code that imported it."""

    def __init__(self, loader):
        self.loader = loader

    def create_module(self, spec):
        with _interruptions_deferred():
            return self.loader.create_module(spec)

    def exec_module(self, module) -> None:
        with _interruptions_deferred():
            self.loader.exec_module(module)


class _interruptions_deferred:
    def __enter__(self) -> None:
        global _deferring
        _deferring += 1

    def __exit__(self, *exc) -> None:
        global _deferring, _deferred
        _deferring -= 1
        if not _deferring and _deferred is not None:
            pending, _deferred = _deferred, None
            raise pending


class _DeferSignalsFinder(importlib.abc.MetaPathFinder):
    """Finds the modules of :data:`DEFERRED_IMPORTS` through the other finders
    and gives them a :class:`_SignalsDeferredLoader`."""

    def find_spec(self, name, path, target=None):
        if name.partition(".")[0] not in DEFERRED_IMPORTS:
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(name, path, target)
            if spec is not None:
                if spec.loader is not None:
                    spec.loader = _SignalsDeferredLoader(spec.loader)
                return spec
        return None


def defer_signals_in_extension_imports() -> None:
    """Have the packages of :data:`DEFERRED_IMPORTS`, whenever first imported,
    load before a terminating signal is raised as an exception."""
    if not any(isinstance(f, _DeferSignalsFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _DeferSignalsFinder())


def main() -> None:
    """Run ``geoproc``: install the handlers, then load and run the command line."""
    install_signal_handlers()
    defer_signals_in_extension_imports()
    try:
        from geoproc_cli.main import main as run

        run()
    except KeyboardInterrupt as exc:  # while the modules load, or once a command's handling is over
        _exit_interrupted(exc)
    except Exception as exc:  # an import that wrapped the interruption (functools' __set_name__ does)
        stop = interruption_cause(exc)
        if stop is None:
            raise
        _exit_interrupted(stop)


def _exit_interrupted(exc: KeyboardInterrupt) -> None:
    text, code = interruption_line(exc)
    sys.stderr.write(f"error: {text}\n")
    sys.exit(code)


def interruption_cause(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C (or termination, :class:`Terminated`) that caused ``exc``, if
    any: numba's compiled functions re-raise a KeyboardInterrupt that arrives
    while they run as a SystemError caused by it, and Python 3.11 wraps one
    raised inside a descriptor's ``__set_name__`` (while a module loads) in a
    RuntimeError."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None
