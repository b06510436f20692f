"""The frames of a bracket, read and checked: one camera; same size, CFA, ISO, aperture and bit depth; distinct
exposures. Where the files name no camera (CR3, RAF, ...: not TIFF), frames of one body are told by what LibRaw
reports of its sensor (``hdrcam.io.raw.sensor_fingerprint``).

A bracket is a bracket.json (or a folder holding one), a folder of RAW files, or a list of RAW files; without
a manifest the exposures come from the files' metadata; with one, each frame must still have the sha256 it
was captured with. Frames are sorted from shortest to longest. In a
folder, files LibRaw does not open as RAW are skipped with a warning naming each; a damaged RAW is refused.
"""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from hdrcam.capture.ingest import identical_copies, raw_files
from hdrcam.capture.manifest import MANIFEST_NAME, load_bracket, sha256_of
from hdrcam.errors import InputError
from hdrcam.io.raw import (NotRawError, RawFrame, RawMetadata, bit_depth_class, raw_size_px, read_raw,
                           sensor_fingerprint, warn_shading_not_applied)
from hdrcam.limits import check_image_size
from hdrcam.parallel import worker_threads


FRAME_BYTES_PER_PIXEL = 2  # a decoded frame: LibRaw's uint16 buffer
MERGED_BYTES_PER_PIXEL = 20  # the merge's rate (float32), usable-frame mask and the demosaiced float32 RGB, with
# the preview and temporaries: a 24 MP bracket of five frames peaked at 706 MB (30 bytes a pixel with the frames')


def bracket_files(sources: list[Path], kind: str = "light") -> list[tuple[Path, str | None]]:
    """RAW paths of a bracket given as a manifest, a folder or files, each with the sha256 its manifest recorded
    (None without a manifest).

    A manifest must be complete and of ``kind`` ("light" or "dark"), and list no missing frame: a capture
    left unfinished, or darks given where lights belong, are refused.
    """
    if len(sources) == 1 and _has_manifest(sources[0]):
        bracket = load_bracket(sources[0])
        if bracket.status != "complete":
            raise InputError(f"{sources[0]}: the capture is {bracket.status} ({bracket.error}); finish it with "
                             "capture bracket --resume, or pass its frames as files")
        if bracket.kind != kind:
            raise InputError(f"{sources[0]}: a bracket of {bracket.kind} frames where {kind} frames are expected"
                             + ("; give dark frames with --darks" if bracket.kind == "dark" else ""))
        for path in bracket.paths():
            if not path.is_file():
                raise InputError(f"{path}: listed in {sources[0]} but missing; restore it")
        return [(path, frame.sha256) for frame, path in zip(bracket.frames, bracket.paths())]
    if len(sources) == 1 and sources[0].is_dir():
        return [(path, None) for path in raw_files(sources[0])]
    for source in sources:
        if source.is_dir() or source.suffix == ".json":
            raise InputError(f"{source}: a {'folder' if source.is_dir() else 'manifest'} among several inputs; give "
                             "one bracket (a bracket.json or a folder) or its RAW files")
    return [(path, None) for path in sources]


def bracket_paths(sources: list[Path], kind: str = "light") -> list[Path]:
    """The RAW paths of :func:`bracket_files` (whether each frame still has its sha256 is checked by
    :func:`read_bracket`)."""
    return [path for path, _ in bracket_files(sources, kind)]


def bracket_input_files(sources: list[Path], kind: str = "light") -> list[Path]:
    """Every file a bracket is read from - its RAW frames and its manifest, if it has one: a command's outputs
    must be none of them, even with --overwrite."""
    manifest = [sources[0] if sources[0].suffix == ".json" else sources[0] / MANIFEST_NAME] \
        if len(sources) == 1 and _has_manifest(sources[0]) else []
    return bracket_paths(sources, kind) + manifest


def _has_manifest(source: Path) -> bool:
    return source.suffix == ".json" or (source / MANIFEST_NAME).is_file()


