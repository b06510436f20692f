"""``hdrcam fabricate``: quantise a height map into lithography masks, with a report."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from hdrcam import __version__
from hdrcam.cli.arguments import add_profile_option, naming_input, positive_int
from hdrcam.errors import InputError
from hdrcam.io.atomic import atomic_paths, check_outputs, write_text_atomic
from hdrcam.profiles import load_profile

if TYPE_CHECKING:
    import numpy as np

    from hdrcam.optics.heightmap import FixedHeightMap


MASKS_MARK = ("white = etch: mask_b_of_k etches 2^(b-1) steps into the plate's top surface (the highest level), so "
              "each feature ends (levels - 1 - level) steps deep and the relief is the height map (heights above "
              "the deepest etch); rows and columns as in heightmap.exr and the simulated PSF. A measured PSF turned "
              "180 degrees from the simulated one means an inverted relief (the masks' tone reversed); a mirrored "
              "one, a plate mounted face-reversed")
MAX_LEVELS = 2 ** 16  # 16 binary masks; a level histogram of 2^40 bins alone would need 8 TB


def register(commands) -> None:
    parser = commands.add_parser("fabricate", help="quantise a height map into lithography masks",
                                 description=__doc__)
    parser.add_argument("heightmap", type=Path, help="height-map EXR (e.g. from 'hdrcam psf' or 'hdrcam design')")
    add_profile_option(parser)
    parser.add_argument("--levels", type=positive_int, default=None,
                        help="phase levels, a power of two (default: the profile's, 16 = 4 masks)")
    parser.add_argument("--out", type=Path, default=Path("fabrication"), help="output folder")
    parser.add_argument("--simulate", action="store_true",
                        help="also simulate the PSFs of the continuous and the quantised DOE and compare them")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.set_defaults(run=run)


def run(arguments: argparse.Namespace) -> int:
    import numpy as np

    from hdrcam.io.exr import write_exr
    from hdrcam.io.png import write_png
    from hdrcam.optics.fabrication import ideal_multilevel_efficiency, quantisation_strehl, quantise_heightmap
    from hdrcam.optics.heightmap import load_heightmap, save_heightmap
    from hdrcam.optics.materials import refractive_index

    profile = load_profile(arguments.profile)
    levels = arguments.levels or profile.doe.levels
    if levels < 2 or levels & (levels - 1) or levels > MAX_LEVELS:
        raise InputError(f"--levels must be a power of two from 2 to {MAX_LEVELS} ({MAX_LEVELS.bit_length() - 1} "
                         f"masks), got {levels}")
    masks_count = levels.bit_length() - 1
    outputs = {"heightmap": arguments.out / "heightmap_quantised.exr",
               "report_json": arguments.out / "report.json", "report_md": arguments.out / "report.md",
               **{f"mask{b}": arguments.out / f"mask_{b + 1}_of_{masks_count}.png" for b in range(masks_count)}}
    if arguments.simulate:
        outputs["psf"] = arguments.out / "psf_quantised.exr"
    check_outputs(outputs.values(), overwrite=arguments.overwrite, inputs=[arguments.heightmap])

    with naming_input(arguments.heightmap):
        source = load_heightmap(arguments.heightmap, profile.doe.aperture_m)
    heights = source.heights_m.numpy().astype(np.float64)
    try:
        quantised = quantise_heightmap(heights, profile.doe.h_max_m, levels)
    except ValueError as error:
        raise InputError(f"{arguments.heightmap}: {error}") from None
    wavelength = profile.doe.design_wavelength_m  # where h_max is one wave (the profile derives one from the other)
    phase_per_height = 2 * np.pi / wavelength * (float(refractive_index(profile.doe.material, wavelength)) - 1)
    report = {
        "hdrcam_version": __version__, "input": str(arguments.heightmap), "profile": profile.name,
        "levels": levels, "masks": masks_count, "feature_pitch_m": source.feature_pitch_m,
        "features": list(heights.shape), "h_max_m": profile.doe.h_max_m, "step_m": quantised.step_m,
        "max_height_m": float(quantised.heights_m.max()), "design_wavelength_m": wavelength,
        "mask_etch_depths_m": [quantised.step_m * 2 ** b for b in range(masks_count)],
        "masks_mark": MASKS_MARK,
        "ideal_multilevel_efficiency": ideal_multilevel_efficiency(levels),
        "quantisation_strehl_at_design_wavelength": quantisation_strehl(heights, quantised.heights_m, phase_per_height),
        "level_histogram": np.bincount(quantised.level_index.ravel(), minlength=levels).tolist(),
    }
    quantised_psf = None
    if arguments.simulate:
        comparison, quantised_psf = _compare_psfs(profile, source, quantised)
        report.update(comparison)

    with atomic_paths(outputs.values(), overwrite=arguments.overwrite) as temporaries:  # all of them, or none
        written = dict(zip(outputs, temporaries))
        save_heightmap(written["heightmap"], quantised.heights_m, source.feature_pitch_m, overwrite=True,
                       attributes={"levels": levels, "step_m": quantised.step_m})
        for bit, mask in enumerate(quantised.masks()):
            write_png(written[f"mask{bit}"], mask.astype(np.uint8) * 255, overwrite=True)
        write_text_atomic(written["report_json"], json.dumps(report, indent=2) + "\n", overwrite=True)
        write_text_atomic(written["report_md"], _markdown(report), overwrite=True)
        if quantised_psf is not None:
            write_exr(written["psf"], quantised_psf, attributes={"pixel_pitch_m": profile.camera.pixel_pitch_m},
                      overwrite=True)
    print(_markdown(report), end="")
    print(f"wrote {', '.join(str(p) for p in outputs.values())}")
    return 0


def _compare_psfs(profile, source: FixedHeightMap, quantised) -> tuple[dict, "np.ndarray"]:
    """The report's PSF comparison of the continuous and the quantised map, and the quantised PSF (H x W x 3)."""
    import torch

    from hdrcam.optics.psf import OpticalSetup, PsfSimulator

    setup = OpticalSetup.from_profile(profile)
    simulator = PsfSimulator(setup, source, dtype=torch.float32)
    with torch.no_grad():
        continuous = simulator()
        stepped = simulator(torch.as_tensor(quantised.heights_m, dtype=torch.float32))
    # L1 of the PSFs as fractions of the light through the aperture, not of the unit-sum crops: quantisation sends
    # light into orders far outside the window (1 +- levels k), which a comparison of unit-sum crops cannot see
    continuous_light = continuous.psf * continuous.crop_energy_fraction[:, None, None]
    stepped_light = stepped.psf * stepped.crop_energy_fraction[:, None, None]
    difference = (stepped_light - continuous_light).abs().sum(dim=(-2, -1))
    return {"psf_l1_difference_rgb": difference.tolist(),
            "crop_energy_fraction_continuous_rgb": continuous.crop_energy_fraction.tolist(),
            "crop_energy_fraction_quantised_rgb": stepped.crop_energy_fraction.tolist(),
            "centre_energy_fraction_continuous_rgb": continuous.centre_energy_fraction.tolist(),
            "centre_energy_fraction_quantised_rgb": stepped.centre_energy_fraction.tolist()}, \
        stepped.psf.numpy().transpose(1, 2, 0)


