"""Bad-pixel lists (dcraw's format), their repair in a Bayer mosaic and in RGB, and finding them in RAW frames."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from hdrcam.calibrate.bad_pixels import find_bad_pixels
from hdrcam.errors import InputError
from hdrcam.io.bad_pixels import read_bad_pixels, repair_mosaic, repair_rgb, write_bad_pixels
from hdrcam.io.ldr_frame import read_ldr_capture
from tests.io.realistic_dng import sensor_dn, write_dng

HOT, DEAD = (20, 31), (41, 12)  # (row, column) on a 64 x 96 sensor


def test_a_list_written_reads_back_and_dcraws_lines_are_understood(tmp_path):
    bad = np.zeros((64, 96), bool)
    bad[HOT] = bad[DEAD] = True
    path = write_bad_pixels(tmp_path / "bad.txt", bad, comment="two")
    listed = read_bad_pixels(path)
    assert len(listed) == 2 and np.array_equal(listed.mask((64, 96)), bad)
    with pytest.raises(Exception, match="already exists"):
        write_bad_pixels(path, bad)

    (tmp_path / "dcraw.txt").write_text("# Sony\n  962 2627   0\n\n1491 1011 1500000000  # died in 2017\n")
    listed = read_bad_pixels(tmp_path / "dcraw.txt")
    before, after = dt.datetime(2016, 1, 1), dt.datetime(2018, 1, 1)
    assert np.argwhere(listed.mask((3000, 4000), before)).tolist() == [[2627, 962]]
    assert np.argwhere(listed.mask((3000, 4000), after)).tolist() == [[1011, 1491], [2627, 962]]
    assert listed.mask((3000, 4000)).sum() == 2  # no capture time: every listed pixel


@pytest.mark.parametrize("content, message", [
    ("962 2627 0\n962 x 0\n", r"line 2: '962 x 0' is not 'COLUMN ROW UNIX_TIME'"),
    ("962 2627\n", r"line 1: .* is not 'COLUMN ROW UNIX_TIME'"),
    ("-1 4 0\n", "line 1: negative column or row"),
])
def test_a_malformed_list_is_refused_naming_its_line(tmp_path, content, message):
    (tmp_path / "bad.txt").write_text(content)
    with pytest.raises(InputError, match=message):
        read_bad_pixels(tmp_path / "bad.txt")


def test_a_binary_file_or_a_list_for_a_larger_sensor_is_refused(tmp_path):
    (tmp_path / "frame.exr").write_bytes(b"v/1\x01\x02\x00\xff\xfe")
    with pytest.raises(InputError, match="not a bad-pixel list"):
        read_bad_pixels(tmp_path / "frame.exr")
    (tmp_path / "big.txt").write_text("10 5 0\n6000 3999 0\n")
    with pytest.raises(InputError, match=r"1 of its 2 bad pixels lie outside the 4000 x 3000 frame \(the first at "
                                         r"column 6000, row 3999\)"):
        read_bad_pixels(tmp_path / "big.txt").mask((3000, 4000))


def test_mosaic_repair_takes_the_median_of_same_colour_neighbours_that_are_not_bad():
    rows, columns = np.mgrid[0:16, 0:16]
    mosaic = (1000 + 10 * rows + 3 * columns).astype(np.uint16)  # a plane: a symmetric median is the centre's value
    mosaic[1::2, 1::2] += 500  # another colour, which must not take part
    truth = mosaic.copy()
    bad = np.zeros(mosaic.shape, bool)
    bad[6, 6] = bad[6, 8] = True  # same-colour neighbours of each other
    mosaic[6, 6], mosaic[6, 8] = 16383, 0  # hot and dead
    repaired, unrepaired = repair_mosaic(mosaic, bad)
    assert unrepaired == 0 and repaired.dtype == np.uint16
    assert np.array_equal(repaired[~bad], truth[~bad]) and mosaic[6, 6] == 16383  # a copy; nothing else moved
    # (6, 6) from its seven other neighbours: their median is the plane's value at (6, 6) +- one step
    assert abs(int(repaired[6, 6]) - int(truth[6, 6])) <= 20 and abs(int(repaired[6, 8]) - int(truth[6, 8])) <= 20
    corner = np.zeros(mosaic.shape, bool)
    corner[0, 0] = True  # three neighbours in the frame
    assert repair_mosaic(truth, corner)[0][0, 0] == 1020  # the median of (0, 2), (2, 0), (2, 2): 1006, 1020, 1026


def test_rgb_repair_and_a_cluster_too_wide_to_repair():
    rgb = np.tile(np.linspace(0.1, 0.5, 8, dtype=np.float32)[None, :, None], (8, 1, 3))
    bad = np.zeros((8, 8), bool)
    bad[3, 4] = True
    broken = rgb.copy()
    broken[3, 4] = (1.0, 0.0, 1.0)
    repaired, unrepaired = repair_rgb(broken, bad)
    assert unrepaired == 0 and np.allclose(repaired, rgb)
    bad[2:5, 3:6] = True  # the centre's eight neighbours all bad
    assert repair_rgb(broken, bad)[1] == 1


def _frames_with_defects(folder, count: int, seed: int = 0):
    """RAW frames on a sensor with one hot and one dead pixel: a dark frame, then evenly lit frames (a flat field
    with a gentle fall-off, brighter each time) each with a bright point of the scene at its own place."""
    rng = np.random.default_rng(seed)
    folder.mkdir()
    rows, columns = np.mgrid[0:64, 0:96]
    falloff = 1.0 - 0.3 * (((rows - 32) / 64) ** 2 + ((columns - 48) / 96) ** 2)
    paths = []
    for index in range(count):
        radiance = 1.0e5 * index * falloff
        radiance[rng.integers(4, 60), rng.integers(4, 92)] += 3.0e6 * (index > 0)  # a point of the scene
        dn = sensor_dn(radiance, 0.01, rng)
        dn[HOT], dn[DEAD] = 16383, 0
        paths.append(write_dng(folder / f"f{index}.dng", dn))
    return paths


def test_find_bad_pixels_finds_the_defects_that_stay_not_the_points_that_move(tmp_path):
    paths = _frames_with_defects(tmp_path / "frames", 4)
    found = find_bad_pixels(paths)
    assert np.argwhere(found).tolist() == sorted([list(DEAD), list(HOT)])
    with pytest.raises(InputError, match="at least 2 frames"):
        find_bad_pixels(paths[:1])
    other = write_dng(tmp_path / "other.dng", sensor_dn(np.full((32, 32), 4.0e5), 0.01, np.random.default_rng(1)))
    with pytest.raises(InputError, match="frames of different sizes"):
        find_bad_pixels([*paths, other])


def test_frames_of_one_scene_are_refused_not_listed(tmp_path, shared_data):
    """Two copies of one real photograph: its edges and texture stand out in both (340,929 samples, 1.9 %), which
    a list would 'repair' into a blur; refused, naming what to give instead."""
    import shutil

    for name in ("a.ARW", "b.ARW"):
        shutil.copy(shared_data / "raw" / "sony-ilce7rm3-DSC2164.ARW", tmp_path / name)
    with open(tmp_path / "b.ARW", "ab") as copy:  # not byte-identical: a byte copy is refused as a copy
        copy.write(b"\0")
    with pytest.raises(InputError, match=r"340929 of 17957376 samples \(1\.9 %\) stand out .* dark frames and in "
                                         "evenly lit ones"):
        find_bad_pixels([tmp_path / "a.ARW", tmp_path / "b.ARW"])


def test_a_listed_dead_pixel_is_repaired_before_demosaicing(tmp_path):
    path = _frames_with_defects(tmp_path / "frames", 3)[2]
    clean = tmp_path / "clean.dng"
    dn = np.asarray(__import__("tifffile").imread(path))
    neighbours = [dn[DEAD[0] + r, DEAD[1] + c] for r in (-2, 0, 2) for c in (-2, 0, 2) if r or c]
    dn[DEAD], dn[HOT] = np.uint16(np.median(neighbours)), 512  # what a repair gives; the hot one left alone
    write_dng(clean, dn)
    bad = np.zeros((64, 96), bool)
    bad[DEAD] = True
    listed = read_bad_pixels(write_bad_pixels(tmp_path / "bad.txt", bad))
    raw = read_ldr_capture(path)
    repaired = read_ldr_capture(path, bad_pixels=listed)
    expected = read_ldr_capture(clean).rgb
    window = (slice(DEAD[0] - 2, DEAD[0] + 3), slice(DEAD[1] - 2, DEAD[1] + 3))
    assert repaired.repaired_pixels == 1 and raw.repaired_pixels == 0
    assert np.abs(raw.rgb[window] - expected[window]).max() > 0.05  # the dead sample darkened its neighbours
    np.testing.assert_allclose(repaired.rgb[window], expected[window], atol=1e-6)


def test_a_demosaiced_frame_is_repaired_per_pixel_on_reading(tmp_path):
    """An EXR frame (already demosaiced; no capture time, so every listed pixel counts) with a hot pixel."""
    from hdrcam.io.exr import write_exr

    rgb = np.tile(np.linspace(0.1, 0.5, 32, dtype=np.float32)[None, :, None], (24, 1, 3))
    broken = rgb.copy()
    broken[10, 12] = 1.0
    frame = write_exr(tmp_path / "frame.exr", broken, channel_names=("R", "G", "B"))
    (tmp_path / "bad.txt").write_text("12 10 1900000000\n")  # found dead in 2030: still counts, no time recorded
    capture = read_ldr_capture(frame, bad_pixels=read_bad_pixels(tmp_path / "bad.txt"))
    assert capture.repaired_pixels == 1
    np.testing.assert_allclose(capture.rgb, rgb, atol=1e-6)
    np.testing.assert_array_equal(read_ldr_capture(frame).rgb, broken)
