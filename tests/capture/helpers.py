"""Small simulated cameras for capture tests."""

from __future__ import annotations

from hdrcam.capture.backends import open_camera
from hdrcam.capture.scene import load_scene
from hdrcam.optics.analytic import dirac
from hdrcam.profiles import load_profile

HEIGHT_PX, WIDTH_PX = 48, 64


def small_camera(kind: str = "sim", scene: str = "flat:0.5", seed: int = 0, faults=None, **simulation):
    """A 64 x 48 px simulated A7 (Dirac PSF) on the simulated profile; returns (camera, simulated camera)."""
    profile = load_profile("simulated")
    return open_camera(kind, profile, scene=load_scene(scene, HEIGHT_PX, WIDTH_PX, seed=seed), psf=dirac(9),
                       seed=seed, faults=faults, **simulation)


def emulated_a7(latencies=None, **faults):
    """The usb client on the emulated A7 with ``faults`` (hdrcam.capture.emulator.Faults fields); returns (camera,
    the emulated body)."""
    from hdrcam.capture.emulator import Faults

    camera, _ = small_camera("sim-usb", faults=Faults(**faults), latencies=latencies)
    return camera, camera._device.backend.camera
