"""A small workspace made once for the fault-injection tests: brackets, a frame, a height map, a PSF."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hdrcam.cli import main


@dataclasses.dataclass(frozen=True)
class Workspace:
    root: Path
    bracket: Path  # 64 x 48 sim bracket of 3 frames, darks in bracket/darks
    pinholes: Path  # 192 x 160 pinhole bracket for calibrate, darks in pinholes/darks
    frame: Path  # 64 x 64 LDR EXR frame for reconstruct and destreak
    heightmap: Path  # 64 x 64 height-map EXR for fabricate
    psf: Path  # a measured PSF EXR (from calibrate) for finetune


def _hdrcam(*argv) -> None:
    assert main([str(a) for a in argv]) == 0, argv


@pytest.fixture(scope="session")
def workspace(tmp_path_factory) -> Workspace:
    from hdrcam.optics.heightmap import save_heightmap

    root = tmp_path_factory.mktemp("faults")
    small = ["--camera", "sim", "--profile", "simulated", "--psf", "dirac", "--darks"]
    _hdrcam("capture", "bracket", *small, "--size", "64x48", "--stops", "3", "--out", root / "bracket")
    _hdrcam("capture", "bracket", "--camera", "sim", "--profile", "simulated", "--darks", "--scene", "pinholes::40.6",
            "--size", "192x160", "--stops", "4", "--out", root / "pinholes")  # the DOE's PSF: a bare lens's
    # is too sharp for a 15 px fit from these few sources (it fitted 800 % negative red energy)
    _hdrcam("simulate", "night", "--psf", "dirac", "--size", "64", "64", "--out", root / "frame.exr")
    save_heightmap(root / "heightmap.exr", np.random.default_rng(0).uniform(0, 1.1e-6, (64, 64)), 32e-6)
    _hdrcam("calibrate", "psf", root / "pinholes", "--darks", root / "pinholes" / "darks", "--profile", "simulated",
            "--size", "15", "--out", root / "calibration")
    return Workspace(root, root / "bracket", root / "pinholes", root / "frame.exr", root / "heightmap.exr",
                     root / "calibration" / "psf.exr")


def command_lines(ws: Workspace, out: Path) -> dict[str, list]:
    """Every command, cheaply, writing under ``out``."""
    bracket, pinholes = ws.bracket, ws.pinholes
    return {
        "psf": ["psf", "--profile", "simulated", "--out", out],
        "fabricate": ["fabricate", ws.heightmap, "--profile", "simulated", "--out", out],
        "capture": ["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--psf", "dirac",
                    "--size", "64x48", "--stops", "2", "--out", out],
        "ingest": ["ingest", bracket, "--out", out],
        "fuse": ["fuse", bracket, "--darks", bracket / "darks", "--profile", "simulated", "--out", out / "fused.exr"],
        "calibrate": ["calibrate", "psf", pinholes, "--darks", pinholes / "darks", "--profile", "simulated",
                      "--size", "15", "--out", out],
        "simulate": ["simulate", "night", "--psf", "dirac", "--size", "64", "64", "--out", out / "frame.exr",
                     "--truth", out / "truth.exr"],
        "reconstruct": ["reconstruct", ws.frame, "--out", out],
        "destreak": ["destreak", ws.frame, "--out", out],
        "export": ["export", "--format", "torchscript", "--out", out / "model.pt"],
        "evaluate": ["evaluate", "--size", "32", "--count", "1", "--out", out],
        "design": ["design", "--psf", "dirac", "--steps", "1", "--crop", "32", "--batch", "1", "--out", out],
        "finetune": ["finetune", "--no-check", "--psf", ws.psf, "--steps", "1", "--crop", "32", "--batch", "1",
                     "--out", out],
    }


COMMANDS = ("psf", "fabricate", "capture", "ingest", "fuse", "calibrate", "simulate", "reconstruct", "destreak",
            "export", "evaluate", "design", "finetune")
