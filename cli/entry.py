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


def _raise_interruption(signum, frame) -> None:
    global _pending
    _pending = KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)
    raise _pending


def install_signal_handlers() -> None:
    """SIGINT raises KeyboardInterrupt, SIGTERM and SIGHUP :class:`Terminated`;
    each is remembered for :func:`unreported_interruption`. A signal the
    process was started with ignored (``nohup`` ignores SIGHUP, a shell's
    background job SIGINT) stays ignored."""
    for sig in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None and signal.getsignal(sig) in (signal.SIG_DFL, signal.default_int_handler):
            signal.signal(sig, _raise_interruption)


def main() -> None:
    """Run ``geoproc``: install the handlers, then load and run the command line."""
    install_signal_handlers()
    try:
        from geoproc_cli.main import main as run

        run()
    except KeyboardInterrupt as exc:  # while the modules load, or once a command's handling is over
        text, code = interruption_line(exc)
        sys.stderr.write(f"error: {text}\n")
        sys.exit(code)
