"""HDR data: datasets of EXR files and procedural scenes, in relative linear radiance."""
