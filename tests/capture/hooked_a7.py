"""A camera for HDRCAM_USB_BACKEND=tests.capture.hooked_a7:backend - the emulated A7 on a pyusb backend, as any
outside simulator would be plugged in. Tests set FAULTS (and read CAMERAS) before running the command line.

It runs on the real clock (the client behind ``--camera usb`` sleeps for real), with the A7's latencies scaled
down by TIME_SCALE so a bracket takes seconds; the image is still ready long after the 2 s the acceptance case
asks for in camera time.
"""

from __future__ import annotations

from hdrcam.capture.emulator import EmulatedSonyA7, EmulatedUsbBackend, Faults, Latencies
from hdrcam.capture.ptp.session import Clock
from tests.capture.helpers import small_camera

TIME_SCALE = 0.02
LATENCIES = Latencies(image_ready_s=2.0, focus_s=0.5)
FAULTS = Faults()
CAMERAS: list[EmulatedSonyA7] = []


def backend() -> EmulatedUsbBackend:
    _, simulated = small_camera("sim", scene="flat:0.3")
    camera = EmulatedSonyA7(simulated, clock=Clock(), faults=FAULTS, latencies=LATENCIES.scaled(TIME_SCALE))
    CAMERAS.append(camera)
    return EmulatedUsbBackend(camera)
