"""Ingest of folders holding copies of a RAW file, and of distinct frames that repeat an exposure."""

from __future__ import annotations

import datetime as dt
import shutil

from hdrcam.capture.ingest import ingest_folder
from hdrcam.capture.manifest import load_bracket
from hdrcam.cli import main
from tests.capture.helpers import small_camera

START = dt.datetime(2026, 5, 1, 21, 0, 0)
EXPOSURES = (1 / 4000, 1 / 500, 1 / 60, 1 / 8, 1.0)


def _write_frames(folder, exposures, start=START, prefix="frame", starts_s=None):
    _, simulated = small_camera("sim")
    for k, exposure in enumerate(exposures):
        simulated.set_exposure(exposure, iso=100)
        simulated.write_frame(folder / f"{prefix}-{k:02d}.dng", simulated.render_dn(), simulated.settings(),
                              start + dt.timedelta(seconds=k if starts_s is None else starts_s[k]))


def test_a_copy_of_a_frame_is_named_as_a_duplicate_and_the_bracket_stays_whole(tmp_path, capsys):
    _write_frames(tmp_path, EXPOSURES)
    shutil.copyfile(tmp_path / "frame-02.dng", tmp_path / "frame-02 (1).dng")
    result = ingest_folder(tmp_path)
    assert [[f.path.name for f in b] for b in result.brackets] == [[f"frame-{k:02d}.dng" for k in range(5)]]
    assert result.report == ["duplicate: frame-02 (1).dng has the same content as frame-02.dng (identical sha256); "
                             "left out of the brackets"]

    assert main(["ingest", str(tmp_path)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert len(printed) == 2 and "5 frames" in printed[0] and printed[1] == result.report[0]
    manifest = load_bracket(tmp_path / "bracket-01.json")
    assert [f.file for f in manifest.frames] == [f"frame-{k:02d}.dng" for k in range(5)]
    assert not (tmp_path / "bracket-02.json").exists()


def test_three_copies_of_one_file_are_two_duplicates_of_the_first(tmp_path, capsys):
    _write_frames(tmp_path, EXPOSURES[:1])
    for k in (1, 2, 3):
        shutil.copyfile(tmp_path / "frame-00.dng", tmp_path / f"copy{k}.dng")
    (tmp_path / "frame-00.dng").unlink()
    result = ingest_folder(tmp_path)
    assert result.brackets == []
    assert [line.split(" (")[0] for line in result.report] == [
        "duplicate: copy2.dng has the same content as copy1.dng",
        "duplicate: copy3.dng has the same content as copy1.dng", "not in a bracket: copy1.dng"]
    assert main(["ingest", str(tmp_path)]) == 1
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "copy2.dng has the same content as copy1.dng" in error


def test_distinct_frames_refused_for_sharing_an_exposure_say_so(tmp_path):
    _write_frames(tmp_path, (1 / 60, 1 / 60))  # two shots (different noise) 1 s apart at one exposure
    _write_frames(tmp_path, (1 / 60,), START + dt.timedelta(minutes=5), prefix="late")  # alone in its minute
    result = ingest_folder(tmp_path)
    assert result.brackets == [] and len(result.report) == 3
    first, second, late = result.report
    assert first.startswith("not in a bracket: frame-00.dng") and second.startswith("not in a bracket: frame-01.dng")
    assert first.endswith("same exposure as frame-01.dng, and a bracket needs distinct exposures")
    assert second.endswith("same exposure as frame-00.dng, and a bracket needs distinct exposures")
    assert late.startswith("not in a bracket: late-00.dng") and late.endswith(
        "no other frame with these settings within 10 s of the camera being ready (twice an exposure after it began)")


def test_a_long_exposure_bracket_with_in_camera_noise_reduction_stays_one_bracket(tmp_path):
    """Long Exposure NR (on by default on Sony bodies) follows each exposure with a dark frame as long: 2, 4, 8,
    15 and 30 s shots begin 5, 9, 17 and 33 s apart. The 30 s frame was split off (33 s > 10 s + 15 s)."""
    _write_frames(tmp_path, (2, 4, 8, 15, 30), starts_s=(0, 5, 14, 31, 64))
    result = ingest_folder(tmp_path)
    assert [len(bracket) for bracket in result.brackets] == [5] and result.report == []


def test_two_camera_brackets_shot_out_of_order_are_told_apart_by_a_smaller_gap(tmp_path):
    """A body's AEB shoots 0, -1, +1 EV within a second; a second set 5 s later, 2 EV brighter, repeats one
    exposure, which starts a bracket there: the first takes the second set's first frame (1/125 s) - pauses
    cannot tell such sets from a hand-set bracket's (a rule on them split those wrongly instead). A --max-gap
    below the pause between the sets separates them."""
    _write_frames(tmp_path, (1 / 500, 1 / 1000, 1 / 250, 1 / 125, 1 / 250, 1 / 60), starts_s=(0, 0, 0, 5, 5, 5))
    assert [len(bracket) for bracket in ingest_folder(tmp_path).brackets] == [4, 2]
    assert [[f.path.name for f in bracket] for bracket in ingest_folder(tmp_path, max_gap_s=3).brackets] == [
        ["frame-00.dng", "frame-01.dng", "frame-02.dng"], ["frame-03.dng", "frame-04.dng", "frame-05.dng"]]


def test_a_card_root_is_refused_pointing_at_the_folder_with_the_frames(tmp_path, capsys):
    """A memory card keeps its frames in DCIM/100MSDCF; ingest of the card's root said only 'no RAW files in it'."""
    from hdrcam.cli import main

    frames = tmp_path / "card" / "DCIM" / "100MSDCF"
    frames.mkdir(parents=True)
    _write_frames(frames, EXPOSURES[:2])
    (tmp_path / "card" / "AVF_INFO").mkdir()  # Sony's index files, beside DCIM and sorting before it
    (tmp_path / "card" / "AVF_INFO" / "AVIN0001.INP").write_bytes(b"index")
    (tmp_path / "card" / "NIKON001.DSC").write_bytes(b"not raw")  # a file of the root's own: a line in the report
    assert main(["ingest", str(tmp_path / "card")]) == 1
    assert capsys.readouterr().err.strip().endswith(f"ingest reads one folder, not its subfolders - e.g. {frames} "
                                                    "(2 files)")


def test_hand_set_brackets_back_to_back_split_at_the_repeat(tmp_path):
    """A hand-set bracket pauses between shots as the dial is turned; split at its longest pause instead of the
    repeat, the first bracket lost frames to the second."""
    for index, starts in enumerate(((0, 2, 3, 4, 6, 7), (0, 1, 5, 6, 7, 8))):
        folder = tmp_path / str(index)
        folder.mkdir()
        _write_frames(folder, (1 / 1000, 1 / 250, 1 / 60, 1 / 1000, 1 / 250, 1 / 60), starts_s=starts)
        assert [[f.path.name for f in bracket] for bracket in ingest_folder(folder).brackets] == [
            ["frame-00.dng", "frame-01.dng", "frame-02.dng"], ["frame-03.dng", "frame-04.dng", "frame-05.dng"]]



def test_frames_without_a_capture_time_are_grouped_and_said_to_be(tmp_path):
    """Frames whose files record no capture time (LibRaw's 0) were dated 1970-01-01 and grouped as if shot in one
    second; nothing tells brackets hours apart from one then, and the report says so."""
    import numpy as np

    from tests.io.realistic_dng import sensor_dn, write_dng

    scene = 2.0 ** (6 + 8 * np.mgrid[0:32, 0:48][1] / 47)
    for k, exposure in enumerate((0.001, 0.004, 0.016)):
        write_dng(tmp_path / f"f{k}.dng", sensor_dn(scene, exposure, np.random.default_rng(k)), exposure_s=exposure,
                  datetime=None)
    result = ingest_folder(tmp_path)
    assert [len(bracket) for bracket in result.brackets] == [3]
    assert all(frame.timestamp is None for frame in result.brackets[0])
    assert any("no capture time recorded in 3 frame(s)" in line for line in result.report)


def test_a_frame_without_a_capture_time_does_not_join_a_timed_bracket(tmp_path):
    """A frame with no time beside three timed ones of the same settings joined their bracket (nothing said it was
    shot apart); it stands alone and is reported."""
    import numpy as np

    from tests.io.realistic_dng import sensor_dn, write_dng

    scene = 2.0 ** (6 + 8 * np.mgrid[0:32, 0:48][1] / 47)
    for k, exposure in enumerate((0.001, 0.004, 0.016, 0.064)):
        write_dng(tmp_path / f"f{k}.dng", sensor_dn(scene, exposure, np.random.default_rng(k)), exposure_s=exposure,
                  datetime=None if k == 3 else f"2026:11:24 12:00:0{k}")
    result = ingest_folder(tmp_path)
    assert [[frame.path.name for frame in bracket] for bracket in result.brackets] == [["f0.dng", "f1.dng", "f2.dng"]]
    assert any(line.startswith("not in a bracket: f3.dng") for line in result.report)
