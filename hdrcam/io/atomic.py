"""Atomic, no-clobber file output.

Every output is written to a temporary name in its destination folder (``.NAME.XXXX.part``) and then
published under its final name without replacing anything: a hard link (which fails if the name exists),
or on file systems without hard links an exclusive create (O_EXCL) of the name followed by a rename onto
it. So a file that appears between a command's checks and its write (another run, another program) is
never touched; only ``overwrite=True`` replaces, and then by an atomic rename of a complete file, so the
old bytes stay whole until the new ones are complete (and an input hard-linked elsewhere keeps its bytes).

A failure of any kind - an exception, a full disk, SIGINT or SIGTERM (which ``hdrcam.cli.main`` turns into
an exception) - removes the temporary file, and never leaves a partial file under the final name. Creating
the temporary file, and publishing it then removing its temporary name, run with signals deferred
(:func:`hdrcam.interrupts.interrupts_deferred`), so a signal cannot fall between the two.
Operating-system errors raised while writing name the final path, not the temporary one.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from hdrcam.errors import OutputExistsError
from hdrcam.interrupts import interrupts_deferred

_NO_HARD_LINKS = {errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK, errno.ENOSYS}
TEMPORARY_SUFFIX = ".part"


def same_file_key(path: Path) -> str:
    """A key equal for two spellings of one destination (symbolic links and '..' resolved; never raises)."""
    return os.path.normcase(os.path.realpath(os.path.abspath(path)))


def check_writable(path: Path, *, overwrite: bool = False, inputs: Iterable[Path] = ()) -> Path:
    """Refuse an output that is one of ``inputs``, a folder, or that exists while ``overwrite`` is false."""
    path = Path(path)
    key = same_file_key(path)
    for source in inputs:
        if same_file_key(Path(source)) == key:
            raise OutputExistsError(f"{path} is also an input; choose another output path")
    if os.path.isdir(path):
        raise OutputExistsError(f"{path} is a folder where an output file is expected; give a file path")
    if not _regular_file_or_absent(path):  # --overwrite would put a file in place of /dev/null (as root)
        raise OutputExistsError(f"{path} is not a regular file (a device, pipe or socket), and an output is written "
                                "as a new file in its place; give a file path")
    if os.path.lexists(path) and not overwrite:
        raise OutputExistsError(f"{path} already exists; choose another output or pass --overwrite")
    check_destination_folder(path.parent)
    return path


def _regular_file_or_absent(path: Path) -> bool:
    """Whether ``path`` (a link: its target) is a regular file, or nothing yet (a dangling link included)."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:  # absent, a dangling link or a link loop: the checks and the write say what is wrong
        return True


def check_destination_folder(folder: Path) -> None:
    """Raise the OSError that writing into ``folder`` would meet, before any work: its nearest existing
    ancestor must be a folder this process may write to (the rest is created)."""
    ancestor = Path(os.path.abspath(folder))
    while not os.path.lexists(ancestor) and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not os.path.isdir(ancestor):
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(ancestor))
    if not os.access(ancestor, os.W_OK | os.X_OK):
        code = errno.EROFS if _read_only_file_system(ancestor) else errno.EACCES
        raise OSError(code, os.strerror(code), str(ancestor))


def _read_only_file_system(folder: Path) -> bool:
    try:
        return bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def check_outputs(paths: Iterable[Path], *, overwrite: bool = False, inputs: Iterable[Path] = ()) -> list[Path]:
    """Check all of one command's outputs before anything is written: no two of them the same file (e.g.
    sibling outputs derived from one stem), none an input, none existing unless ``overwrite``."""
    inputs, seen, checked = list(inputs), {}, []
    for path in map(Path, paths):
        key = same_file_key(path)
        if key in seen:
            raise OutputExistsError(f"{seen[key]} and {path} would be the same output file; rename an input "
                                    "or choose another output")
        seen[key] = path
        checked.append(check_writable(path, overwrite=overwrite, inputs=inputs))
    return checked


def check_outputs_of_inputs(outputs: Iterable[tuple[Path, Iterable[Path]]], *, overwrite: bool = False,
                            inputs: Iterable[Path] = ()) -> None:
    """:func:`check_outputs` for outputs named after their inputs, (input, its outputs) pairs: two inputs whose
    outputs would be one file (a.exr and a.png both writing OUT/a.exr) are named."""
    planned: dict[str, Path] = {}
    every = []
    for source, paths in outputs:
        for path in map(Path, paths):
            key = same_file_key(path)
            if key in planned:
                raise OutputExistsError(f"{source} is given twice" if planned[key] == source else
                                        f"{source} and {planned[key]} would both write {path}; rename one of them")
            planned[key] = source
            every.append(path)
    check_outputs(every, overwrite=overwrite, inputs=inputs)


