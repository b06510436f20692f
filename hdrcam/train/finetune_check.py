"""Did a fine-tune help? Its networks against the ones it started from, on scenes it never trained on.

A short fine-tune can end worse than its start: the demo's 30 steps behind its measured PSF scored 54.03 dB on
the demo's night frame, the shipped networks behind the same PSF 54.40 (tools/results/real-data/README.md). So
``hdrcam finetune`` ends by scoring both (each with its partner where the run has one) through
:func:`hdrcam.evaluate.scoring.evaluate_models`: test scenes captured behind the PSF the run trained behind
(the fine-tuned checkpoint's own, unit sum per channel), reconstructed as ``reconstruct`` does with that PSF,
linear PSNR (peak 2^8, dB) against the truth. Procedural test scenes are seeded apart from every training draw
(hdrcam.data.scenes.TEST_SEED_BASE); a folder of photographs is held out only if the user kept it out of
``--data``. The scenes are 256 px by default, not the run's crops: on the demo's PSF a 30-step run on 128 px
crops scored +0.26 dB over its start on 128 px scenes and -1.05 dB on 256 px ones, as on the demo's frame.

Where the fine-tuned pair's mean is below the start's, the run falls back, visibly: its networks are kept as
OUT/model-finetuned.pt (and model-finetuned-partner.pt), and OUT/model.pt (model-partner.pt) becomes the start
networks behind the measured PSF - what ``reconstruct`` and ``evaluate`` then find. OUT/check.json records the
scores and which networks model.pt holds.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

CHECK_SIZE_PX = 256
CHECK_SCENES = 8
CHECK_FILE = "check.json"
FINETUNED_SUFFIX = "-finetuned"  # OUT/model-finetuned.pt: the fine-tuned networks after a fall-back


@dataclasses.dataclass(frozen=True)
class FinetuneCheck:
    """Mean linear PSNR (dB, peak 2^8) over the scenes both pairs were scored on, and what model.pt holds."""

    data: str
    size_px: int
    scenes: int  # scored
    ldr_db: float
    start_db: float
    finetuned_db: float
    kept: str  # "finetuned", or "start": the run fell back

    def summary(self) -> str:
        scenes = f"{self.scenes} held-out {self.size_px} px scenes ({self.data}) behind the run's PSF"
        if self.scenes == 0:
            return f"no held-out scene could be scored ({self.data}): the fine-tuned networks kept, unchecked"
        scores = (f"fine-tuned {self.finetuned_db:.2f} dB, start {self.start_db:.2f} dB, LDR {self.ldr_db:.2f} dB "
                  f"on {scenes}")
        if self.kept == "start":
            return (f"the fine-tune did not help ({scores}): model.pt holds the start networks behind the measured "
                    f"PSF; the fine-tuned ones are model{FINETUNED_SUFFIX}.pt")
        return f"the fine-tune helped ({scores})"


def check_finetune(out: Path, start: Path, start_partner: Path | None, *, data: str = "procedural",
                   size_px: int = CHECK_SIZE_PX, scenes: int = CHECK_SCENES) -> FinetuneCheck:
    """Score the run in ``out`` (model.pt, with model-partner.pt when ``start_partner`` is given) against its start
    checkpoint ``start`` (with ``start_partner``), fall back when it scored lower, write ``out``/check.json."""
    import numpy as np

    from hdrcam.data.scenes import SceneSource
    from hdrcam.evaluate.scoring import check_test_crop, evaluate_models
    from hdrcam.train.checkpoint import load_model, partner_checkpoint

    check_test_crop(size_px)
    out = Path(out)
    finetuned = load_model(out / "model.pt")
    models = {"start": load_model(Path(start)), "finetuned": finetuned}
    partners = {"start": start_partner, "finetuned": partner_checkpoint(out / "model.pt") if start_partner else None}
    source = SceneSource(data, lenient=True)
    count = scenes if source.folder is None else min(scenes, len(source.folder))
    rows, _ = evaluate_models(models, source, size_px=size_px, count=count, psf=finetuned.psf, examples=0,
                              partner=partners)
    scored = {}
    for row in rows:
        scored.setdefault(row.method, {})[row.image] = row.metrics["psnr_linear"]
    images = sorted(set.intersection(*(set(scored.get(method, {})) for method in ("ldr", "start", "finetuned"))))

    def mean(method: str) -> float:
        return float(np.mean([scored[method][image] for image in images])) if images else math.nan

    kept = "start" if images and mean("finetuned") < mean("start") else "finetuned"
    check = FinetuneCheck(str(data), size_px, len(images), mean("ldr"), mean("start"), mean("finetuned"), kept)
    if kept == "start":
        _fall_back(out, Path(start), start_partner)
    _write_record(out, check)
    return check


def _fall_back(out: Path, start: Path, start_partner: Path | None) -> None:
    """model.pt (model-partner.pt) -> model-finetuned.pt (model-finetuned-partner.pt), each copied before the
    start networks, behind the run's PSF, replace it."""
    from hdrcam.io.atomic import write_bytes_atomic
    from hdrcam.train.checkpoint import partner_checkpoint, read_checkpoint, save_checkpoint

    model, kept = out / "model.pt", out / f"model{FINETUNED_SUFFIX}.pt"
    pairs = [(model, kept, start)] + ([(partner_checkpoint(model), partner_checkpoint(kept), start_partner)]
                                      if start_partner else [])
    for written, kept_as, began in pairs:
        write_bytes_atomic(kept_as, written.read_bytes(), overwrite=True)  # this run's own, from an earlier check
        state = read_checkpoint(written)
        save_checkpoint(written, {**state, "network": read_checkpoint(began)["network"], "step": 0})


def _write_record(out: Path, check: FinetuneCheck) -> None:
    from hdrcam.io.atomic import write_text_atomic

    record = {field: (None if isinstance(value, float) and math.isnan(value) else value)
              for field, value in dataclasses.asdict(check).items()}
    record["model"] = "the start networks behind the run's PSF" if check.kept == "start" else "the fine-tuned networks"
    record["summary"] = check.summary()
    write_text_atomic(out / CHECK_FILE, json.dumps(record, indent=1) + "\n", overwrite=True)


def read_check(out: Path) -> dict | None:
    """The record :func:`check_finetune` wrote in ``out``, None when there is none."""
    path = Path(out) / CHECK_FILE
    return json.loads(path.read_text()) if path.is_file() else None