def _markdown(report: dict) -> str:
    lines = [f"# Fabrication report: {report['input']}", "",
             f"- {report['levels']} levels = {report['masks']} binary masks, step {report['step_m'] * 1e9:.2f} nm, "
             f"max height {report['max_height_m'] * 1e9:.2f} nm (h_max {report['h_max_m'] * 1e9:.1f} nm)",
             f"- {report['features'][0]} x {report['features'][1]} features at "
             f"{report['feature_pitch_m'] * 1e6:.3f} um",
             "- mask etch depths: " + ", ".join(f"{d * 1e9:.2f} nm" for d in report["mask_etch_depths_m"]),
             f"- masks: {report['masks_mark']}",
             f"- design wavelength (h_max = one wave): {report['design_wavelength_m'] * 1e9:.1f} nm",
             f"- ideal {report['levels']}-level efficiency sinc^2(1/N): {report['ideal_multilevel_efficiency']:.4f}",
             f"- quantisation Strehl of this map: {report['quantisation_strehl_at_design_wavelength']:.4f}"]
    if "psf_l1_difference_rgb" in report:
        lines.append("- PSF L1 difference quantised vs continuous, of the light through the aperture (R, G, B): "
                     + ", ".join(f"{v:.4f}" for v in report["psf_l1_difference_rgb"]))
        lines.append("- light inside the PSF window, continuous -> quantised (R, G, B): " + ", ".join(
            f"{a:.4f} -> {b:.4f}" for a, b in zip(report["crop_energy_fraction_continuous_rgb"],
                                                   report["crop_energy_fraction_quantised_rgb"])))
    return "\n".join(lines) + "\n"
