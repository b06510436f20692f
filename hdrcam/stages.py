"""The stages of the user story as Python functions: capture a bracket, fuse it, calibrate the PSF, design or
fine-tune the network, evaluate checkpoints (reconstruction is :func:`hdrcam.api.reconstruct`). ``hdrcam`` re-exports
them; the command line calls the same functions and only parses arguments and writes files.

    import hdrcam
    bracket, _ = hdrcam.capture_bracket("bracket", camera="sim", profile="simulated", scene="night")
    image = hdrcam.fuse(["bracket"], profile="simulated")     # image.rgb: H x W x 3 relative radiance
    calibration = hdrcam.calibrate_psf(["pinholes"], profile="simulated", darks="pinholes/darks")

Units: SI (seconds, metres); images are float32 H x W x 3 numpy arrays in linear light. Nothing heavy is
imported before a function runs (torch only where a network or an optical simulation runs: design, finetune,
evaluate, and capture_bracket's simulated camera).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from hdrcam.profiles import DEFAULT_PROFILE
from hdrcam.train.run_options import recorded_data, recorded_file

if TYPE_CHECKING:
    from hdrcam.calibrate.psf_calibration import PsfCalibration
    from hdrcam.capture.manifest import Bracket
    from hdrcam.evaluate.scoring import Example, ScoredImage
    from hdrcam.hdr.fuse import FusedImage


def capture_bracket(out: str | Path, *, camera: str = "sim", profile: str = DEFAULT_PROFILE,
                    shortest_s: float = 1 / 4000, stops: int | None = None, ev_step: float | None = None,
                    iso: float = 100.0, auto: bool = False, roi: tuple[int, int, int, int] | None = None,
                    darks: bool = False, scene: str = "point", psf: str = "doe", size_px: tuple[int, int] | None = None,
                    seed: int = 0, hot_pixel_fraction: float = 2e-5, exposure_error: float = 0.02,
                    resume: bool = False, show_progress: bool = False,
                    log: Callable[[str], None] | None = None) -> tuple["Bracket", "Bracket | None"]:
    """Shoot an exposure bracket of RAW frames into the new folder ``out`` (frames + bracket.json).

    ``camera``: ``sim`` (simulated A7), ``sim-usb`` (the USB code path against an emulated A7) or ``usb`` (a
    Sony A7 in PC-remote mode). Exposures: ``stops`` frames ``ev_step`` EV apart from ``shortest_s`` seconds
    (defaults: the profile's calibration plan), at ``iso`` (one of the camera's settings, 100 ... 25600 in 1/3 EV
    steps); ``auto`` takes only the exposures the region ``roi`` (x, y, width, height in pixels) needs. A plan the
    camera cannot take is refused (InputError) before anything is written. ``darks``: dark frames at the same
    exposures in out/darks. Simulated cameras: ``scene`` (point[:POWER], pinholes[:POWER[:SPACING]], night,
    flat[:LEVEL] or an EXR in relative radiance), ``psf`` (doe, dirac or an EXR), ``size_px`` (width, height in
    pixels, at least 22 each: LibRaw's smallest RAW; default: the profile's sensor), ``seed``,
    ``hot_pixel_fraction`` (of all pixels) and ``exposure_error`` (largest relative error of a true shutter time).
    A folder that holds a capture is never overwritten (OutputExistsError); ``resume`` continues an incomplete
    one instead, keeping the frames on disk (InputError when it is complete).
    ``log`` receives one line per event (the camera, each frame, the time taken, the bracket's notes).
    Returns the bracket and the dark bracket (or None).
    """
    import time

    from hdrcam.capture.backends import SIMULATED_MIN_SIDE_PX, open_camera
    from hdrcam.capture.bracket import BracketCapture, BracketPlan
    from hdrcam.capture.manifest import MANIFEST_NAME, load_bracket, sha256_of
    from hdrcam.capture.notches import nearest_shutter
    from hdrcam.capture.scene import load_scene, pinhole_spacing_for
    from hdrcam.capture.simulated import check_defect_settings, simulation_psf
    from hdrcam.errors import InputError, OutputExistsError
    from hdrcam.profiles import load_profile

    say = log or (lambda line: None)
    for name, value in (("shortest_s", shortest_s), ("ev_step", ev_step), ("iso", iso)):
        if isinstance(value, str):  # the command line's spelling: a TypeError deep in the plan
            raise InputError(f"capture_bracket's {name} is a number (e.g. 1 / 4000), not the string {value!r}")
    if size_px is not None:
        try:
            size_px = tuple(int(side) for side in size_px) if not isinstance(size_px, str) else ()
        except (TypeError, ValueError):  # a number alone, a side that is no number
            size_px = ()
        if len(size_px) != 2:
            raise InputError("capture_bracket's size_px is (width, height) in whole pixels")
    if roi is not None and not auto:  # it would be taken and ignored: the plan is the fixed bracket
        raise InputError("--roi (roi) is the region --auto meters: give --auto (auto=True) with it, or leave it out")
    check_defect_settings(hot_pixel_fraction, exposure_error)  # before the folder is claimed
    chosen = load_profile(profile)
    folder = Path(out)
    lights_manifest, darks_manifest = folder / MANIFEST_NAME, folder / "darks" / MANIFEST_NAME
    saved = saved_darks = None
    if resume:
        saved = load_bracket(lights_manifest)
        saved_darks = load_bracket(darks_manifest) if darks_manifest.exists() else None
        darks_status = saved_darks.status if saved_darks else None
        darks_pending = darks_status == "incomplete" or (saved.options.get("darks") and darks_status is None)
        if saved.status == "complete" and not darks and darks_pending:
            raise InputError(f"--resume: {lights_manifest} was started with --darks and its darks are not "
                             "complete; resume with --darks too")
        if saved.status == "complete" and (not darks or darks_status == "complete"):
            raise InputError(f"{folder}: the capture is complete; nothing to resume")
    else:
        for manifest in (lights_manifest, darks_manifest):
            if manifest.exists():
                raise OutputExistsError(f"{manifest} exists: a capture is never overwritten; choose another --out "
                                        "(or pass --resume to continue an incomplete one)")
    plan = BracketPlan(shortest_s=shortest_s, stops=chosen.calibration.stops if stops is None else stops,
                       ev_step=chosen.calibration.ev_step if ev_step is None else ev_step, iso=iso, auto=auto, roi=roi,
                       target_snr=chosen.calibration.target_snr, snr_percentile=chosen.calibration.snr_percentile)
    rendered = kernel = None
    width, height = size_px if size_px is not None and camera != "usb" else \
        (chosen.camera.width_px, chosen.camera.height_px)
    plan.check_roi_fits(width, height)  # before the folder is claimed (a real body's frame: its profile's size)
    if camera != "usb":
        if min(width, height) < SIMULATED_MIN_SIDE_PX:
            raise InputError(f"--size {width}x{height}: LibRaw opens no RAW frame smaller than {SIMULATED_MIN_SIDE_PX} "
                             f"px on a side; use --size {max(width, SIMULATED_MIN_SIDE_PX)}x"
                             f"{max(height, SIMULATED_MIN_SIDE_PX)} or larger")
        kernel = simulation_psf(chosen, psf)  # the DOE is part of the camera, not of the seed
        rendered = load_scene(scene, height, width, seed=seed, pinhole_spacing_px=pinhole_spacing_for(kernel.shape[-1]))
    device, simulated = open_camera(camera, chosen, scene=rendered, psf=kernel, seed=seed,
                                    hot_pixel_fraction=hot_pixel_fraction, exposure_error=exposure_error)
    options = {"scene": rendered.description if rendered else None, "psf": psf if rendered else None, "seed": seed,
               "profile_sha256": sha256_of(chosen.path), **({"darks": True} if darks else {})}
    truth = simulated.true_exposure_s if simulated else None
    started, shot, dark_bracket = time.perf_counter(), 0, None
    with device:
        say(f"camera: {device.model} ({camera}); profile {chosen.name}")
        lights = BracketCapture(device, chosen.camera, folder, backend=camera, profile=chosen.name, options=options,
                                true_exposure_s=truth, show_progress=show_progress)
        if saved is not None and saved.status == "complete":
            lights.check_same_request(saved, plan)  # darks only for lights shot as this run would shoot them
            bracket = saved
        else:
            kept = len(saved.frames) if saved else 0  # before shoot(), which goes on adding to ``saved``
            bracket = lights.shoot(plan, resume=saved)
            shot += len(bracket.frames) - kept
        _log_frames(say, bracket, folder)
        if darks:
            notches = [nearest_shutter(frame.exposure_s) for frame in bracket.frames]
            kept = len(saved_darks.frames) if saved_darks else 0
            dark_bracket = BracketCapture(device, chosen.camera, folder / "darks", backend=camera,
                                          profile=chosen.name, options=options, true_exposure_s=truth,
                                          show_progress=show_progress).shoot(plan, dark_notches=notches,
                                                                             resume=saved_darks)
            shot += len(dark_bracket.frames) - kept
            _log_frames(say, dark_bracket, folder / "darks")
    seconds = time.perf_counter() - started
    say(f"{shot} frames in {seconds:.1f} s ({seconds / max(shot, 1):.2f} s per frame) -> {lights_manifest}")
    for note in bracket.notes:
        say(f"note: {note}")
    return bracket, dark_bracket


def _log_frames(say: Callable[[str], None], bracket: "Bracket", folder: Path) -> None:
    for frame in bracket.frames:
        say(f"  {folder / frame.file}  {frame.exposure_label:>7} ({frame.exposure_s:g} s)  ISO {frame.iso:g}  "
            f"f/{'?' if frame.f_number is None else f'{frame.f_number:g}'}")


def fuse(bracket: str | Path | list[str | Path], *, profile: str = DEFAULT_PROFILE, darks: str | Path | None = None,
         camera_rgb: bool = False, with_variance: bool = False, demosaic: str = "bilinear",
         bad_pixels: str | Path | None = None) -> "FusedImage":
    """Merge a RAW bracket into linear HDR (nothing is written).

    ``bracket``: a bracket.json, a folder of RAW files, or the RAW files. ``profile``: the capture profile
    whose sensor noise (full well, read noise) weights the merge. ``darks``: dark frames (bracket.json or
    folder) to subtract instead of the black level. ``camera_rgb``: keep camera RGB (default: linear sRGB,
    D65). ``demosaic``: ``bilinear`` (fast) or ``menon2007`` (sharper, slower). ``bad_pixels``: a dcraw list of
    the sensor's defects (from :func:`find_bad_pixels` and hdrcam.io.bad_pixels.write_bad_pixels), repaired in
    the merged mosaic. Returns a FusedImage: ``rgb``
    (H x W x 3 float32, relative radiance = full wells per second at ISO 100), ``clipped`` (H x W bool: a
    lower bound), ``variance`` (with ``with_variance``) and the merge's exposure estimates.
    """
    from hdrcam.hdr.fuse import fuse as fuse_bracket
    from hdrcam.io.bad_pixels import read_bad_pixels
    from hdrcam.profiles import load_profile

    return fuse_bracket(_sources(bracket), load_profile(profile).camera,
                        darks=Path(darks) if darks else None, camera_rgb=camera_rgb, with_variance=with_variance,
                        demosaic_method=demosaic, bad_pixels=read_bad_pixels(bad_pixels) if bad_pixels else None)


def calibrate_psf(bracket: str | Path | list[str | Path], *, profile: str = DEFAULT_PROFILE,
                  darks: str | Path | None = None, bad_pixels: str | Path | None = None,
                  size_px: int | None = None, energy_fraction: float | None = None,
                  source_diameter_m: float | None = None, source_distance_m: float | None = None
                  ) -> "PsfCalibration":
    """Measure the PSF from a point-source (best: pinhole-array) bracket, on the Bayer data.

    ``size_px``: the odd PSF size in pixels (default: the profile's); ``energy_fraction``: crop to the smallest
    size holding this fraction of every channel's energy. ``darks`` locate hot pixels; ``bad_pixels`` (a dcraw
    list) names more, left out alike. ``source_diameter_m``: the
    point source's (pinhole's) diameter in metres, at ``source_distance_m`` metres from the lens (default: the
    profile's calibration.point_source_distance_m); its geometric image is warned about when wider than 1 px and
    refused when wider than ``size_px`` (hdrcam.calibrate.psf_calibration.check_source_size). Returns the
    calibration: ``psf`` (3 x S x S float, camera RGB, each channel summing to 1, optical axis at S // 2),
    per-source fits, energy in the crop, the fit's reduced chi^2 and ``source`` (the source's image size in
    pixels, ``image_px``; None without a diameter).
    """
    from hdrcam.calibrate.psf_calibration import calibrate_psf as calibrate
    from hdrcam.calibrate.psf_calibration import source_size
    from hdrcam.io.bad_pixels import read_bad_pixels
    from hdrcam.profiles import load_profile

    chosen = load_profile(profile)
    source = source_size(source_diameter_m, source_distance_m, chosen)
    return calibrate(_sources(bracket), chosen.camera, darks=Path(darks) if darks else None,
                     size_px=chosen.simulation.psf_size_px if size_px is None else size_px,
                     energy_fraction=energy_fraction, source=source,
                     bad_pixels=read_bad_pixels(bad_pixels) if bad_pixels else None)


def _sources(bracket: "str | Path | list[str | Path]") -> list[Path]:
    """A bracket given as one path (a folder, a bracket.json, a file) or as a list of them."""
    return [Path(bracket)] if isinstance(bracket, (str, os.PathLike)) else [Path(source) for source in bracket]


def design(out: str | Path, *, preset: str | None = None, profile: str | None = None, doe: str | None = None,
           psf: str | None = None, init: str | Path | None = None, data: str | None = None, steps: int | None = None,
           batch: int | None = None, crop_px: int | None = None, learning_rate: float | None = None,
           seed: int | None = None, checkpoint_every: int | None = None, precision: str | None = None,
           channels_last: bool | None = None, resume: bool = False, vgg_weights: str | Path | None = None,
           random_vgg: bool = False, device: str = "auto", quiet: bool = False, data_workers: int | None = None,
           init_doe: str | Path | None = None, linear_gain_weight: float | None = None) -> dict:
    """Train the reconstruction network and (with ``doe`` rank1 or freeform, the default) the DOE end to end.

    ``psf`` (dirac, star8, dual-peak, windshield or a PSF EXR) instead trains the network alone behind a fixed
    PSF. ``init``: start the network from this checkpoint's weights (same preset); ``init_doe``: start the DOE
    from this checkpoint's trained DOE (same kind, same feature grid: e.g. a PSF-first design). ``data``:
    procedural (the default), a folder of EXR/.hdr photographs, or SOURCE:WEIGHT,... . ``steps`` (default 1000)
    Adam steps of ``batch`` (4) crops of ``crop_px`` (128) pixels, a multiple of 16; ``learning_rate`` of the
    network (1e-3, polynomial decay); ``preset`` fast, ``profile`` simulated, ``seed`` 0. ``precision``
    (float32, bfloat16, float16 on CUDA) and ``channels_last`` set the network's forward; ``data_workers`` CPU
    threads draw scenes ahead (hdrcam.train.design). Writes the run folder ``out`` (config, log, checkpoint.pt every
    ``checkpoint_every`` (100) steps, and model.pt at the end). ``resume`` continues it: options left as None
    take the run's own values, options given must match them (InputError), except ``steps``, which may grow.
    ``random_vgg``: random VGG-19 features for the ``paper`` preset (tests only). ``linear_gain_weight``
    (default 0): weight per dB of the loss term that is minus each scene's linear-PSNR gain over its captured
    frame (hdrcam.recon.losses.linear_gain_loss). Returns the last logged step (losses, seconds).
    """
    from hdrcam.errors import missing_input
    from hdrcam.train.choices import FIXED_PSFS

    if psf and psf not in FIXED_PSFS and not Path(psf).is_file():
        raise missing_input(psf, f"one of {', '.join(FIXED_PSFS)} or a PSF (EXR file)", option="--psf",
                            missing=f"--psf {psf}: not one of {', '.join(FIXED_PSFS)} and no such file")
    for option, path in (("--init", init), ("--init-doe", init_doe)):
        if path is not None and not Path(path).is_file():
            raise missing_input(path, "a checkpoint file", option=option, missing=f"{option} {path} does not exist")
    given = _given(preset=preset, profile=recorded_file(profile), data=recorded_data(data), steps=steps,
                   batch=batch, crop_px=crop_px, learning_rate=learning_rate, seed=seed,
                   checkpoint_every=checkpoint_every, precision=precision, channels_last=channels_last,
                   init_checkpoint=recorded_file(init), init_doe_checkpoint=recorded_file(init_doe),
                   weights=_loss_weights(linear_gain_weight))
    if psf:
        given.update(psf=recorded_file(psf), doe=None)
    elif doe:
        given.update(doe=doe, psf=None)
    return _train(out, {"steps": 1000}, given, resume=resume, vgg_weights=vgg_weights, random_vgg=random_vgg,
                  device=device, quiet=quiet, data_workers=data_workers)


def finetune(psf: str | Path | None, out: str | Path, *, checkpoint: str | Path | None = None, data: str | None = None,
             steps: int | None = None, batch: int | None = None, crop_px: int | None = None,
             learning_rate: float | None = None, seed: int | None = None, checkpoint_every: int | None = None,
             precision: str | None = None, channels_last: bool | None = None, resume: bool = False,
             vgg_weights: str | Path | None = None, random_vgg: bool = False, device: str = "auto",
             quiet: bool = False, data_workers: int | None = None, partner: bool | None = None,
             check: str | Path | None = "procedural", check_size_px: int = 256,
             linear_gain_weight: float | None = None) -> dict:
    """Fine-tune a checkpoint's network (default: the shipped one), not its DOE, behind a measured PSF (e.g.
    calibration/NAME/psf.exr). Options as :func:`design`; a new run defaults to 200 steps and a gentler
    learning rate (2e-4: the network already works). Writes the run folder ``out`` (model.pt at the end).
    ``psf`` may be None with ``resume``: the run's own PSF file.

    ``partner`` (None: true for a new run, a resumed run's own choice): when the starting checkpoint NAME.pt has
    a partner NAME-partner.pt beside it (a second network trained behind the same PSF, which reconstruct runs
    with it; the shipped checkpoint has one),
    the partner is fine-tuned next, from its own weights with the same options (PSF, data, steps, batch, crop,
    learning rate, precision; seed + 1, so that it draws other batches than its model), in the run folder
    ``out``/partner, and its final network is written atomically to ``out``/model-partner.pt, where reconstruct
    finds it beside ``out``/model.pt; training takes twice as long. A partner trained behind another PSF than
    its checkpoint is refused (InputError) before any training; a new run never replaces an existing
    model-partner.pt or partner run. ``resume`` continues each run folder on its own: a run stopped while its
    partner trained continues the partner (from step 0 when it had saved no checkpoint yet) without training
    the finished main network again, and follows the choice the run was started with (InputError for the other
    one; runs saved before the choice was recorded train a partner unless ``partner`` is False). Returns
    the main run's last logged step (losses, seconds; {} when the main run had already finished);
    ``hdrcam.stages.finetuned_partner(out)`` names the partner written.

    ``check`` (unless None; in a call that trained, or that finds the finished run unchecked): the fine-tuned
    networks are scored against the ones the run started from on 8 held-out test scenes of ``check``
    ("procedural", or a folder of photographs kept out of ``data``), ``check_size_px`` px, captured behind the
    run's PSF; where they score lower the run falls back:
    ``out``/model.pt (model-partner.pt) holds the start networks behind that PSF and the fine-tuned ones are
    kept as model-finetuned.pt (model-finetuned-partner.pt). ``out``/check.json records it
    (hdrcam.train.finetune_check; ``hdrcam.stages.finetune_check_record(out)`` reads it)."""
    from hdrcam.errors import InputError, missing_input
    from hdrcam.train.checkpoint import SHIPPED_CHECKPOINT, partner_checkpoint, read_checkpoint
    from hdrcam.train.config import read_run_config
    from hdrcam.train.design import RUN_FILES

    out = Path(out)
    partner = _partner_choice(out, partner) if resume else partner is not False
    if psf is not None and not isinstance(psf, (str, Path)):  # a run records its PSF's path, to resume behind it
        raise InputError(f"finetune's psf is a file, not a {type(psf).__name__}: give the psf.exr `hdrcam calibrate "
                         "psf` writes (calibrate_psf returns the PSF in memory only)")
    start = Path(checkpoint).resolve() if checkpoint else SHIPPED_CHECKPOINT
    state = read_checkpoint(start)
    partner_run, partner_model = out / PARTNER_RUN, partner_checkpoint(out / "model.pt")
    recorded_psf_gone = False  # resumed behind the PSF its checkpoints hold (a run folder copied elsewhere)
    if psf is None:
        if not resume:
            raise InputError("finetune needs --psf, the measured PSF to train behind (e.g. calibration/NAME/psf.exr)")
        psf = _run_psf(out)
        recorded_psf_gone = not Path(psf).is_file()
        runs_to_start = [run for run, needed in ((out, True), (partner_run, partner))
                         if needed and not (run / "checkpoint.pt").is_file()]
        if recorded_psf_gone and runs_to_start:  # a run with no checkpoint yet trains behind the file itself
            raise InputError(f"the PSF {out} was fine-tuned behind ({psf}, its config.json) is gone and "
                             f"{runs_to_start[0]} saved no checkpoint holding it; give it, or a copy of it, with --psf")
    if not recorded_psf_gone and Path(psf).is_dir() and (Path(psf) / "psf.exr").is_file():
        raise InputError(f"--psf {psf} is a folder; give the PSF inside it: {Path(psf) / 'psf.exr'}")
    if not recorded_psf_gone and not Path(psf).is_file():
        raise missing_input(psf, "a PSF (EXR file)", option="--psf", missing=f"--psf {psf} does not exist")
    if not resume and (partner_model.exists() or any((partner_run / name).exists() for name in RUN_FILES)):
        raise InputError(f"{out} already holds a run; pass --resume to continue it or choose another --out")
    partner_resumes = partner and resume and (partner_run / "checkpoint.pt").is_file()
    partner_start = partner_state = None
    # the config the main run saved before this call (resuming a run whose partner has not started yet)
    saved_config = _saved_config(out) if partner and not partner_resumes and resume else None
    if partner and not partner_resumes:  # checked before any training
        began = _run_start(saved_config) if not checkpoint else None
        partner_start, partner_state = _checked_partner(*(began or (start, state)))
    new_run = {"preset": state["preset"], "profile": state["profile"], "doe": None, "steps": 200,
               "init_checkpoint": str(start), "learning_rate": 2e-4, "finetune_partner": partner_start is not None}
    options = _given(data=recorded_data(data), steps=steps, batch=batch, crop_px=crop_px,
                     learning_rate=learning_rate, seed=seed, checkpoint_every=checkpoint_every, precision=precision,
                     channels_last=channels_last, psf=recorded_file(psf), weights=_loss_weights(linear_gain_weight))
    running = {"vgg_weights": vgg_weights, "random_vgg": random_vgg, "device": device, "quiet": quiet,
               "data_workers": data_workers}
    if check is not None:  # refused before any training, as every option
        from hdrcam.data.scenes import SceneSource
        from hdrcam.evaluate.scoring import check_test_crop

        check_test_crop(check_size_px)
        SceneSource(check, lenient=True)
    last = _train(out, new_run, {**options, **_given(init_checkpoint=str(start) if checkpoint else None)},
                  resume=resume, **running)
    if not partner_resumes and partner_start is None:
        _check_finetune(out, trained=bool(last), partner=False, check=check, size_px=check_size_px)
        return last
    new_partner_run = new_run  # unused when the partner's own run continues
    if partner_start is not None:  # the main run's own options (also when this call gave none: a resume)
        trained = read_run_config(out / "config.json")
        new_partner_run = {**new_run, **{field: trained[field] for field in PARTNER_SHARES if field in trained},
                           "preset": partner_state["preset"], "profile": partner_state["profile"],
                           "init_checkpoint": str(partner_start), "finetune_partner": None,
                           "seed": (trained.get("seed", _main_seed(seed, saved_config)) + 1) % 2 ** 32}  # other batches
        if resume:
            _forget_unsaved_run(partner_run)
    given = {**{field: value for field, value in options.items() if field != "seed"},
             **_given(init_checkpoint=str(partner_checkpoint(start)) if checkpoint else None)}
    partner_last = _train(partner_run, new_partner_run, given, resume=partner_resumes, **running)
    if first_process():  # under torchrun only the first process writes
        from hdrcam.io.atomic import write_bytes_atomic

        write_bytes_atomic(partner_model, (partner_run / "model.pt").read_bytes(), overwrite=resume)
    _check_finetune(out, trained=bool(last or partner_last), partner=True, check=check, size_px=check_size_px)
    return last


def _check_finetune(out: Path, *, trained: bool, partner: bool, check, size_px: int) -> None:
    """:func:`finetune`'s check (hdrcam.train.finetune_check) of the run in ``out`` against the checkpoints it
    recorded as its starts, unless ``check`` is None: when this call trained, or the finished run holds no check
    yet (one stopped during its check, or run with none); its summary on stderr."""
    from hdrcam.train.finetune_check import CHECK_FILE, check_finetune

    if check is None or not first_process() or (not trained and (out / CHECK_FILE).is_file()):
        return
    import sys

    from hdrcam.train.checkpoint import recorded_checkpoint
    from hdrcam.train.config import read_run_config

    def began(run: Path) -> Path:
        return recorded_checkpoint(read_run_config(run / "config.json")["init_checkpoint"])

    result = check_finetune(out, began(out), began(out / PARTNER_RUN) if partner else None, data=str(check),
                            size_px=size_px)
    print(f"finetune check: {result.summary()}", file=sys.stderr)


def finetune_check_record(out: str | Path) -> dict | None:
    """What :func:`finetune`'s check wrote in ``out``/check.json (scores, dB, and which networks model.pt holds),
    None where no check ran."""
    from hdrcam.train.finetune_check import read_check

    return read_check(Path(out))


PARTNER_RUN = "partner"  # finetune's run folder for the partner network, inside the main run's
PARTNER_SHARES = ("psf", "data", "steps", "batch", "crop_px", "learning_rate", "checkpoint_every", "precision",
                  "channels_last")  # the options a partner takes from its main run


def finetuned_partner(out: str | Path) -> Path | None:
    """The partner network a finished :func:`finetune` run in ``out`` wrote: ``out``/model-partner.pt, or None."""
    from hdrcam.train.checkpoint import partner_checkpoint

    path = partner_checkpoint(Path(out) / "model.pt")
    return path if path.is_file() and (Path(out) / PARTNER_RUN / "model.pt").is_file() else None


def _saved_config(out: Path) -> dict | None:
    """The config the run in ``out`` saved with its checkpoint, else the config.json it wrote as it started (a run
    stopped before its first checkpoint), None before either."""
    from hdrcam.train.checkpoint import read_checkpoint
    from hdrcam.train.config import read_run_config

    saved, claimed = out / "checkpoint.pt", out / "config.json"
    if saved.is_file():
        return read_checkpoint(saved)["config"]
    return read_run_config(claimed) if claimed.is_file() else None


def _partner_choice(out: Path, given: bool | None) -> bool:
    """Whether the resumed finetune run in ``out`` fine-tunes a partner: the choice it was started with
    (``given`` None, or the same), True for a run saved before the choice was recorded unless ``given`` is
    False; InputError when ``given`` contradicts the recorded choice."""
    from hdrcam.errors import InputError

    recorded = (_saved_config(out) or {}).get("finetune_partner")
    if recorded is None:
        return given is not False
    if given is not None and given != recorded:
        started = "without --no-partner (it fine-tunes its partner)" if recorded else \
            "without a partner (--no-partner, or a checkpoint that has none)"
        raise InputError(f"finetune --resume: {out} was started {started}; resume it as it was started, or choose "
                         "another --out")
    return recorded


def _run_psf(out: Path) -> str:
    """The PSF file the fine-tuning run in ``out`` recorded; InputError when ``out`` holds no run, or a run that
    trained behind no PSF file (a DOE design, a fixed PSF by name)."""
    from hdrcam.errors import InputError
    from hdrcam.train.choices import FIXED_PSFS

    config = _saved_config(out)
    if config is None:
        raise InputError(f"finetune --resume: {out} holds no run to resume; start one with --psf")
    if not config.get("psf") or config["psf"] in FIXED_PSFS:
        raise InputError(f"finetune --resume: {out} holds a run trained behind no PSF file (a design run?); "
                         "resume it with the command that made it")
    return config["psf"]


def _main_seed(seed: int | None, saved_config: dict | None) -> int:
    """The main run's seed: the one given, else the one its saved config holds, else TrainConfig's default."""
    from hdrcam.train.config import TrainConfig

    if seed is not None:
        return seed
    return (saved_config or {}).get("seed", TrainConfig.seed)


def _run_start(saved: dict | None) -> tuple[Path, dict] | None:
    """The checkpoint (path, state) a finetune run whose saved config is ``saved`` started from, None before its
    first save."""
    from hdrcam.errors import InputError
    from hdrcam.train.checkpoint import partner_checkpoint, read_checkpoint, recorded_checkpoint

    began = (saved or {}).get("init_checkpoint")
    if not began:
        return None
    start = recorded_checkpoint(began)
    if not start.is_file():
        raise InputError(f"{began}, the checkpoint this run started from, is gone; its partner "
                         f"({partner_checkpoint(start).name}) is fine-tuned from beside it: restore it there, or "
                         "resume with --no-partner")
    return start, read_checkpoint(start)


def _checked_partner(start: Path, state: dict) -> tuple[Path | None, dict | None]:
    """Checkpoint ``start``'s partner file and its read state, (None, None) when it has none; InputError when it
    was trained behind another PSF than ``start`` (whose read ``state`` is given)."""
    from types import SimpleNamespace

    from hdrcam.api import check_partner
    from hdrcam.errors import InputError
    from hdrcam.train.checkpoint import partner_checkpoint, read_checkpoint

    path = partner_checkpoint(start)
    if not path.is_file():
        return None, None
    try:
        partner_state = read_checkpoint(path)
        check_partner(SimpleNamespace(psf=state["psf"], source=start),
                      SimpleNamespace(psf=partner_state["psf"], source=path))
    except InputError as error:
        raise InputError(f"{error} ({path.name} is taken as {start.name}'s partner; --no-partner fine-tunes it "
                         "alone)") from error
    return path, partner_state


def first_process() -> bool:
    """False in the other processes of a torchrun launch (only the first writes files and reports)."""
    import os

    return os.environ.get("RANK", "0") == "0"


def _forget_unsaved_run(folder: Path) -> None:
    """Remove what a run stopped before its first checkpoint left in ``folder`` (config.json, log.jsonl): it
    saved no step, so a new run continues it. Every torchrun process calls this; the first one removes."""
    import torch.distributed as dist

    if first_process() and not (folder / "checkpoint.pt").exists():
        for name in ("config.json", "log.jsonl"):
            (folder / name).unlink(missing_ok=True)
    if dist.is_available() and dist.is_initialized():
        dist.barrier()


def _loss_weights(linear_gain_weight: float | None):
    """The loss weights of a run asked for a linear-gain weight (None: the run's own, or the defaults)."""
    from hdrcam.recon.losses import LossWeights

    return None if linear_gain_weight is None else LossWeights(linear_gain=linear_gain_weight)


def _given(**fields) -> dict:
    """The run fields a caller set (not None)."""
    return {field: value for field, value in fields.items() if value is not None}


def _train(out: str | Path, new_run: dict, given: dict, *, resume: bool, vgg_weights, random_vgg: bool, device: str,
           quiet: bool, data_workers: int | None) -> dict:
    """A new run from ``new_run`` (or, with ``resume``, the run saved in ``out``), then the fields ``given``;
    train() refuses a resume whose given fields differ from the run's."""
    import torch

    from hdrcam.errors import InputError
    from hdrcam.train.checkpoint import read_checkpoint
    from hdrcam.train.config import TrainConfig, read_run_config
    from hdrcam.train.design import train

    if device == "cuda" and not torch.cuda.is_available():
        raise InputError("--device cuda asked for, but torch sees no CUDA device")
    checkpoint, claimed = Path(out) / "checkpoint.pt", Path(out) / "config.json"
    restart = resume and not checkpoint.is_file() and claimed.is_file()  # stopped before its first checkpoint:
    if restart:  # it starts again, with its own options
        config, resume = TrainConfig.from_dict(read_run_config(claimed), claimed), False
    elif resume and checkpoint.is_file():
        config = TrainConfig.from_dict(read_checkpoint(checkpoint)["config"], checkpoint)
    else:
        config = TrainConfig(**new_run)
    config = dataclasses.replace(config, **given)  # checks the given fields as a new config would
    return train(config, Path(out), resume=resume, restart=restart,
                 vgg_weights=Path(vgg_weights) if vgg_weights else None, random_vgg=random_vgg, quiet=quiet,
                 data_workers=data_workers,
                 device=None if device == "auto" else torch.device(device))  # auto: each torchrun rank its GPU


def evaluate_checkpoints(checkpoints: dict[str, str | Path | None] | None = None, *, data: str = "procedural",
             size_px: int = 512, count: int = 16, seed: int = 0, psf: str | Path | None = None,
             vgg_weights: str | Path | None = None, place_highlights: bool = False,
             progress=None) -> tuple[list["ScoredImage"], list["Example"]]:
    """Score checkpoints (label -> checkpoint path; None = the shipped one) on a fixed test set.

    ``data``: procedural (``count`` seeded night scenes) or a folder of EXR/.hdr photographs; each test image is
    a ``size_px`` crop scaled so 1.5 % of its pixels exceed 1, captured through each checkpoint's PSF (or
    ``psf``) with noise seed ``seed``, reconstructed by :func:`hdrcam.reconstruct` (with each checkpoint's
    partner NAME-partner.pt where it has one, as ``reconstruct`` does) and scored: linear PSNR
    (peak 2^8, dB), PU21 PSNR and PSNR-mu. ``place_highlights``: reconstruct's option of that name.
    ``progress``: a tqdm-like object (``update()``) per image. Returns the scored rows (also ``ldr`` and
    ``hdrcnn-blend``) and three examples (images).
    """
    from hdrcam.data.scenes import SceneSource
    from hdrcam.errors import InputError
    from hdrcam.evaluate.scoring import check_test_crop, evaluate_models
    from hdrcam.optics.psf_file import load_psf
    from hdrcam.train.checkpoint import load_model

    check_test_crop(size_px)
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise InputError(f"count must be a whole number of test scenes, 1 or more, got {count!r}")
    if checkpoints is not None and not isinstance(checkpoints, dict):
        raise InputError("checkpoints: a dict of label -> checkpoint path (None: the shipped checkpoint)")
    models = {label: load_model(Path(path) if path else None, vgg_weights=Path(vgg_weights) if vgg_weights else None)
              for label, path in (checkpoints or {"hdrcam": None}).items()}
    source = SceneSource(data, lenient=True)
    count = count if source.folder is None else len(source.folder)
    return evaluate_models(models, source, size_px=size_px, count=count, psf=load_psf(Path(psf)) if psf else None,
                           seed=seed, place_highlights=place_highlights, progress=progress)
