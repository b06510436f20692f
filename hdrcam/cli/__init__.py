"""``hdrcam <command>``: the command line. Exit statuses follow :mod:`hdrcam.errors`: bad arguments exit 2 with
one line; failures a user can act on exit 1 with one line; a bug exits 3."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import traceback
import warnings

from hdrcam import __version__
from hdrcam.errors import EXIT_BUG, EXIT_FAILURE, EXIT_USAGE, HdrcamError, StepFailed, failure_message, one_line
from hdrcam.interrupts import termination_signals_raised


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are a single line (exit status 2)."""

    def error(self, message: str):
        self.exit(EXIT_USAGE, one_line(f"{self.prog}: error: {message} (see '{self.prog} --help')") + "\n")


# command -> the module under hdrcam.cli that registers it, in the order of ``hdrcam --help``. Only the module of
# the command being run is imported (all of them for ``hdrcam --help``); none imports torch before its run().
COMMAND_MODULES = {"psf": "psf_command", "fabricate": "fabricate_command", "capture": "capture_command",
                   "ingest": "ingest_command", "inspect": "inspect_command", "bad-pixels": "bad_pixels_command",
                   "fuse": "fuse_command",
                   "calibrate": "calibrate_command", "design": "design_command", "finetune": "design_command",
                   "evaluate": "evaluate_command", "simulate": "simulate_command", "reconstruct": "reconstruct_command",
                   "destreak": "destreak_command", "export": "export_command", "demo": "demo_command"}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of ``hdrcam``; with a known ``command``, registering only that command's module."""
    parser = OneLineParser(prog="hdrcam", description="Snapshot HDR imaging with a learned rank-1 diffractive "
                                                      "optical element (Sun et al., CVPR 2020).")
    parser.add_argument("--version", action="version", version=f"hdrcam {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="<command>", required=True)
    modules = [COMMAND_MODULES[command]] if command in COMMAND_MODULES else COMMAND_MODULES.values()
    for module in dict.fromkeys(modules):
        importlib.import_module(f"hdrcam.cli.{module}").register(commands)
    return parser


def main(argv: list[str] | None = None, *, step: str | None = None) -> int:
    """Run one command; the exit status follows the contract in :mod:`hdrcam.errors`. ``step``: this command is
    that step of another (``demo``): an interrupt is raised on, with the step's name, for the outer command to
    report under its own name."""
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(next((word for word in argv if not word.startswith("-")), None))
    try:
        with _stdout_guarded():
            try:
                arguments = parser.parse_args(argv)
            except SystemExit:  # --help or --version printed (or a usage error): a lost text is a failure too
                sys.stdout.flush()
                raise
    except StandardOutputError as error:
        _report(f"hdrcam: error: {error}")
        return EXIT_FAILURE
    warnings.formatwarning = lambda message, category, *rest: f"hdrcam: warning: {one_line(str(message))}\n"
    name = f"hdrcam {getattr(arguments, 'command_name', arguments.command)}"  # with its action, as usage errors say
    try:
        with termination_signals_raised(), _stdout_guarded():
            status = int(arguments.run(arguments) or 0)
            sys.stdout.flush()  # a full or closed stdout is a failure of this command, not of the interpreter
        return status
    except StepFailed as failure:  # the step has printed its own line
        return failure.status
    except KeyboardInterrupt as interrupt:
        return _interrupted(name, interrupt, step)
    except Exception as error:  # never a traceback for users; HDRCAM_DEBUG=1 shows it
        interrupt = _interrupt_behind(error)
        if interrupt is not None:  # an extension module's import turned the interrupt into an ImportError
            return _interrupted(name, interrupt, step)
        if _debugging():
            traceback.print_exc()
        message = failure_message(error)
        if message is not None:
            _report(f"{name}: error: {message}")
            return EXIT_FAILURE
        _report(f"{name}: internal error: {type(error).__name__}: {error} (a bug; please report it, with the "
                "traceback that HDRCAM_DEBUG=1 shows)")
        return EXIT_BUG


def _interrupted(name: str, interrupt: KeyboardInterrupt, step: str | None) -> int:
    """Report an interrupt in one line and return its exit status (128 + the signal's number); a step's
    interrupt is raised on to the command that runs it, so that the line names the command the user typed."""
    if step is not None:
        if getattr(interrupt, "step", None) is None:  # the innermost step names it
            interrupt.step = step
        raise interrupt
    number = getattr(interrupt, "signal_number", signal.SIGINT)
    where = f" in its step '{interrupt.step}'" if getattr(interrupt, "step", None) else ""
    _report(f"{name}: interrupted by {signal.Signals(number).name}{where}; outputs not finished were removed")
    return 128 + number


def _interrupt_behind(error: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (or :class:`hdrcam.errors.Interrupted`) behind an ImportError or SystemError, if its
    direct cause or context is one: a signal landing inside a C extension's initialisation surfaces that way.
    Any other error raised while an interrupt was handled (a full disk while cleaning up) is reported as
    itself."""
    if not isinstance(error, (ImportError, SystemError)):
        return None
    behind = error.__cause__ or error.__context__
    return behind if isinstance(behind, KeyboardInterrupt) else None


_DEBUG_OFF = ("", "0", "false", "no", "off")


def _debugging() -> bool:
    """Whether HDRCAM_DEBUG asks for tracebacks: any value but unset, empty, 0, false, no or off (any case)."""
    return os.environ.get("HDRCAM_DEBUG", "").strip().lower() not in _DEBUG_OFF


def _report(line: str) -> None:
    with contextlib.suppress(OSError):  # standard error closed as well (2>&1 | head): nowhere left to say it
        progress = sys.modules.get("tqdm")  # a progress bar may be on the line: tqdm clears it first
        if progress is not None:
            progress.tqdm.write(one_line(line), file=sys.stderr)
            sys.stderr.flush()
        else:
            print(one_line(line), file=sys.stderr, flush=True)


class StandardOutputError(HdrcamError):
    """Standard output cannot be written (a full device, a closed pipe)."""


_CLOSED_STDOUT = "cannot write to standard output (it is closed); redirect it to a file or /dev/null"


def require_standard_output() -> None:
    """Refuse, before any work, a command whose results go to a closed standard output (``>&-``): without this
    it would do all the work and write its files, then fail at its first print. (``capture`` and ``inspect``
    print before any work, which refuses the same way.) A full device or a reader that has gone shows only
    when written to, and is reported then."""
    stream = sys.stdout
    if stream is None or (isinstance(stream, _GuardedOutput) and stream._stream is None):
        raise StandardOutputError(_CLOSED_STDOUT)


class _GuardedOutput:
    """Wraps sys.stdout while a command runs: a failed write becomes a one-line StandardOutputError, and the
    descriptor then points at /dev/null so that the interpreter's own flush at exit cannot fail again."""

    def __init__(self, stream):
        self._stream = stream  # None when the process started with standard output closed

    def write(self, text: str) -> int:
        if self._stream is None:
            raise StandardOutputError(_CLOSED_STDOUT)
        try:
            return self._guarded(self._stream.write, text)
        except UnicodeEncodeError:  # a file name that is not valid in the terminal's encoding: escape it
            encoding = getattr(self._stream, "encoding", None) or "utf-8"
            return self._guarded(self._stream.write, text.encode(encoding, "backslashreplace").decode(encoding))

    def flush(self) -> None:
        if self._stream is not None:  # nothing was written to a closed standard output
            self._guarded(self._stream.flush)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)

    def _guarded(self, operation, *arguments):
        try:
            return operation(*arguments)
        except OSError as error:
            with contextlib.suppress(OSError, ValueError, AttributeError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, self._stream.fileno())
                os.close(devnull)
            if isinstance(error, BrokenPipeError):  # the reader has gone (| head): nothing for the user to fix
                raise StandardOutputError("standard output closed early (broken pipe: the program reading it "
                                          "has exited); stopped, files already written are kept") from None
            raise StandardOutputError(f"cannot write to standard output ({error.strerror or error}); "
                                      "redirect it to a file or device with room") from None


@contextlib.contextmanager
def _stdout_guarded():
    stream = sys.stdout
    sys.stdout = _GuardedOutput(stream)
    try:
        yield
    finally:
        sys.stdout = stream


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
