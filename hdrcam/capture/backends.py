"""Choose and build a camera backend: ``sim``, ``sim-usb`` or ``usb`` (the ``--camera`` option)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from hdrcam.errors import InputError

if TYPE_CHECKING:  # the command line reads CAMERA_KINDS without importing the simulation (torch)
    from hdrcam.capture.camera import Camera
    from hdrcam.capture.scene import Scene
    from hdrcam.capture.simulated import SimulatedCamera
    from hdrcam.profiles import Profile

CAMERA_KINDS = ("sim", "sim-usb", "usb")
# the smallest width and height of a simulated camera's frame, in pixels: LibRaw opens no RAW file smaller than
# 22 px on a side (identify.cpp, "Early reject for damaged images": height < 22 || width < 22 -> not RAW)
SIMULATED_MIN_SIDE_PX = 22


def open_camera(kind: str, profile: Profile, *, scene: Scene | None = None, psf=None, seed: int = 0,
                faults=None, latencies=None, **simulation) -> tuple[Camera, SimulatedCamera | None]:
    """A camera ready to be entered (``with camera:``) and, for sim and sim-usb, the simulation behind it.

    ``sim`` and ``sim-usb`` need the ``scene`` and ``psf`` they image; ``faults`` (emulator.Faults) make the
    emulated camera misbehave and ``latencies`` (emulator.Latencies) time it; ``simulation`` goes to
    SimulatedCamera (hot pixels, exposure error, ...). ``usb`` finds the camera on the backend that
    HDRCAM_USB_BACKEND names (module:callable), else on libusb; ``sim-usb`` puts the emulated A7 on a pyusb
    backend the same way.
    """
    if kind == "usb":
        from hdrcam.capture.sony import SonyA7Camera

        return SonyA7Camera(), None
    if kind not in CAMERA_KINDS:
        raise InputError(f"unknown camera {kind!r}; choose from {', '.join(CAMERA_KINDS)}")
    from hdrcam.capture.simulated import SimulatedCamera

    simulated = SimulatedCamera(profile, scene, psf, seed=seed, **simulation)
    if kind == "sim":
        return simulated, simulated
    from hdrcam.capture.emulator import EmulatedSonyA7, EmulatedUsbBackend
    from hdrcam.capture.sony import SonyA7Camera, find_sony_camera

    emulated = EmulatedSonyA7(simulated, faults=faults, latencies=latencies)
    backend = EmulatedUsbBackend(emulated)
    camera = SonyA7Camera(find_sony_camera(backend), clock=emulated.clock,
                          cover_lens=lambda covered: setattr(emulated, "lens_covered", covered))
    return camera, simulated
