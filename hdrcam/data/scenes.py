"""Where training and test scenes come from: the procedural night-scene generator, folders of HDR files,
or a weighted mixture of them.

A data specification is ``procedural``, a folder, or a comma-separated mixture ``SOURCE:WEIGHT,...``
(e.g. ``runs/data/train:0.6,procedural:0.3,photos/:0.1``): each training draw picks a source with
probability proportional to its weight, then a scene from it. Test sets come from the first source.

A scene is H x W x 3 float32 linear radiance, exposure-scaled as the paper does (hdrcam.data.saturation):
training scenes so that 1-3 % of the pixels of the centre region exceed 1, test scenes exactly 1.5 %,
clipped at 2^8. ``margin_px`` pads the centre region on every side so that light from outside the crop
spreads into it through the PSF, as it does on a sensor; targets are the centre region only.
"""

from __future__ import annotations

import math
import unicodedata
import warnings
import zlib

from pathlib import Path
from typing import Iterator, NamedTuple

import numpy as np

from hdrcam.data.augment import undistorted_rows, white_balance_jitter
from hdrcam.data.crops import rotate_flip, saturated_crop, scored_crop
from hdrcam.data.hdr_folder import HdrFolder
from hdrcam.data.night_scene import night_scene
from hdrcam.data.saturation import (HIGHLIGHT_PEAK, TEST_CLIPPED_FRACTION, TRAIN_CLIPPED_RANGE, clipped_fraction,
                                    fraction_shortfall, scale_to_clipped_fraction)
from hdrcam.errors import InputError, escaped_name

PROCEDURAL = "procedural"
PROCEDURAL_CANVAS_PX = 256  # a night scene is drawn at this size and cropped
TEST_SEED_BASE = 1_000_000  # test scenes never share seeds with training draws
TEST_CONTEXT_PX = 128  # of a test scene's own content around its scored centre (the A7 PSFs' margin is 127)
TRAINING_DRAWS = 16  # crops drawn in a row before a training scene without light is an error


class TestScene(NamedTuple):
    """A test scene: its name, H x W x 3 float32 radiance (scaled, or unscaled where it cannot be) and its own seed
    (of its crop and its capture's noise): its index among procedural scenes, the CRC-32 of a photograph's file
    name (so a photograph's score does not depend on which other files share its folder)."""
    name: str
    radiance: np.ndarray
    seed: int


def protocol_shortfall(truth: np.ndarray) -> str | None:
    """Why a test scene's scored centre (H x W x 3) misses the protocol's 1.5 % above 1 (so it is not scored:
    hdrcam.data.saturation.fraction_shortfall), or None when it meets it."""
    return fraction_shortfall(clipped_fraction(truth), TEST_CLIPPED_FRACTION, truth.shape[0] * truth.shape[1],
                              lit=int(np.count_nonzero(truth.max(axis=-1) > 0.0)))


def name_seed(name: str) -> int:
    """A file name's CRC-32 (0 to 2^32 - 1) over its bytes (UTF-8 of its NFC form: macOS stores "Café" decomposed,
    Linux composed; a name that is not valid UTF-8, its own bytes): the same in every run and on every platform,
    unlike Python's salted hash()."""
    try:
        return zlib.crc32(unicodedata.normalize("NFC", name).encode("utf-8"))
    except UnicodeEncodeError:  # lone surrogates: the bytes of a name that is not UTF-8
        return zlib.crc32(name.encode("utf-8", "surrogateescape"))


def parse_mixture(data: str) -> list[tuple[str, float]]:
    """``SOURCE[:WEIGHT],...`` -> [(source, weight)]; a source without a weight weighs 1. A folder whose own name
    holds a ',' or ends in ':NUMBER' is taken as itself when it exists (``data/shoot:2`` trained on ``data/shoot``
    with weight 2), and refused as ambiguous when the split reading names existing sources too."""
    text = str(data)
    if text not in ("", PROCEDURAL) and Path(text).exists():
        split = [_weighted(entry) for entry in text.split(",")]
        if split != [(text, 1.0)] and all(source == PROCEDURAL or Path(source).exists() for source, _ in split):
            raise InputError(f"--data {text!r}: a folder of that name, and the mixture "
                             f"{', '.join(f'{source} with weight {weight:g}' for source, weight in split)} too; "
                             "rename the folder")
        return [(text, 1.0)]
    mixture = []
    for entry in text.split(","):
        weighted = _weighted(entry)
        if weighted[0] != entry and Path(entry).exists():
            if Path(weighted[0]).exists():
                raise InputError(f"--data {data!r}: {entry} is a folder, and {weighted[0]} with weight {weighted[1]:g} "
                                 "too; rename one of them")
            weighted = (entry, 1.0)
        mixture.append(weighted)
    weights = [weight for _, weight in mixture]
    if not mixture or any(not source for source, _ in mixture) or not all(0 < weight < math.inf for weight in weights) \
            or not math.isfinite(sum(weights)):
        raise InputError(f"--data {data!r}: expected SOURCE[:WEIGHT],... with positive, finite weights")
    return mixture


