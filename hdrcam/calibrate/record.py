"""Write a calibration record: NAME/psf.exr, NAME/record.json and NAME/psf.png (issue 4)."""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import numpy as np

from hdrcam.calibrate.effective_psf import green_centroid_offset
from hdrcam.calibrate.psf_calibration import PsfCalibration, SourceSize
from hdrcam.capture.manifest import sha256_of, software_versions
from hdrcam.io.atomic import atomic_paths, write_text_atomic
from hdrcam.io.exr import write_exr
from hdrcam.io.png import write_png
from hdrcam.optics.psf_file import PSF_UNITS
from hdrcam.preview import log_psf_rgb, radial_profile_plot, side_by_side
from hdrcam.profiles import Profile

RECORD_FORMAT = "hdrcam-psf-calibration/1"
OUTPUT_NAMES = ("psf.exr", "record.json", "psf.png")


def record_document(calibration: PsfCalibration, profile: Profile, command: str) -> dict:
    fit = calibration.fit
    mean_position = fit.positions_px.mean(axis=0)
    return {
        "format": RECORD_FORMAT,
        "created": dt.datetime.now().isoformat(timespec="seconds"),
        "command": command,
        "profile": profile.name,
        "camera_model": calibration.frames[0].metadata.camera_model,
        "pixel_pitch_m": profile.camera.pixel_pitch_m,
        "colour": "camera RGB",
        "inputs": {"frames": [_file_entry(f.metadata.path, f.metadata.exposure_s) for f in calibration.frames],
                   "darks": [_file_entry(d.metadata.path, d.metadata.exposure_s) for d in calibration.darks or []]},
        "merge": {"estimated_exposures_s": [float(t) for t in calibration.merge.exposures_s],
                  "clip_level_dn": float(calibration.merge.clip_level_dn), "notes": calibration.merge.notes},
        "method": "joint least-squares fit of PSF, positions and brightnesses on the Bayer samples of all point "
                  "sources (box-model sub-pixel shift); hot pixels and samples clipped in every frame left out",
        "psf_size_px": int(calibration.psf.shape[-1]),
        "fitted_size_px": int(fit.psf.shape[-1]),
        "energy_in_crop": [float(e) for e in calibration.energy_in_crop],
        "sources_used": len(calibration.windows),
        "sources_rejected": calibration.rejected_sources,
        "hot_pixels": calibration.hot_pixels,
        "centroid_px": {"mean_y": float(mean_position[0]), "mean_x": float(mean_position[1]),
                        "sources_yx": [[round(float(y), 4), round(float(x), 4)] for y, x in fit.positions_px]},
        "green_centroid_offset_px": list(green_centroid_offset(calibration.psf)),
        "background_per_channel": [float(b) for b in calibration.background],
        "peak_snr_per_channel": [float(s) for s in calibration.peak_snr],
        "reduced_chi2": fit.reduced_chi2,
        "outlier_samples_left_out": fit.outlier_samples,
        "negative_energy_clipped": [float(n) for n in fit.negative_energy],
        "source": _source_entry(calibration.source),
        "units": "PSF: fraction of each channel's energy per pixel (unit sum); background: relative radiance",
        "software": software_versions(),
    }


def _source_entry(source: SourceSize | None) -> dict:
    """The point source's size and its geometric image on the sensor, or that it was not given."""
    if source is None:
        return {"given": False, "image_px": None,
                "note": "source diameter not given (--source-diameter-mm): its image size was not checked"}
    return {"given": True, "diameter_m": source.diameter_m, "distance_m": source.distance_m,
            "distance_from": "given" if source.distance_given else "profile calibration.point_source_distance_m",
            "image_px": source.image_px, "largest_within_one_pixel_m": source.largest_within_pixel_m,
            "units": "metres; image_px: geometric (thin-lens) image diameter in pixels"}


def _file_entry(path: Path, exposure_s: float) -> dict:
    return {"file": str(path), "sha256": sha256_of(path), "exposure_s": exposure_s}


def write_record(folder: Path, calibration: PsfCalibration, profile: Profile, command: str, *,
                 overwrite: bool = False) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    psf = calibration.psf
    document = record_document(calibration, profile, command)
    paths = [folder / name for name in OUTPUT_NAMES]
    panels = [log_psf_rgb(np.repeat(psf[c:c + 1], 3, axis=0)) for c in range(3)]
    with atomic_paths(paths, overwrite=overwrite) as (exr, record, preview):  # all three, or none
        write_exr(exr, psf.transpose(1, 2, 0).astype(np.float32),
                  attributes={"pixel_pitch_m": profile.camera.pixel_pitch_m, "colour": "camera RGB",
                              "units": PSF_UNITS, "record": RECORD_FORMAT}, overwrite=True)
        write_text_atomic(record, json.dumps(document, indent=1) + "\n", overwrite=True)
        write_png(preview, side_by_side(panels + [radial_profile_plot(psf)]), overwrite=True)
    return paths
