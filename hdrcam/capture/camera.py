"""The Camera protocol every backend implements, and what a capture returns.

A camera is a session (python-gphoto2 style): open it as a context manager, read or change the exposure,
capture RAW frames into a folder. Exposure times are seconds; ``exposure_s`` is what the camera reports
(the nominal label, e.g. 1/125 s), not the true shutter time - brackets estimate true ratios from data.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from pathlib import Path
from typing import Protocol, runtime_checkable

from hdrcam.errors import HdrcamError
from hdrcam.io.raw import RawFrame


class CameraError(HdrcamError):
    """The camera failed, timed out, or answered something unexpected."""


class CameraNotFound(CameraError):
    """No camera of the requested kind is connected."""


@dataclasses.dataclass(frozen=True)
class ExposureSettings:
    exposure_s: float  # nominal shutter time as the camera labels it
    exposure_label: str  # e.g. "1/125" or "2.5\""
    iso: float
    f_number: float | None  # None: the lens reports no aperture (no electronic contacts)


@dataclasses.dataclass(frozen=True)
class CapturedFrame:
    path: Path  # the RAW file as written (DNG from simulated cameras, ARW from a Sony)
    settings: ExposureSettings
    timestamp: dt.datetime
    camera_model: str
    raw: RawFrame  # the file read back: Bayer data, CFA, levels, colour, metadata


@runtime_checkable
class Camera(Protocol):
    """What brackets and the command line need from a camera backend."""

    model: str

    def __enter__(self) -> "Camera": ...

    def __exit__(self, *exc) -> None: ...

    def settings(self) -> ExposureSettings:
        """The exposure the camera is set to now."""

    def set_exposure(self, exposure_s: float | None = None, iso: float | None = None) -> ExposureSettings:
        """Move to the shutter notch nearest ``exposure_s`` (seconds) and to ``iso``, one of the camera's ISO settings
        (InputError otherwise: never another ISO than asked); returns what the camera landed on."""

    def capture(self, folder: Path, stem: str, *, dark: bool = False) -> CapturedFrame:
        """Expose one RAW frame and write it atomically as ``folder/stem.<camera's suffix>``.

        ``dark``: a dark frame (lens covered) at the same settings; backends that cannot cover the lens
        themselves ask the user.
        """