def read_bracket(sources: list[Path], kind: str = "light") -> list[RawFrame]:
    """Read and check every frame; InputError naming the offending file otherwise.

    Every frame listed in a manifest must still have the sha256 it was captured with. The files are decoded
    and hashed on a thread per core (LibRaw's decoding and hashlib both release the GIL; five 24 MP DNGs decode
    in 0.34-0.44 s on two threads against 0.58-0.74 s on one), decoding queued first, and each light frame's
    clip level is measured as soon as it is decoded.
    """
    files = bracket_files(sources, kind)
    from_folder = len(sources) == 1 and sources[0].is_dir() and not (sources[0] / MANIFEST_NAME).is_file()
    _check_bracket_memory([path for path, _ in files])
    with ThreadPoolExecutor(worker_threads()) as pool:
        reads = [pool.submit(_read, path, kind == "light") for path, _ in files]  # decoding first: it takes longest
        work = [(pool.submit(sha256_of, path) if expected else None, read)
                for (path, expected), read in zip(files, reads)]
        try:
            for (path, expected), (digest, _) in zip(files, work):
                if digest is not None and digest.result() != expected:
                    raise InputError(f"{path}: changed since it was captured (its sha256 differs from the "
                                     "manifest's); restore the original frame")
            frames, skipped = [], []
            for (path, _), (_, read) in zip(files, work):
                try:
                    frames.append(read.result())
                except NotRawError as error:
                    if not from_folder:
                        raise
                    skipped.append(error)
        except BaseException:
            for futures in work:
                for future in futures:
                    if future is not None:
                        future.cancel()
            raise
    for error in skipped:  # after the pool: while a frame decodes, LibRaw's silenced stderr would swallow them
        warnings.warn(f"skipped {error}")
    if kind == "light":  # dark frames record no light to shade
        warn_shading_not_applied(frames)
    if len(frames) < 1:
        raise InputError(f"{' '.join(map(str, sources))}: no RAW frames found")
    frames.sort(key=lambda f: f.metadata.exposure_s)
    reference = frames[0].metadata
    for frame in frames[1:]:
        meta = frame.metadata
        checks = (("camera model", meta.camera_model, reference.camera_model),
                  ("frame size", (meta.width_px, meta.height_px), (reference.width_px, reference.height_px)),
                  ("CFA pattern", meta.cfa_pattern, reference.cfa_pattern),
                  ("ISO", meta.iso, reference.iso),
                  ("aperture", _rounded(meta.f_number), _rounded(reference.f_number)))
        refuse_differences(meta, reference, checks)
    depths = [bit_depth_class(frame.metadata.white_level_dn) for frame in frames]
    if len(set(depths)) > 1:
        # the depth most frames have; on a tie the shortest frame's
        usual = max(depths, key=lambda depth: (depths.count(depth), depth == depths[0]))
        odd = [frame.metadata for frame, depth in zip(frames, depths) if depth != usual]
        raise InputError(f"{', '.join(meta.path.name for meta in odd)}: white level {odd[0].white_level_dn:g} DN, "
                         f"{bit_depth_class(odd[0].white_level_dn)} bits where the bracket's others have {usual} (e.g. "
                         "a 12-bit frame among 14-bit ones: continuous drive, bulb or a 12-bit setting); shoot the "
                         "bracket at one bit depth")
    for frame in frames[1:]:  # after the bit depth check, which says more of a white level of another depth
        pairs = zip(sensor_fingerprint(frame.metadata), sensor_fingerprint(reference))  # none for a named camera
        refuse_differences(frame.metadata, reference, [(what, value, expected)
                                                        for (what, value), (_, expected) in pairs])
    exposures = [f.metadata.exposure_s for f in frames]
    if len(set(exposures)) != len(exposures):
        refuse_repeated_files([frame.metadata for frame in frames])
        names = [f.metadata.path.name for f in frames]
        shown = [str(f.metadata.path) if names.count(f.metadata.path.name) > 1 else f.metadata.path.name
                 for f in frames]  # frames of the same name from two folders: their paths tell them apart
        raise InputError(f"two {kind} frames of the bracket have the same exposure time (one frame per exposure"
                         f"{'; average repeated darks first' if kind == 'dark' else ''}): "
                         + ", ".join(f"{name} {f.metadata.exposure_s:g} s" for name, f in zip(shown, frames)))
    for frame in frames:
        if not np.isfinite(frame.metadata.exposure_s):
            raise InputError(f"{frame.metadata.path}: exposure time is not finite")
    return frames


def refuse_repeated_files(frames: list[RawMetadata], what: str = "the bracket") -> None:
    """InputError naming a frame given twice (the same path, or a link to another frame's file) or that is a
    byte-identical copy of another (``frame (1).dng`` beside ``frame.dng``): one exposure counted twice.
    ``what``: where to remove it from."""
    seen: dict[Path, int] = {}
    for index, meta in enumerate(frames):
        original = frames[seen.setdefault(meta.path.resolve(), index)].path
        if seen[meta.path.resolve()] != index:
            same = "given twice" if original == meta.path else \
                f"the same file as {original.name} (one links to the other)"
            raise InputError(f"{meta.path}: {same}; give each frame once")
    copies = identical_copies(frames)
    if copies:
        copy, original = copies[0]
        raise InputError(f"{copy}: a copy of {original.name} (identical sha256); remove it from {what}")


def _check_bracket_memory(paths: list[Path]) -> None:
    """Refuse (TooLargeError) a bracket whose frames, all held until the merge, and what the merge makes need more
    memory than is available; sized from the files LibRaw opens (their headers only: nothing is decoded; a
    folder's other files are skipped, a damaged frame refused, when the frames are read)."""
    sizes = [size for size in map(raw_size_px, paths) if size is not None] if len(paths) > 1 else []
    if len(sizes) > 1:
        width_px, height_px = sizes[0]
        bytes_per_pixel = FRAME_BYTES_PER_PIXEL * len(sizes) + MERGED_BYTES_PER_PIXEL
        check_image_size(f"{len(sizes)} frames", height_px, width_px, bytes_per_pixel,
                         "fuse fewer frames, or free memory")


def refuse_differences(meta: RawMetadata, reference: RawMetadata, checks,
                       rule: str = "a bracket varies only the shutter") -> None:
    """InputError at the first (property, frame's value, reference's value) of ``checks`` whose values differ;
    ``rule``: what the frames must share, said after them."""
    for what, value, expected in checks:
        if value != expected:
            raise InputError(f"{meta.path}: {what} {value} differs from {reference.path.name}'s {expected}; {rule}")


def _rounded(f_number: float | None) -> float | None:
    return None if f_number is None else round(f_number, 1)


def _read(path: Path, measure_clip_level: bool) -> RawFrame:
    frame = read_raw(path)
    if measure_clip_level:
        frame.clip_level_tile_dn  # noqa: B018 - a cached property, measured here on the worker thread
    return frame
