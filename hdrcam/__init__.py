"""hdrcam: snapshot HDR imaging with a learned rank-1 diffractive optical element.

Implements Sun, Tseng, Fu, Heidrich, Heide, "Learning Rank-1 Diffractive Optics for Single-shot High
Dynamic Range Imaging", CVPR 2020. Linear light and SI units throughout (see DESIGN.md).
"""

__version__ = "0.1.0"