@contextlib.contextmanager
def atomic_path(path: Path, *, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (same suffix); publish it as ``path`` when the body succeeds.

    Without ``overwrite`` the publication fails with OutputExistsError if ``path`` exists by then. The
    temporary file is removed on every failure. Parent folders are created.
    """
    with atomic_paths([path], overwrite=overwrite) as (temporary,):
        yield temporary


@contextlib.contextmanager
def atomic_paths(paths: Iterable[Path], *, overwrite: bool = False) -> Iterator[list[Path]]:
    """:func:`atomic_path` for several outputs of one command, published together once the body has written
    them all: a failure while writing any (a full disk, an interrupt) leaves none of them, and a failure while
    publishing removes those this call had published - unless ``overwrite``: those replaced a file, and the new
    one stays rather than leaving neither."""
    paths = [check_writable(Path(path), overwrite=overwrite) for path in paths]
    temporaries: list[Path] = []
    current = paths[0] if paths else None  # the output an OSError concerns
    try:
        with interrupts_deferred():  # a signal here is raised once temporaries names every file to remove
            for current in paths:
                _make_folder(current.parent)
                handle, temporary = tempfile.mkstemp(prefix=f".{current.stem[:80]}.",
                                                     suffix=f"{TEMPORARY_SUFFIX}{current.suffix[:20]}",
                                                     dir=current.parent)
                os.close(handle)
                temporaries.append(Path(temporary))
        # an error of the body names a temporary (the output it stands for), or no file: the output, if only one
        current = paths[0] if len(paths) == 1 else None
        yield list(temporaries)
        for current, temporary in zip(paths, temporaries):
            os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual mode
            _flush_to_disk(temporary)
        with interrupts_deferred():  # publish and remove the temporary names as one step
            _publish_all(temporaries, paths, overwrite)
            temporaries = []  # published: nothing left for the cleanup below
    except OSError as error:
        _name_the_output(error, dict(zip(map(str, temporaries), paths)), current)
        raise
    finally:
        with interrupts_deferred():  # a second signal here would leave the temporaries not yet removed
            for temporary in temporaries:
                with contextlib.suppress(OSError):
                    temporary.unlink(missing_ok=True)


def _publish_all(temporaries: list[Path], paths: list[Path], overwrite: bool) -> None:
    published: list[Path] = []
    try:
        for temporary, path in zip(temporaries, paths):
            _publish(temporary, path, overwrite)
            published.append(path)
            temporary.unlink(missing_ok=True)
    except BaseException:
        for path in published if not overwrite else ():
            with contextlib.suppress(OSError):
                path.unlink()
        raise


def _make_folder(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:  # a file (or a dangling link) where the folder belongs
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(folder)) from None


def _publish(temporary: Path, path: Path, overwrite: bool) -> None:
    if overwrite:
        os.replace(temporary, path)
        return
    try:
        os.link(temporary, path)
    except FileExistsError:
        raise _appeared(path) from None
    except OSError as error:
        if error.errno not in _NO_HARD_LINKS:
            raise
        try:  # claim the name exclusively, then move the complete file onto our own empty claim
            os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        except FileExistsError:
            raise _appeared(path) from None
        os.replace(temporary, path)


def _appeared(path: Path) -> OutputExistsError:
    return OutputExistsError(f"{path} appeared while it was being written (another run?); it was left as it is; "
                             "choose another output or pass --overwrite")


def _flush_to_disk(path: Path) -> None:
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _name_the_output(error: OSError, outputs_of_temporaries: dict[str, Path], current: Path | None) -> None:
    """Make an OSError raised while writing name the output the user asked for: the output of the temporary it
    names, else (naming no file) ``current``, the output last created or flushed (or the only one)."""
    path = outputs_of_temporaries.get(str(error.filename)) if error.filename is not None else current
    if path is not None:
        error.filename = str(path)
        if error.filename2 is not None and str(error.filename2) == str(path):
            error.filename2 = None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def move_without_clobbering(source: Path, target: Path) -> None:
    """Rename ``source`` to ``target`` in one folder, never over an existing file (OutputExistsError)."""
    with interrupts_deferred():  # never both names, nor neither
        _publish(Path(source), Path(target), overwrite=False)
        Path(source).unlink(missing_ok=True)


def write_bytes_atomic(path: Path, data: bytes, *, overwrite: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path, overwrite=overwrite) as temporary:
        temporary.write_bytes(data)
    return Path(path)


def write_text_atomic(path: Path, text: str, *, overwrite: bool = False) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return write_bytes_atomic(path, text.encode("utf-8"), overwrite=overwrite)
