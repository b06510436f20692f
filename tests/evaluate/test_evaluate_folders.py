"""``hdrcam evaluate`` on the folders judges bring: no --out, damaged or odd files among the photographs, names
that clash or are not UTF-8, photographs that cannot be scored."""

from __future__ import annotations

import csv
import os
import time

import numpy as np
import OpenEXR
import pytest

from hdrcam.cli import main
from hdrcam.data.scenes import SceneSource
from hdrcam.errors import InputError
from hdrcam.io.exr import write_exr

QUICK = ["evaluate", "--size", "32", "--count", "1", "--no-partner"]


def _lamps(seed: int = 0, side_px: int = 96) -> np.ndarray:
    """A photograph of scattered lights (relative radiance), scaled by the protocol without a plateau."""
    return np.random.default_rng(seed).lognormal(0.0, 1.5, (side_px, side_px, 3)).astype(np.float32)


def _exr(path, channels: dict[str, np.ndarray]) -> None:
    """An EXR written as given, Inf and NaN included (hdrcam's own writer refuses them)."""
    OpenEXR.File({"type": OpenEXR.scanlineimage}, channels).write(str(path))


def _scored(out) -> list[str]:
    with open(out / "metrics.csv", newline="", encoding="utf-8") as table:
        return list(dict.fromkeys(row["image"] for row in csv.DictReader(table)))


