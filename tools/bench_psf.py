"""Benchmark the PSF simulation: time, peak memory and accuracy against a finer reference.

Each configuration runs in its own process so its peak resident memory is its own. Accuracy is the L1
distance (summed over pixels, mean over R, G, B; each PSF sums to 1 per channel, so 2 is the maximum)
between the configuration's sensor PSF and the reference configuration's, for the same seeded rank-1 DOE.

    .venv/bin/python tools/bench_psf.py                 # simulated profile sweep + A7 on a Fresnel grid
    .venv/bin/python tools/bench_psf.py --quick         # simulated profile only
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import statistics
import subprocess
import sys
import time

import numpy as np


def run_one(config: dict) -> dict:
    import torch

    from hdrcam.optics.heightmap import heightmap_for_doe
    from hdrcam.optics.psf import OpticalSetup, PsfSimulator
    from hdrcam.profiles import load_profile

    torch.set_num_threads(config.get("threads", 2))
    dtype = {"float32": torch.float32, "float64": torch.float64}[config["dtype"]]
    profile = load_profile(config["profile"])
    if "propagation" in config:  # samples per pixel set a grid: the A7 profile's own chirp-z has none
        profile = dataclasses.replace(profile, simulation=dataclasses.replace(profile.simulation,
                                                                              propagation=config["propagation"]))
    setup = OpticalSetup.from_profile(profile, upsample=config.get("upsample"),
                                      wavelengths_per_band=config.get("wavelengths_per_band"))
    heightmap = heightmap_for_doe(profile.doe, "rank1", seed=0, dtype=dtype)
    simulator = PsfSimulator(setup, heightmap, dtype=dtype)
    forward_s, backward_s = [], []
    for _ in range(config["repeats"]):
        started = time.perf_counter()
        with torch.no_grad():
            psf = simulator().psf
        forward_s.append(time.perf_counter() - started)
    if config.get("backward"):
        for _ in range(max(1, config["repeats"] // 2)):
            started = time.perf_counter()
            result = simulator()
            (result.psf.square().sum() + result.centre_energy_fraction.sum()).backward()
            backward_s.append(time.perf_counter() - started)
    return {**config, "grid": setup.grid.size, "pitch_um": setup.grid.pitch_m * 1e6,
            "forward_s": statistics.median(forward_s),
            "forward_backward_s": statistics.median(backward_s) if backward_s else None,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "psf": psf.double().numpy().tolist()}


def in_subprocess(config: dict) -> dict:
    output = subprocess.run([sys.executable, __file__, "--one", json.dumps(config)], check=True,
                            capture_output=True, text=True).stdout
    return json.loads(output.splitlines()[-1])


def sweep(quick: bool) -> list[tuple[str, list[dict], dict]]:
    simulated = dict(profile="simulated", dtype="float32", repeats=5)
    groups = [
        ("simulated: samples per pixel", [dict(simulated, upsample=u, backward=True) for u in (2, 3, 4, 6)],
         dict(simulated, upsample=8, repeats=1)),
        ("simulated: wavelengths per band", [dict(simulated, wavelengths_per_band=k) for k in (1, 3, 5)],
         dict(simulated, wavelengths_per_band=9, repeats=1)),
        ("simulated: precision", [dict(simulated, dtype="float32")], dict(simulated, dtype="float64", repeats=1)),
    ]
    if not quick:
        a7 = dict(profile="sony-a7-zeiss50-rank1", propagation="fresnel", dtype="float32", repeats=2)
        groups.append(("A7: samples per pixel", [dict(a7, upsample=3, backward=True)], dict(a7, upsample=4, repeats=1)))
    return groups


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--quick", action="store_true", help="simulated profile only")
    arguments = parser.parse_args()
    if arguments.one:
        print(json.dumps(run_one(json.loads(arguments.one))))
        return
    print("| group | setting | grid | pitch (um) | forward (s) | fwd+bwd (s) | peak RSS (MB) | L1 vs reference |")
    print("|---|---|---|---|---|---|---|---|")
    for title, configs, reference_config in sweep(arguments.quick):
        reference = in_subprocess(reference_config)
        reference_psf = np.array(reference["psf"])
        for result in [in_subprocess(c) for c in configs] + [reference]:
            error = np.abs(np.array(result["psf"]) - reference_psf).sum(axis=(1, 2)).mean()
            setting = ", ".join(f"{k}={result[k]}" for k in ("upsample", "wavelengths_per_band", "dtype") if k in result
                                and (k != "dtype" or "precision" in title))
            backward = f"{result['forward_backward_s']:.3f}" if result["forward_backward_s"] else "-"
            label = "reference" if result is reference else f"{error:.2e}"
            print(f"| {title} | {setting} | {result['grid']} | {result['pitch_um']:.3f} | {result['forward_s']:.3f} | "
                  f"{backward} | {result['peak_rss_mb']:.0f} | {label} |", flush=True)


if __name__ == "__main__":
    main()
