"""PTP (ISO 15740) over USB, written against pyusb, with Sony's SDIO extension in ``hdrcam.capture.sony``."""