def test_without_out_each_run_writes_a_new_folder_in_the_working_directory(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(time, "strftime", lambda layout, *when: "evaluate-20250102-030405")
    (tmp_path / "evaluate-20250102-030405").mkdir()  # an earlier run's folder, same second: kept as it is
    assert main(QUICK) == 0 and main(QUICK) == 0
    assert not any((tmp_path / "evaluate-20250102-030405").iterdir())
    printed = capsys.readouterr().out
    for name in ("evaluate-20250102-030405-2", "evaluate-20250102-030405-3"):
        assert (tmp_path / name / "summary.md").is_file() and f"wrote {name}/metrics.csv" in printed


def test_unreadable_photographs_are_left_out_by_name_and_a_sun_stored_as_inf_is_scored(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    write_exr(data / "lamps.exr", _lamps())
    sun = _lamps(1).astype(np.float16)
    sun[40:44, 40:44] = np.inf  # a half-float sun above 65504
    _exr(data / "sun.exr", {"RGB": sun})
    damaged = _lamps(2)
    damaged[5, 5, 1] = np.nan
    _exr(data / "nan.exr", {"RGB": damaged})
    _exr(data / "beauty.exr", {"beauty": _lamps(3)})  # channels beauty.R, beauty.G, beauty.B: the image's layer
    _exr(data / "layered.exr", {"diffuse": _lamps(4), "specular": _lamps(5)})  # which one is the image is not known
    (data / "preview.hdr").write_bytes(b"\xff\xd8\xff\xe0" + bytes(64))  # a JPEG under an HDR name
    (data / "gone.exr").symlink_to(tmp_path / "missing.exr")
    with pytest.warns(UserWarning) as warned:
        assert main(["evaluate", "--data", str(data), "--size", "64", "--no-partner",
                     "--out", str(tmp_path / "out")]) == 0
    assert _scored(tmp_path / "out") == ["beauty", "lamps", "sun"]
    messages = [str(warning.message) for warning in warned]
    for name, why in [("nan.exr", "NaN"), ("layered.exr", "diffuse, specular"), ("preview.hdr", "cannot read"),
                      ("gone.exr", "no such file")]:
        assert any(f"{name}: not evaluated - " in message and why in message for message in messages), name
    assert any("sun.exr: 48 values are +Inf" in message for message in messages)
    with pytest.raises(InputError, match="gone.exr: no such file"):  # training still refuses the first bad file
        SceneSource(data)


def test_a_folder_with_nothing_readable_is_refused(tmp_path, capsys):
    (tmp_path / "preview.exr").write_bytes(b"not an image")
    assert main(["evaluate", "--data", str(tmp_path), *QUICK[1:], "--out", str(tmp_path / "out")]) == 1
    assert "nothing to evaluate" in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_the_summary_says_how_many_photographs_were_scored_and_names_the_others(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    write_exr(data / "lamps.exr", _lamps())
    write_exr(data / "uniform.exr", np.full((96, 96, 3), 0.5, np.float32))  # no scale leaves 1.5 % above 1
    damaged = _lamps(2)
    damaged[5, 5, 1] = np.nan
    _exr(data / "nan.exr", {"RGB": damaged})
    with pytest.warns(UserWarning):
        assert main(["evaluate", "--data", str(data), "--size", "64", "--no-partner",
                     "--out", str(tmp_path / "out")]) == 0
    summary = (tmp_path / "out" / "summary.md").read_text(encoding="utf-8")
    assert "1 of 3 photographs scored" in summary
    assert "- nan.exr: image has NaN" in summary
    assert "- uniform: scaled as the protocol asks, " in summary


def _rows(out) -> dict[tuple[str, str], dict[str, str]]:
    with open(out / "metrics.csv", newline="", encoding="utf-8") as table:
        return {(row["image"], row["method"]): row for row in csv.DictReader(table)}


def test_a_photographs_score_does_not_depend_on_the_files_beside_it(tmp_path):
    alone, crowded = tmp_path / "alone", tmp_path / "crowded"
    for folder in (alone, crowded):
        folder.mkdir()
        write_exr(folder / "lamps.exr", _lamps(0, 160))
    write_exr(crowded / "a-first.exr", _lamps(1, 160))  # sorted before lamps.exr: lamps moves to position 1
    for folder in (alone, crowded):
        assert main(["evaluate", "--data", str(folder), "--size", "64", "--no-partner",
                     "--out", str(tmp_path / f"out-{folder.name}")]) == 0
    before, after = _rows(tmp_path / "out-alone"), _rows(tmp_path / "out-crowded")
    assert [key for key in after if key[0] == "lamps"] == list(before)
    for key, row in before.items():
        assert after[key] == row


def test_a_file_name_that_is_not_utf8_is_written_with_its_odd_bytes_escaped(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    write_exr(data / "lamps.exr", _lamps())
    (data / os.fsdecode(b"caf\xe9.exr")).write_bytes((data / "lamps.exr").read_bytes())  # Latin-1, from a camera
    (data / os.fsdecode(b"n\xe9ant.exr")).write_bytes(b"not an image")
    with pytest.warns(UserWarning):
        assert main(["evaluate", "--data", str(data), "--size", "64", "--no-partner",
                     "--out", str(tmp_path / "out")]) == 0
    assert _scored(tmp_path / "out") == ["caf\\xe9", "lamps"]
    assert "- n\\xe9ant.exr: " in (tmp_path / "out" / "summary.md").read_text(encoding="utf-8")


def test_reading_is_shown_file_by_file_and_counted_in_the_time_printed(tmp_path, monkeypatch, capsys):
    from hdrcam.data import hdr_folder

    data = tmp_path / "data"
    data.mkdir()
    write_exr(data / "lamps.exr", _lamps())
    read = hdr_folder.read_hdr_image

    def slow_read(path, **options):  # a large photograph on a slow disk
        time.sleep(2.0)
        return read(path, **options)

    monkeypatch.setattr(hdr_folder, "read_hdr_image", slow_read)
    started = time.perf_counter()
    assert main(["evaluate", "--data", str(data), *QUICK[1:], "--out", str(tmp_path / "out")]) == 0
    took = time.perf_counter() - started
    shown = capsys.readouterr()
    assert float(shown.out.rsplit("evaluated in ", 1)[1].split(" s;")[0]) > took - 1.0
    assert "read: " in shown.err and "lamps.exr" in shown.err.split("evaluate: ")[0]


def test_a_folder_of_dark_frames_is_refused_for_its_real_reason(tmp_path, capsys):
    night = np.zeros((96, 96, 3), np.float32)
    night[40:43, 40:43] = 50.0  # one small lamp: 9 lit pixels, fewer than 1.5 % of the 64 px crop
    write_exr(tmp_path / "night.exr", night)
    with pytest.warns(UserWarning, match="too few lit pixels: only 9 hold any light"):
        assert main(["evaluate", "--data", str(tmp_path), "--size", "64", "--no-partner",
                     "--out", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err
    assert "night: " in error and "too few lit pixels" in error and "plateau" not in error


def test_subfolders_holding_photographs_are_named_not_read(tmp_path):
    write_exr(tmp_path / "lamps.exr", _lamps())
    for name, held in [("day", "sun.exr"), ("night", "moon.hdr"), ("notes", "notes.txt")]:
        (tmp_path / name).mkdir()
        (tmp_path / name / held).write_bytes(b"")
    with pytest.warns(UserWarning, match=r"HDR files in its subfolders day, night are not read"):
        assert [path.name for path in SceneSource(tmp_path).folder.files] == ["lamps.exr"]


def test_infinite_light_in_a_photograph_with_other_primaries_is_read_not_skipped(tmp_path):
    """+Inf in an EXR whose chromaticities name Display P3: the matrix to Rec. 709 ran first and turned Inf into
    NaN and -Inf, so the photograph was skipped as "NaN or -Inf pixels". The light is replaced, then converted."""
    from hdrcam.data.hdr_folder import read_hdr_image

    pixels = _lamps(3)
    pixels[10:16, 10:16] = np.inf
    p3 = (0.680, 0.320, 0.265, 0.690, 0.150, 0.060, 0.3127, 0.3290)
    OpenEXR.File({"type": OpenEXR.scanlineimage, "chromaticities": p3}, {"RGB": pixels}).write(
        str(tmp_path / "sun.exr"))
    with pytest.warns(UserWarning, match=r"\+Inf"):
        image = read_hdr_image(tmp_path / "sun.exr", infinite_as_peak=True)
    assert np.isfinite(image).all() and image[12, 12].min() > 0


def test_a_name_seeds_the_same_crop_whether_stored_composed_or_decomposed():
    """macOS stores "Café.exr" decomposed (NFD), Linux composed (NFC): the same photograph got two seeds."""
    import unicodedata

    from hdrcam.data.scenes import name_seed

    assert name_seed(unicodedata.normalize("NFD", "Café.exr")) == name_seed(unicodedata.normalize("NFC", "Café.exr"))
