"""Bad-pixel lists in dcraw's format (``dcraw -P FILE``, LibRaw's ``bad_pixels``, rawpy.enhance), and their repair.

A list names sensor defects - hot pixels that read bright without light, dead ones that read dark in it - so that
a frame's reconstruction does not take them for light: one pixel per line, ``COLUMN ROW UNIX_TIME`` (whole
numbers; text after ``#`` is a comment), columns and rows counted from 0 at the top-left of the visible RAW area,
in the sensor's orientation (the PSF's; not turned by the EXIF Orientation). A pixel counts for frames taken at
or after its UNIX_TIME, the moment it was found dead (0: always), as dcraw applies it. hdrcam writes UNIX_TIME 0
(``hdrcam bad-pixels``).

Repair, as dcraw's: each listed sample becomes what its same-colour neighbours read - in a Bayer mosaic the eight
samples two pixels away (the median of those not themselves listed), in a demosaiced frame the eight pixels
around it, per channel. A demosaiced frame (EXR, TIFF) repaired so is a second best: the demosaicing already
spread the defect's value into its neighbours, so a list is best applied to the RAW file.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from pathlib import Path

import numpy as np

from hdrcam.errors import InputError
from hdrcam.io.atomic import write_text_atomic


@dataclasses.dataclass(frozen=True)
class BadPixelList:
    """The pixels of a list file: ``rows``, ``columns`` (int64, sensor orientation, from 0) and ``since_unix_s``,
    the UNIX time (s) from which each is bad (0: always)."""

    path: Path
    rows: np.ndarray
    columns: np.ndarray
    since_unix_s: np.ndarray

    def __len__(self) -> int:
        return int(self.rows.size)

    def mask(self, shape: tuple[int, int], taken: dt.datetime | None = None) -> np.ndarray:
        """H x W bool: the listed pixels bad for a frame of ``shape`` taken at ``taken`` (None: an unknown time,
        every listed pixel); InputError naming the list when a pixel lies outside the frame (a list for
        another camera, or for the frame turned upright)."""
        height, width = shape
        outside = (self.rows >= height) | (self.columns >= width)
        if outside.any():
            first = int(np.flatnonzero(outside)[0])
            raise InputError(f"{self.path}: {int(outside.sum())} of its {len(self)} bad pixels lie outside the "
                             f"{width} x {height} frame (the first at column {self.columns[first]}, row "
                             f"{self.rows[first]}): a list for another camera, or for the frame turned upright?")
        bad = np.zeros(shape, bool)
        applies = np.ones(len(self), bool) if taken is None else self.since_unix_s <= taken.timestamp()
        bad[self.rows[applies], self.columns[applies]] = True
        return bad


def read_bad_pixels(path: str | Path) -> BadPixelList:
    """A dcraw bad-pixel list; InputError (one line, naming the file and line) for a missing or malformed file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path} does not exist") from None
    except IsADirectoryError:
        raise InputError(f"{path} is a folder, not a bad-pixel list") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a bad-pixel list (binary data; expected lines 'COLUMN ROW UNIX_TIME')") from None
    entries = []
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        try:
            column, row, since = (int(word) for word in words)
        except ValueError:  # not three whole numbers
            raise InputError(f"{path}, line {number}: {line.strip()[:60]!r} is not 'COLUMN ROW UNIX_TIME' (three "
                             "whole numbers; dcraw's bad-pixel format)") from None
        if column < 0 or row < 0:
            raise InputError(f"{path}, line {number}: negative column or row ({column} {row})")
        entries.append((row, column, since))
    rows, columns, since_unix_s = np.asarray(entries, np.int64).reshape(-1, 3).T
    return BadPixelList(path, rows, columns, since_unix_s)


def write_bad_pixels(path: str | Path, bad: np.ndarray, *, comment: str = "", overwrite: bool = False) -> Path:
    """Write the True pixels of the H x W bool ``bad`` as a dcraw list (UNIX_TIME 0), atomically, row by row;
    ``comment``: a header line (what found them)."""
    rows, columns = np.nonzero(bad)
    header = f"# hdrcam bad-pixel list: COLUMN ROW UNIX_TIME (dcraw's format); {len(rows)} pixels\n"
    if comment:
        header += f"# {comment}\n"
    body = "".join(f"{column} {row} 0\n" for row, column in zip(rows.tolist(), columns.tolist()))
    return write_text_atomic(Path(path), header + body, overwrite=overwrite)


MOSAIC_NEIGHBOURS = ((-2, -2), (-2, 0), (-2, 2), (0, -2), (0, 2), (2, -2), (2, 0), (2, 2))  # same CFA colour
RGB_NEIGHBOURS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


def repair_mosaic(mosaic: np.ndarray, bad: np.ndarray) -> tuple[np.ndarray, int]:
    """A copy of the H x W Bayer ``mosaic`` (any units) with each ``bad`` sample replaced by the median of its
    same-colour neighbours two pixels away that are not bad, and how many samples had none (left as they were)."""
    return _repaired(mosaic, bad, MOSAIC_NEIGHBOURS)


def repair_rgb(rgb: np.ndarray, bad: np.ndarray) -> tuple[np.ndarray, int]:
    """A copy of the H x W x 3 ``rgb`` with each ``bad`` pixel replaced, per channel, by the median of its eight
    neighbours that are not bad, and how many pixels had none (left as they were)."""
    return _repaired(rgb, bad, RGB_NEIGHBOURS)


def _repaired(image: np.ndarray, bad: np.ndarray, offsets) -> tuple[np.ndarray, int]:
    repaired = image.copy()
    rows, columns = np.nonzero(bad)
    if rows.size == 0:
        return repaired, 0
    height, width = bad.shape
    values = np.full((len(offsets), rows.size) + image.shape[2:], np.nan, np.float64)
    for index, (row_step, column_step) in enumerate(offsets):
        row, column = rows + row_step, columns + column_step
        usable = (row >= 0) & (row < height) & (column >= 0) & (column < width)
        usable[usable] &= ~bad[row[usable], column[usable]]
        values[index, usable] = image[row[usable], column[usable]]
    found = ~np.all(np.isnan(values), axis=0)
    if image.ndim == 3:
        found = found.all(axis=-1)
    median = np.nanmedian(values[:, found], axis=0)
    if np.issubdtype(image.dtype, np.integer):
        median = np.rint(median)
    repaired[rows[found], columns[found]] = median.astype(image.dtype)
    return repaired, int((~found).sum())
