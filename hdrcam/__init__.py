"""hdrcam: snapshot HDR imaging with a learned rank-1 diffractive optical element.

Implements Sun, Tseng, Fu, Heidrich, Heide, "Learning Rank-1 Diffractive Optics for Single-shot High
Dynamic Range Imaging", CVPR 2020. Linear light and SI units throughout (see DESIGN.md).
"""

__version__ = "0.1.0"


def reconstruct(frame, model=None, **options):
    """Reconstruct a captured LDR frame into linear HDR; see :func:`hdrcam.api.reconstruct` (imported on first
    use, so ``import hdrcam`` stays light)."""
    from hdrcam.api import reconstruct as _reconstruct

    return _reconstruct(frame, model, **options)


__all__ = ["reconstruct", "__version__"]
