"""RAW ingest: read a folder of RAW files and group them into exposure brackets.

A bracket is a run of frames from one camera (for files that name none, one sensor as LibRaw reports it:
``hdrcam.io.raw.sensor_fingerprint``) at one ISO, aperture and frame size, taken close together (no gap longer
than ``max_gap_s`` plus twice the previous exposure: a long exposure is followed by an in-camera dark frame as
long, Long Exposure NR, on by default on Sony bodies), with distinct exposure times; a repeated exposure starts
the next bracket (a camera's own bracket sets, shot out of order as 0, -1, +1 EV and less than ``max_gap_s``
apart, are told apart by a smaller ``max_gap_s``). Brackets shot alternately (e.g. at two ISOs) are separated by
their settings. Every file of the folder is offered to LibRaw (no list of suffixes): one it does not open, or
that fits no bracket, is reported with the reason - never silently dropped. A byte-identical copy of another RAW
file (``frame-02 (1).dng`` beside ``frame-02.dng``) is named as a duplicate and left out, so that it neither
splits a bracket nor stands for a second exposure. Hidden files and hdrcam's own JSON manifests are not
candidates.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path


from hdrcam.capture.manifest import Bracket, BracketFrame, sha256_of
from hdrcam.capture.notches import exposure_label
from hdrcam.errors import InputError
from hdrcam.io.raw import RawMetadata, bit_depth_class, read_raw_metadata, sensor_fingerprint

DEFAULT_MAX_GAP_S = 10.0


@dataclasses.dataclass
class IngestResult:
    brackets: list[list[RawMetadata]]
    report: list[str]  # one line per file that is not in a bracket, one for frames without a capture time


NOT_CANDIDATES = (".json",)  # hdrcam's manifests beside the frames


def raw_files(folder: Path) -> list[Path]:
    """The files of ``folder`` that may be RAW files: all but hidden files and manifests (LibRaw decides)."""
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder")
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and not p.name.startswith(".") and p.suffix.lower() not in NOT_CANDIDATES)


def group_brackets(frames: list[RawMetadata], max_gap_s: float = DEFAULT_MAX_GAP_S) -> IngestResult:
    by_settings: dict[tuple, list[RawMetadata]] = {}
    for frame in frames:
        key = (frame.camera_model, sensor_fingerprint(frame), frame.iso, round(frame.f_number or 0.0, 1),
               frame.width_px, frame.height_px, bit_depth_class(frame.white_level_dn))
        by_settings.setdefault(key, []).append(frame)
    brackets, report = [], []
    timeless = [frame.path.name for frame in frames if frame.timestamp is None]
    if timeless:  # nothing tells brackets shot hours apart from one: only settings and file order group them
        report.append(f"no capture time recorded in {len(timeless)} frame(s) ({', '.join(timeless[:3])}"
                      f"{', ...' if len(timeless) > 3 else ''}): they are grouped by their settings and file names "
                      "alone; check the brackets")
    for group in by_settings.values():
        group.sort(key=lambda f: (*_taken(f), f.path.name))
        current: list[RawMetadata] = []
        for frame in group:
            if current and (_too_late(current[-1], frame, max_gap_s)
                            or any(_same_exposure(frame, other) for other in current)):
                _close(current, group, brackets, report, max_gap_s)
                current = []
            current.append(frame)
        _close(current, group, brackets, report, max_gap_s)
    brackets.sort(key=lambda b: (*_taken(b[0]), b[0].path.name))
    return IngestResult(brackets, report)


BUSY_EXPOSURES = 2.0  # the exposure and the long-exposure noise reduction's dark frame, as long


def _too_late(previous: RawMetadata, frame: RawMetadata, max_gap_s: float) -> bool:
    """True when ``frame`` (EXIF times: when each exposure began) began more than ``max_gap_s`` after the
    camera could have been ready again: BUSY_EXPOSURES times the previous exposure after it began; or when one
    of the two records a time and the other none (nothing ties a frame without a time to a timed bracket)."""
    if previous.timestamp is None and frame.timestamp is None:
        return False
    if previous.timestamp is None or frame.timestamp is None:  # a frame without a time beside timed ones: apart
        return True
    return (frame.timestamp - previous.timestamp).total_seconds() > max_gap_s + BUSY_EXPOSURES * previous.exposure_s


def _same_exposure(a: RawMetadata, b: RawMetadata) -> bool:
    return abs(a.exposure_s - b.exposure_s) <= 1e-3 * max(a.exposure_s, b.exposure_s)


def _close(current: list[RawMetadata], group: list[RawMetadata], brackets: list, report: list[str],
           max_gap_s: float) -> None:
    """A run of two or more frames is a bracket; a lone frame is reported, with the frame whose exposure it
    repeats when one with its settings was taken close enough to share its bracket."""
    if len(current) >= 2:
        brackets.append(current)
    elif current:
        frame = current[0]
        twin = next((other for other in group if other is not frame and _same_exposure(frame, other)
                     and not _too_late(*sorted((frame, other), key=_taken), max_gap_s)), None)
        reason = (f"same exposure as {twin.path.name}, and a bracket needs distinct exposures" if twin
                  else f"no other frame with these settings within {max_gap_s:g} s of the camera being ready "
                       "(twice an exposure after it began)")
        report.append(f"not in a bracket: {frame.path.name} ({settings_text(frame)}, "
                      f"{exposure_label(frame.exposure_s)}): {reason}")


def _taken(frame: RawMetadata) -> tuple:
    """Sorts by capture time, frames without one last."""
    return frame.timestamp is None, frame.timestamp or 0


def subfolder_hint(folder: Path) -> str:
    """Where files lie below a folder whose own gave no bracket (a memory card's root: its frames are in
    DCIM/100MSDCF, the DCF layout every camera writes; beside it Sony's AVF_INFO holds index files), as
    ': ingest reads one folder, not its subfolders - e.g. PATH (N files)': the first folder below DCIM that
    holds files, else the first folder that does; '' for none."""
    for top in (folder / "DCIM", folder):
        for root, folders, _ in os.walk(top) if top.is_dir() else ():  # top down, the first with files
            folders[:] = sorted(name for name in folders if not name.startswith("."))
            below = Path(root)
            count = len(raw_files(below)) if below != folder else 0
            if count:
                return (f": ingest reads one folder, not its subfolders - e.g. {below} ({count} "
                        f"file{'s' if count > 1 else ''})")
    return ""


def ingest_folder(folder: Path, max_gap_s: float = DEFAULT_MAX_GAP_S) -> IngestResult:
    """Read every RAW file in ``folder`` and group them; unreadable files go to the report."""
    frames, unreadable = [], []
    for path in raw_files(folder):
        try:
            frames.append(read_raw_metadata(path))
        except InputError as error:
            unreadable.append(f"skipped: {error}")
    originals, duplicates = _without_copies(frames)
    result = group_brackets(originals, max_gap_s)
    result.report = unreadable + duplicates + result.report
    return result


def _without_copies(frames: list[RawMetadata]) -> tuple[list[RawMetadata], list[str]]:
    """``frames`` less byte-identical copies (:func:`identical_copies`), and one line per copy."""
    copies = identical_copies(frames)
    report = sorted(f"duplicate: {copy.name} has the same content as {original.name} (identical sha256); left out "
                    "of the brackets" for copy, original in copies)
    left_out = {copy for copy, _ in copies}
    return [frame for frame in frames if frame.path not in left_out], report


def identical_copies(frames: list[RawMetadata]) -> list[tuple[Path, Path]]:
    """(copy, original) for each file among ``frames`` byte-identical to another. Only files of equal size,
    capture time and exposure are hashed (a card of same-sized frames is not read whole). Of identical files the
    shortest name (then the first by name) is the original: frame-02.dng, not "frame-02 (1).dng"."""
    candidates: dict[tuple, list[RawMetadata]] = {}
    for frame in frames:
        candidates.setdefault((frame.path.stat().st_size, frame.timestamp, frame.exposure_s), []).append(frame)
    copies = []
    for same in (group for group in candidates.values() if len(group) > 1):
        originals: dict[str, Path] = {}
        for path in sorted((frame.path for frame in same), key=lambda path: (len(path.name), path.name)):
            original = originals.setdefault(sha256_of(path), path)
            if original != path:
                copies.append((path, original))
    return copies


def settings_text(frame: RawMetadata) -> str:
    """'ISO 3200, f/2.8' ('?' for what the file does not record)."""
    return f"ISO {f'{frame.iso:g}' if frame.iso else '?'}, f/{f'{frame.f_number:g}' if frame.f_number else '?'}"


def bracket_manifest(frames: list[RawMetadata], manifest_folder: Path, options: dict) -> Bracket:
    """A manifest for ingested frames; file names relative to ``manifest_folder``."""
    ordered = sorted(frames, key=lambda f: f.exposure_s)
    return Bracket(kind="light", camera={"backend": "ingest", "model": ordered[0].camera_model}, profile=None,
                   frames=[BracketFrame(file=os.path.relpath(f.path, manifest_folder), sha256=sha256_of(f.path),
                                        exposure_s=f.exposure_s, exposure_label=exposure_label(f.exposure_s),
                                        iso=f.iso or 0.0, f_number=f.f_number,
                                        timestamp=f.timestamp.isoformat() if f.timestamp else "")
                           for f in ordered], options=options)
