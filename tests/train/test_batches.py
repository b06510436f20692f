"""Training batches: reproducible per step, whatever the number of threads or where a run resumed."""

import numpy as np
import pytest

from hdrcam.data.scenes import SceneSource
from hdrcam.train.batches import BatchStream


def _batches(workers: int, start: int, count: int, seed: int = 0) -> list[np.ndarray]:
    with BatchStream(SceneSource("procedural"), crop_px=32, margin_px=4, batch=3, run_seed=seed, start=start,
                     workers=workers) as stream:
        return [stream.next_batch() for _ in range(count)]


def test_a_step_draws_the_same_scenes_on_any_number_of_threads_and_after_a_resume():
    one_thread = _batches(workers=1, start=0, count=5)
    two_threads = _batches(workers=2, start=0, count=5)
    on_demand = _batches(workers=0, start=0, count=5)
    resumed = _batches(workers=2, start=3, count=2)  # a run resumed at step 3
    assert all(np.array_equal(a, b) for a, b in zip(one_thread, two_threads))
    assert all(np.array_equal(a, b) for a, b in zip(one_thread, on_demand))
    assert all(np.array_equal(a, b) for a, b in zip(one_thread[3:], resumed))
    assert one_thread[0].shape == (3, 40, 40, 3) and one_thread[0].dtype == np.float32


def test_steps_scenes_and_seeds_differ():
    first, second = _batches(workers=1, start=0, count=2)
    assert not np.array_equal(first, second)  # steps
    assert not np.array_equal(first[0], first[1])  # scenes within a batch
    assert not np.array_equal(first, _batches(workers=1, start=0, count=1, seed=1)[0])  # run seeds


def test_a_failing_draw_is_raised_by_next_batch_and_workers_must_be_positive():
    class Broken(SceneSource):
        def training_scene(self, size_px, margin_px, rng):
            raise OSError("photograph unreadable")

    for workers in (0, 1):
        with BatchStream(Broken("procedural"), crop_px=32, margin_px=4, batch=2, run_seed=0,
                         workers=workers) as stream:
            with pytest.raises(OSError, match="unreadable"):
                stream.next_batch()
    with pytest.raises(ValueError, match="0 or more"):
        BatchStream(SceneSource("procedural"), crop_px=32, margin_px=4, batch=2, run_seed=0, workers=-1)
