"""A training run's file options (``--psf``, ``--init``, ``--profile``, ``--data``) as its config.json records them,
and whether a resume names the same files.

A run records an existing file by its absolute path and ``--data`` by its folders' absolute paths, so a resume
from another folder finds them; a resume compares what the options name, not how they are spelled: a relative
path from another folder, an absolute one, or a byte-identical copy moved with the run all name the same file.
"""

from __future__ import annotations

from pathlib import Path


def recorded_file(value: str | Path | None) -> str | None:
    """A file option as the run records it: an existing file's absolute path, else the value as given (a name
    such as dirac, or None)."""
    if value is None:
        return None
    return str(Path(value).resolve()) if Path(value).is_file() else str(value)


def recorded_data(data: str | None) -> str | None:
    """``--data`` as a run records it: its folders by absolute path (hdrcam.data.scenes.absolute_mixture)."""
    from hdrcam.data.scenes import absolute_mixture

    return None if data is None else absolute_mixture(data)


def same_file(saved: str | None, wanted: str | None) -> bool:
    """Whether two spellings of a file option name the same file: equal, resolving to one path, or two files of
    identical bytes (a copy moved with its run)."""
    if saved == wanted:
        return True
    if saved is None or wanted is None or not Path(wanted).is_file():
        return False
    if Path(saved).is_file():
        return Path(saved).resolve() == Path(wanted).resolve() or Path(saved).read_bytes() == Path(wanted).read_bytes()
    return False


def moved_file(saved: str | None, wanted: str | None, names: tuple[str, ...] = ()) -> bool:
    """Whether a run's file is gone from where it was and another file is given in its place (``names``: values
    that name no file, such as the fixed PSFs' names)."""
    files = [value for value in (saved, wanted) if value is not None and value not in names]
    return len(files) == 2 and not Path(saved).is_file() and Path(wanted).is_file()
