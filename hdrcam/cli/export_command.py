"""``hdrcam export``: a checkpoint's network as TorchScript or ONNX for deployment."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from hdrcam.io.atomic import check_writable


def register(commands) -> None:
    parser = commands.add_parser("export", help="export a network for deployment (ONNX, TorchScript)",
                                 description=__doc__)
    parser.add_argument("--checkpoint", type=Path, default=None, help="default: the shipped one")
    parser.add_argument("--format", choices=("onnx", "torchscript"), required=True)
    parser.add_argument("--out", type=Path, required=True, help="output file (.onnx or .pt)")
    parser.add_argument("--vgg-weights", type=Path, default=None)
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.recon.export import export_onnx, export_torchscript
    from hdrcam.train.checkpoint import load_model

    check_writable(arguments.out, overwrite=arguments.overwrite)
    model = load_model(arguments.checkpoint, vgg_weights=arguments.vgg_weights)
    if arguments.format == "onnx":
        metadata = {"hdrcam_psf": json.dumps(model.psf.tolist()), "hdrcam_profile": model.profile,
                    "hdrcam_preset": model.preset, "hdrcam_checkpoint": str(model.source)}
        export_onnx(model.network, arguments.out, metadata, overwrite=arguments.overwrite)
    else:
        export_torchscript(model.network, arguments.out, overwrite=arguments.overwrite)
    print(json.dumps({"format": arguments.format, "out": str(arguments.out), "checkpoint": str(model.source),
                      "bytes": arguments.out.stat().st_size}))
    return 0
