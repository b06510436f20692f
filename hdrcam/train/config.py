"""Configuration of a training run (``hdrcam design`` and ``hdrcam finetune``)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

from hdrcam.errors import InputError
from hdrcam.recon.losses import LossWeights
from hdrcam.train.choices import TRAINABLE_DOES

PRECISIONS = ("float32", "bfloat16", "float16")  # of the network's forward in training; optics stay float32


@dataclasses.dataclass
class TrainConfig:
    preset: str = "fast"
    data: str = "procedural"  # 'procedural' or a folder of .exr/.hdr files
    profile: str = "simulated"
    doe: str | None = "rank1"  # trained height map: rank1 | freeform; None with a fixed psf
    psf: str | None = None  # fixed PSF: dirac | star8 | dual-peak | a PSF EXR (network-only training)
    steps: int = 1000
    batch: int = 4
    crop_px: int = 128  # multiple of 16 (the U-Net pools four times)
    learning_rate: float = 1e-3  # network, Adam; polynomial decay to 0 at ``steps``
    doe_learning_rate: float = 1e-2  # height-map parameters
    decay_power: float = 0.9
    seed: int = 0
    checkpoint_every: int = 100
    init_checkpoint: str | None = None  # start the network from this checkpoint (fine-tuning)
    init_doe_checkpoint: str | None = None  # start the trained DOE's parameters from this checkpoint's DOE
    precision: str = "float32"  # the network's forward: float32, or autocast to bfloat16 / float16 (CUDA)
    channels_last: bool = False  # NHWC network weights and input (faster convolutions on CUDA tensor cores)
    finetune_partner: bool | None = None  # finetune: the partner network is fine-tuned after this run (None:
    # not a finetune run, or one saved before the choice was recorded; such runs trained a partner unless told not to)
    weights: LossWeights = dataclasses.field(default_factory=LossWeights)

    def __post_init__(self) -> None:
        """InputError, before anything is written, for settings no run can have (the command line's parsers
        refuse them too; the Python API reaches here directly)."""
        if self.precision not in PRECISIONS:
            raise InputError(f"precision must be one of {', '.join(PRECISIONS)}, got {self.precision!r}")
        if self.doe is not None and self.doe not in TRAINABLE_DOES:
            raise InputError(f"doe must be one of {', '.join(TRAINABLE_DOES)} (or None with a fixed psf), got "
                             f"{self.doe!r}")
        for name in ("steps", "batch", "crop_px", "checkpoint_every"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(f"{name} must be a whole number, 1 or more, got {value!r}")
        for name in ("learning_rate", "doe_learning_rate"):
            if not 0 < getattr(self, name) < math.inf:
                raise InputError(f"{name} must be a positive, finite number, got {getattr(self, name)!r}")
        if self.init_doe_checkpoint is not None and self.doe is None:
            raise InputError("a DOE to start from (init_doe_checkpoint, --init-doe) needs a DOE to train (doe rank1 "
                             "or freeform), not a fixed psf")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2 ** 32:
            raise InputError(f"seed must be a whole number from 0 to 2^32 - 1, got {self.seed!r}")

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, document: dict, source: Path | str = "the run's configuration") -> "TrainConfig":
        """The configuration a run saved (fields a run saved before they existed take their defaults); a one-line
        InputError naming ``source`` for settings this version does not know (a run of a newer hdrcam)."""
        values = dict(document)
        weights = values.get("weights", {})
        if not isinstance(weights, dict):
            raise InputError(f"{source}: its loss weights are not a JSON object; restore the run folder or start a "
                             "new one")
        unknown = sorted(set(values) - {field.name for field in dataclasses.fields(cls)}) + \
            sorted(set(weights) - {field.name for field in dataclasses.fields(LossWeights)})
        if unknown:
            raise InputError(f"{source}: settings this hdrcam does not know ({', '.join(unknown)}): a run of another "
                             "version? Resume it with that version, or start a new run")
        try:
            values["weights"] = LossWeights(**weights)
            return cls(**values)
        except InputError as error:  # a value no run can have
            raise InputError(f"{source}: {error}") from None
        except (TypeError, ValueError) as error:  # a value of the wrong type (null, a string for a number)
            raise InputError(f"{source}: a setting of the wrong type ({error}); restore the run folder or start "
                             "a new one") from None

    def learning_rate_at(self, step: int, base: float) -> float:
        """Polynomial decay: base (1 - step / steps)^power."""
        return base * max(0.0, 1.0 - step / self.steps) ** self.decay_power


def read_run_config(path: Path) -> dict:
    """A run folder's config.json; a one-line InputError naming it when it is damaged or not a run's."""
    try:
        document = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise InputError(f"{path}: not a readable run configuration ({type(error).__name__}: {error}); restore the "
                         "run folder or start a new one") from None
    if not isinstance(document, dict):
        raise InputError(f"{path}: not a run configuration (a JSON {type(document).__name__}); restore the run folder "
                         "or start a new one")
    return document