def _weighted(entry: str) -> tuple[str, float]:
    """One SOURCE[:WEIGHT] entry read as written: (source, weight), weight 1 when none (or a ':' inside a path)."""
    source, _, weight = entry.rpartition(":")
    try:
        return (source, float(weight)) if source else (entry, 1.0)
    except ValueError:
        return entry, 1.0


def absolute_mixture(data: str) -> str:
    """``data`` (SOURCE[:WEIGHT],...) with every folder an absolute path, as a training run records it (a resume
    from another folder finds the folders); one source keeps no weight, several keep theirs."""
    mixture = parse_mixture(data)
    sources = [source if source == PROCEDURAL else str(Path(source).resolve()) for source, _ in mixture]
    if len(mixture) == 1:
        return sources[0]
    return ",".join(f"{source}:{weight!r}" for source, (_, weight) in zip(sources, mixture))


class SceneSource:
    """Training draws from a mixture of ``procedural`` and folders of .exr/.hdr files (module docstring);
    a fixed test set from the first of them."""

    def __init__(self, data: str | Path, *, lenient: bool = False, progress=None):
        """``lenient`` (evaluation): unreadable photographs are left out with a warning; ``progress``: a tqdm-like
        bar of the files read (HdrFolder)."""
        self.description = str(data)
        self.mixture = parse_mixture(str(data))
        self.folders = [None if source == PROCEDURAL else HdrFolder(Path(source), lenient=lenient, progress=progress)
                        for source, _ in self.mixture]
        weights = np.array([weight for _, weight in self.mixture])
        self.probabilities = weights / weights.sum()
        self.folder = self.folders[0]

    def check_training_folders(self, scene_px: int | None = None) -> None:
        """Refuse, by name, a training photograph without light (every pixel 0 in every channel): no crop of it
        can be saturated (checked once, before training, rather than failing at the step that draws it); warn,
        by name, of one smaller than ``scene_px`` (a training scene's side, crop and margins): its crops are
        mirrored to fill it, as the test set's are."""
        for folder in (folder for folder in self.folders if folder is not None):
            for path, image in zip(folder.files, folder.images):
                if not image.max(initial=0.0) > 0.0:
                    raise InputError(f"{path}: the photograph holds no light (every pixel is 0); it cannot be "
                                     "saturated for training - remove it from --data")
                if scene_px is not None and min(image.shape[:2]) < scene_px:
                    warnings.warn(f"{path}: {image.shape[1]} x {image.shape[0]} px, smaller than the {scene_px} px "
                                  "training scene (crop and margins): mirrored to fill it")

    def _raw_crop(self, folder: HdrFolder | None, size_px: int, rng: np.random.Generator) -> tuple[np.ndarray, str]:
        """A crop of ``folder``'s photographs (None: a procedural night scene) and where it came from."""
        if folder is None:
            canvas = max(PROCEDURAL_CANVAS_PX, size_px)
            image, origin = night_scene(canvas, canvas, seed=int(rng.integers(2 ** 31))), PROCEDURAL
        else:
            index = int(rng.integers(len(folder)))
            image = white_balance_jitter(undistorted_rows(folder.images[index], size_px), rng)
            origin = str(folder.files[index])
        return saturated_crop(image, size_px, rng), origin

    def training_scene(self, size_px: int, margin_px: int, rng: np.random.Generator) -> np.ndarray:
        """A (size + 2 margin)^2 scene, rotated/flipped, with 1-3 % of its centre above 1, from a source drawn in
        proportion to its weight. A crop whose centre cannot be scaled so (too little light - a dark corner of
        a photograph - or a plateau at its brightest: a light clipped at source lands on 1 exactly, and its crop
        would teach that clipped pixels are white) is drawn again from the same source (the mixture's weights
        hold), up to TRAINING_DRAWS times in a row; a draw that never failed is the one it was before this
        rule."""
        # one source draws no choice, so single-source runs (Table 2, the shipped design) keep their random streams
        folder = self.folders[int(rng.choice(len(self.folders), p=self.probabilities))] \
            if len(self.folders) > 1 else self.folder
        for _ in range(TRAINING_DRAWS):
            raw, origin = self._raw_crop(folder, size_px + 2 * margin_px, rng)
            crop = rotate_flip(raw, rng)
            fraction = rng.uniform(*TRAIN_CLIPPED_RANGE)
            try:
                scene = _scaled(crop, fraction, margin_px)
            except InputError:
                continue
            centre = scene[margin_px:scene.shape[0] - margin_px, margin_px:scene.shape[1] - margin_px]
            if not fraction_shortfall(clipped_fraction(centre), fraction, centre.shape[0] * centre.shape[1]):
                return scene
        raise InputError(f"{origin}: {TRAINING_DRAWS} training crops of {size_px} px in a row could not be scaled "
                         "so 1-3 % of their pixels exceed white (too little light, or a plateau at their brightest: "
                         "clipped at source); remove such photographs from --data")

    def test_scenes(self, size_px: int, margin_px: int, count: int) -> Iterator[TestScene]:
        """``count`` fixed scenes (procedural) or one per file (folder) of the first source, centre exactly 1.5 %
        above 1 and holding a highlight, the same whatever ``margin_px`` (hdrcam.data.crops.scored_crop); each
        named (night-NNN, or the file's stem - its name where another file of the folder, read or not, shares the
        stem or is named so: Bonita.exr beside Bonita.exr.hdr) and seeded (TestScene): a
        photograph's crop by its file name, not its place in the folder. A photograph without
        light in its crop stays in its place unscaled (no pixel above 1); one smaller than the crop is
        mirrored to fill it, with a warning where it can be scored (protocol_shortfall: where it cannot, evaluate's
        'not scored' is the one warning). Each is cropped as it is asked for (a crop of a large panorama takes
        seconds)."""
        if self.folder is None:
            canvas = max(PROCEDURAL_CANVAS_PX, size_px + 2 * TEST_CONTEXT_PX)
            for index in range(count):
                rng = np.random.default_rng(TEST_SEED_BASE + index)
                scene = night_scene(canvas, canvas, seed=int(rng.integers(2 ** 31)))
                yield TestScene(f"night-{index:03d}", _scaled(scored_crop(scene, size_px, margin_px, TEST_CONTEXT_PX,
                                                                        rng), TEST_CLIPPED_FRACTION, margin_px), index)
        else:
            listed = [*self.folder.files, *(path for path, _ in self.folder.skipped)]
            stems, names = [path.stem for path in listed], {path.name for path in listed}
            for path, image in zip(self.folder.files, self.folder.images):
                seed = name_seed(path.name)
                rng = np.random.default_rng(TEST_SEED_BASE + seed)
                crop = scored_crop(image, size_px, margin_px, TEST_CONTEXT_PX, rng)
                unique = stems.count(path.stem) == 1 and path.stem not in names  # Bonita.exr.hdr's stem is
                name = escaped_name(path.stem if unique else path.name)  # Bonita.exr's name
                try:
                    scaled = _scaled(crop, TEST_CLIPPED_FRACTION, margin_px)
                except InputError:  # no light to scale: kept unscaled (evaluate leaves it out, as it does any
                    scaled = np.clip(crop, 0.0, HIGHLIGHT_PEAK).astype(np.float32)  # photograph it cannot scale,
                centre = scaled[margin_px:margin_px + size_px, margin_px:margin_px + size_px]
                if min(image.shape[:2]) < size_px and protocol_shortfall(centre) is None:  # else only 'not scored'
                    warnings.warn(f"{path}: {image.shape[1]} x {image.shape[0]} px, smaller than the {size_px} px "
                                  "test crop: mirrored to fill it, and the mirrored copies are scored too")
                yield TestScene(name, scaled, seed)  # and names it)


def _scaled(crop: np.ndarray, fraction: float, margin_px: int) -> np.ndarray:
    centre = crop[margin_px:crop.shape[0] - margin_px, margin_px:crop.shape[1] - margin_px]
    return scale_to_clipped_fraction(crop, fraction, scale_region=centre)
