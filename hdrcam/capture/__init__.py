"""Cameras: one protocol, three backends (simulated, emulated USB, Sony A7 over USB), RAW ingest and brackets."""
