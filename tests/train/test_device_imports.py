"""Training runs where only torch, numpy, scipy, OpenCV, tqdm (and OpenEXR) are installed, as on a lent GPU
machine (tools/gpu/train.sh): neither ``finetune`` nor ``design`` may import rawpy, colour-science, pyusb, ONNX,
OpenVINO or tifffile - here made absent by an import hook in a fresh process - on photographs that include a
luminance-chroma EXR (which once needed colour-science), an EXR in ACES primaries and a Radiance file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import OpenEXR
import pytest

from tests.train.test_finetune_partner import MEASURED_PSF

ABSENT = ("rawpy", "colour", "colour_demosaicing", "usb", "openvino", "onnx", "onnxruntime", "onnxscript", "tifffile")
RUNNER = f'''
import importlib.abc, importlib.machinery, runpy, sys

class Absent(importlib.abc.Loader):
    def create_module(self, spec):
        raise ModuleNotFoundError(f"No module named {{spec.name!r}}", name=spec.name)

    def exec_module(self, module):
        pass

class Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        return importlib.machinery.ModuleSpec(name, Absent()) if name.split(".")[0] in {ABSENT!r} else None

sys.meta_path.insert(0, Finder())
sys.argv = ["hdrcam"] + sys.argv[1:]
runpy.run_module("hdrcam", run_name="__main__")
'''


@pytest.mark.parametrize("command", [
    ["finetune", "--psf", str(MEASURED_PSF), "--no-partner"],
    ["design", "--profile", "simulated", "--doe", "rank1", "--preset", "fast"],
])
def test_training_imports_nothing_a_gpu_machine_lacks(command, tmp_path):
    photographs = tmp_path / "photographs"
    photographs.mkdir()
    rgb = np.random.default_rng(0).uniform(0.05, 6.0, (96, 96, 3))
    luminance = rgb @ np.array([0.2126, 0.7152, 0.0722])
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {
        "Y": luminance.astype(np.float32), "RY": ((rgb[..., 0] - luminance) / luminance).astype(np.float32),
        "BY": ((rgb[..., 2] - luminance) / luminance).astype(np.float32)}).write(str(photographs / "yc.exr"))
    OpenEXR.File({"type": OpenEXR.scanlineimage, "chromaticities": (0.7347, 0.2653, 0.0, 1.0, 0.0001, -0.077, 0.32168,
                                                                    0.33767)},  # ACES AP0, converted on reading
                 {"RGB": rgb.astype(np.float32)}).write(str(photographs / "aces.exr"))
    cv2.imwrite(str(photographs / "radiance.hdr"), rgb.astype(np.float32))
    (tmp_path / "runner.py").write_text(RUNNER)
    arguments = [*command, "--steps", "1", "--crop", "64", "--batch", "1",
                 "--data", f"{photographs}:0.5,procedural:0.5", "--out", str(tmp_path / "run")]
    root = Path(__file__).resolve().parents[2]
    environment = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")]))}
    result = subprocess.run([sys.executable, str(tmp_path / "runner.py"), *arguments], capture_output=True, text=True,
                            timeout=300, cwd=root, env=environment)
    assert result.returncode == 0, result.stderr[-2000:]
    assert (tmp_path / "run" / "model.pt").is_file()
