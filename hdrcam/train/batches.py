"""Training batches drawn ahead of the optimiser, on worker threads, reproducibly.

The scenes of step s are drawn from their own seed, SeedSequence([run seed, process rank, s, index in the
batch]), so a batch does not depend on how many threads drew it, in what order they finished, or whether the
run was interrupted and resumed before step s: a resumed run sees the scenes an uninterrupted one would,
with no random state to save.

Why threads ahead of the step: a scene is drawn on the CPU (a procedural night scene, or a crop of a
photograph with its augmentation), and at the paper's scale (512 px crops with the A7 PSF's 127 px margins)
one takes 0.14 s (photograph) to 0.58 s (night scene) on this project's CPU - seconds per batch, many times a
GPU step. Drawing runs in numpy and OpenCV, which release the GIL, so on a machine with free cores (a GPU
machine has 16) threads overlap it with each other and with the step; tools/bench_batches.py measures it.
On a CPU the step itself uses every core, and a drawing thread beside it slowed a 2-core fine-tune by half
(measured), so there ``workers`` 0 draws each batch when it is asked for, in the calling thread.
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from hdrcam.data.scenes import SceneSource

PREFETCH_BATCHES = 2  # batches drawn ahead of the one the step uses


def scene_seed(run_seed: int, rank: int, step: int, index: int) -> np.random.SeedSequence:
    """The seed of scene ``index`` of step ``step`` (0-based) on process ``rank``."""
    return np.random.SeedSequence([run_seed, rank, step, index])


class BatchStream:
    """Batches (batch, crop + 2 margin, crop + 2 margin, 3) float32 of steps ``start``, ``start`` + 1, ...,
    drawn by ``workers`` threads up to PREFETCH_BATCHES ahead (0: none, each batch drawn when asked for). Use
    as a context manager; ``next_batch()`` returns the batches in step order."""

    def __init__(self, source: SceneSource, *, crop_px: int, margin_px: int, batch: int, run_seed: int,
                 rank: int = 0, start: int = 0, workers: int = 1):
        if workers < 0:
            raise ValueError(f"workers must be 0 or more, got {workers}")
        self.source, self.crop_px, self.margin_px, self.batch = source, crop_px, margin_px, batch
        self.run_seed, self.rank, self.next_step = run_seed, rank, start
        self.pool = ThreadPoolExecutor(workers, thread_name_prefix="hdrcam-batch") if workers else None
        self.pending: deque[list[Future]] = deque()

    def __enter__(self) -> "BatchStream":
        return self

    def __exit__(self, *exc) -> None:
        for futures in self.pending:
            for future in futures:
                future.cancel()
        if self.pool:
            self.pool.shutdown(wait=True)

    def _scene(self, step: int, index: int) -> np.ndarray:
        rng = np.random.default_rng(scene_seed(self.run_seed, self.rank, step, index))
        return self.source.training_scene(self.crop_px, self.margin_px, rng)

    def _submit(self) -> None:
        step = self.next_step + len(self.pending)
        self.pending.append([self.pool.submit(self._scene, step, index) for index in range(self.batch)])

    def next_batch(self) -> np.ndarray:
        """The next step's batch (its scenes' failures are raised here)."""
        if self.pool is None:
            self.next_step += 1
            return np.stack([self._scene(self.next_step - 1, index) for index in range(self.batch)])
        while len(self.pending) < PREFETCH_BATCHES + 1:
            self._submit()
        futures = self.pending.popleft()
        self.next_step += 1
        return np.stack([future.result() for future in futures])
