"""hdrcam: snapshot HDR imaging with a learned rank-1 diffractive optical element.

Implements Sun, Tseng, Fu, Heidrich, Heide, "Learning Rank-1 Diffractive Optics for Single-shot High
Dynamic Range Imaging", CVPR 2020. Linear light and SI units throughout (see README.md).

The stages a Python user calls, one function each (imported on first use: ``import hdrcam`` loads neither
numpy nor torch):

- capture_bracket: shoot an exposure bracket of RAW frames (simulated or a USB Sony A7)
- fuse: merge a RAW bracket into linear HDR (relative radiance)
- calibrate_psf: measure the PSF from a point-source bracket
- find_bad_pixels: the sensor's hot and dead pixels from dark and flat RAW frames (a mask; written as a dcraw
  list by hdrcam.io.bad_pixels.write_bad_pixels, repaired on reading by hdrcam.io.ldr_frame.read_ldr_capture)
- design / finetune: train the network (and the DOE) / fine-tune it behind a measured PSF
- reconstruct: a captured LDR frame -> linear HDR
- evaluate_checkpoints: score checkpoints on a fixed test set (PSNR in dB)

    import hdrcam
    hdrcam.capture_bracket("bracket", camera="sim", profile="simulated", scene="night")
    hdr = hdrcam.fuse(["bracket"], profile="simulated").rgb     # H x W x 3 float32
    result = hdrcam.reconstruct(frame)                          # frame: H x W x 3 in [0, 1]
    result.hdr, result.confidence
"""

__version__ = "0.1.0"

# public name -> the module that defines it
_STAGES = {"capture_bracket": "hdrcam.stages", "fuse": "hdrcam.stages", "calibrate_psf": "hdrcam.stages",
           "find_bad_pixels": "hdrcam.calibrate.bad_pixels",
           "design": "hdrcam.stages", "finetune": "hdrcam.stages", "reconstruct": "hdrcam.api",
           "evaluate_checkpoints": "hdrcam.stages"}

__all__ = [*_STAGES, "__version__"]


def __getattr__(name: str):
    if name in _STAGES:
        import importlib

        return getattr(importlib.import_module(_STAGES[name]), name)
    raise AttributeError(f"module 'hdrcam' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_STAGES))
