"""bracket.json: what a bracket holds and how it was made (frames with hashes, exposures, camera, software).

File names are relative to the manifest's folder, so a capture folder can be moved as a whole. Exposures
are the camera's nominal values; ``true_exposure_s`` appears only for simulated cameras (ground truth for
tests of ratio estimation).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import json
import math
import platform
from pathlib import Path

from hdrcam.errors import InputError
from hdrcam.io.atomic import write_text_atomic

FORMAT = "hdrcam-bracket/1"
MANIFEST_NAME = "bracket.json"
IN_PROGRESS = "the capture is running (or was killed: resume it with capture bracket --resume)"


@dataclasses.dataclass(frozen=True)
class BracketFrame:
    file: str  # relative to the manifest's folder
    sha256: str
    exposure_s: float
    exposure_label: str
    iso: float
    f_number: float | None  # None: not recorded (a lens without electronic contacts)
    timestamp: str  # ISO 8601
    true_exposure_s: float | None = None  # simulated cameras only


@dataclasses.dataclass
class Bracket:
    kind: str  # "light" or "dark"
    camera: dict
    profile: str | None
    frames: list[BracketFrame]
    status: str = "complete"  # complete | incomplete (stopped or running: ``error`` says why)
    error: str | None = None
    notes: list[str] = dataclasses.field(default_factory=list)
    options: dict = dataclasses.field(default_factory=dict)
    software: dict = dataclasses.field(default_factory=lambda: software_versions())
    created: str = dataclasses.field(default_factory=lambda: dt.datetime.now().isoformat(timespec="seconds"))
    folder: Path | None = None  # where the manifest lives (not stored)

    def paths(self) -> list[Path]:
        return [(self.folder or Path(".")) / frame.file for frame in self.frames]

    def to_json(self) -> str:
        document = {"format": FORMAT, **{k: v for k, v in dataclasses.asdict(self).items() if k != "folder"}}
        return json.dumps(document, indent=2) + "\n"

    def write(self, folder: Path, name: str = MANIFEST_NAME, *, overwrite: bool = False) -> Path:
        self.folder = folder
        return write_text_atomic(folder / name, self.to_json(), overwrite=overwrite)


def load_bracket(path: Path) -> Bracket:
    """Read a bracket.json (or a folder holding one); InputError if it is not one."""
    path = Path(path)
    if path.is_dir():
        path = path / MANIFEST_NAME
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: no such bracket manifest") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: not a bracket manifest ({error})") from None
    if not isinstance(document, dict) or document.pop("format", None) != FORMAT:
        raise InputError(f"{path}: not an {FORMAT} manifest")
    try:
        frames = [BracketFrame(**frame) for frame in document.pop("frames")]
        bracket = Bracket(frames=frames, **document)
        _check_types(bracket)
    except (TypeError, KeyError, ValueError) as error:
        raise InputError(f"{path}: malformed bracket manifest ({error})") from None
    bracket.folder = path.parent
    return bracket


def _check_types(bracket: Bracket) -> None:
    """TypeError or ValueError naming the first field that does not hold what the manifest format says."""
    def number(value, name: str, *, positive: bool = False, optional: bool = False) -> None:
        if optional and (value is None or (isinstance(value, float) and math.isnan(value))):
            return  # not recorded (NaN: how manifests before null recorded a lens without contacts)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or value < 0 or (positive and value == 0):
            raise ValueError(f"{name} {json.dumps(value)} is not a {'positive' if positive else 'non-negative'} "
                             "finite number")

    if bracket.kind not in ("light", "dark") or bracket.status not in ("complete", "incomplete"):
        raise ValueError(f"kind {bracket.kind!r} / status {bracket.status!r}: expected light or dark / complete "
                         "or incomplete")
    for name, value, kind in (("camera", bracket.camera, dict), ("options", bracket.options, dict),
                              ("notes", bracket.notes, list)):
        if not isinstance(value, kind):
            raise TypeError(f"{name} is not a JSON {'object' if kind is dict else 'array'}")
    for frame in bracket.frames:
        for name in ("file", "sha256", "exposure_label", "timestamp"):
            if not isinstance(getattr(frame, name), str):
                raise TypeError(f"frame {name} {json.dumps(getattr(frame, name))} is not a string")
        number(frame.exposure_s, "frame exposure_s", positive=True)
        number(frame.iso, "frame iso")
        number(frame.f_number, "frame f_number", optional=True)
        number(frame.true_exposure_s, "frame true_exposure_s", positive=True, optional=True)


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def software_versions() -> dict:
    import numpy
    import rawpy
    import usb

    from hdrcam import __version__

    return {"hdrcam": __version__, "python": platform.python_version(), "numpy": numpy.__version__,
            "rawpy": rawpy.__version__, "pyusb": usb.__version__}
