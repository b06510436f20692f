"""``hdrcam export``: a checkpoint's network as TorchScript or ONNX for deployment."""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

from hdrcam.errors import InputError
from hdrcam.io.atomic import check_outputs

# --format -> the --out suffixes it may write; reconstruct reads a .onnx file as ONNX and anything else as torch
SUFFIXES = {"onnx": (".onnx",), "torchscript": (".pt", ".pth")}


def register(commands) -> None:
    parser = commands.add_parser("export", help="export a network for deployment (ONNX, TorchScript)",
                                 description=__doc__)
    parser.add_argument("--checkpoint", type=Path, default=None, help="default: the shipped one")
    parser.add_argument("--format", choices=tuple(SUFFIXES), required=True)
    parser.add_argument("--out", type=Path, required=True,
                        help="output file: .onnx for onnx, .pt or .pth for torchscript")
    parser.add_argument("--vgg-weights", type=Path, default=None)
    parser.add_argument("--overwrite", action="store_true")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    from hdrcam.recon.export import export_onnx, export_torchscript
    from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, load_model, partner_checkpoint

    suffixes = SUFFIXES[arguments.format]
    if arguments.out.suffix.lower() not in suffixes:
        raise InputError(f"--out {arguments.out}: a --format {arguments.format} file is named "
                         f"{' or '.join('NAME' + suffix for suffix in suffixes)}")
    inputs = [arguments.checkpoint or SHIPPED_CHECKPOINT] + ([arguments.vgg_weights] if arguments.vgg_weights else [])
    check_outputs([arguments.out], overwrite=arguments.overwrite, inputs=inputs)
    model = load_model(arguments.checkpoint, vgg_weights=arguments.vgg_weights)
    if model.fixed_psf == "windshield":  # its export would be the HDR estimate, not the streak-free image destreak uses
        raise InputError(f"{model.source}: a windshield network (design --psf windshield): destreak runs it from this "
                         f"checkpoint (hdrcam destreak --method network --checkpoint {model.source}); export writes "
                         "highlight-reconstruction networks")
    if arguments.format == "onnx":
        metadata = {"hdrcam_psf": json.dumps(model.psf.tolist()), "hdrcam_profile": model.profile,
                    "hdrcam_preset": model.preset, "hdrcam_checkpoint": str(model.source),
                    **({"hdrcam_fixed_psf": model.fixed_psf} if model.fixed_psf else {})}
        export_onnx(model.network, arguments.out, metadata, overwrite=arguments.overwrite)
    else:
        export_torchscript(model.network, arguments.out, overwrite=arguments.overwrite)
    partner = partner_checkpoint(Path(model.source))
    if partner.is_file() and not Path(model.source).stem.endswith("-partner"):
        why = "for reconstruct's results (it reads both ONNX files)" if arguments.format == "onnx" else \
            "to run both as reconstruct does (reconstruct itself reads checkpoints and ONNX files, not TorchScript)"
        warnings.warn(f"{model.source} has a partner, {partner.name}, which reconstruct runs beside it (keeping what "
                      f"both paint); this export holds the checkpoint alone. Export the partner too, as "
                      f"{partner_checkpoint(arguments.out).name} beside {arguments.out.name}, {why}: "
                      f"hdrcam export --checkpoint {partner} --format {arguments.format} --out "
                      f"{partner_checkpoint(arguments.out)}")
    print(json.dumps({"format": arguments.format, "out": str(arguments.out), "checkpoint": str(model.source),
                      "bytes": arguments.out.stat().st_size}))
    return 0
