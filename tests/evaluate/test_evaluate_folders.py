"""``hdrcam evaluate`` on the folders judges bring: no --out, damaged or odd files among the photographs, names
that clash or are not UTF-8, photographs that cannot be scored."""

from __future__ import annotations

import time

from hdrcam.cli import main

QUICK = ["evaluate", "--size", "32", "--count", "1", "--no-partner"]


def test_without_out_each_run_writes_a_new_folder_in_the_working_directory(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(time, "strftime", lambda layout, *when: "evaluate-20250102-030405")
    (tmp_path / "evaluate-20250102-030405").mkdir()  # an earlier run's folder, same second: kept as it is
    assert main(QUICK) == 0 and main(QUICK) == 0
    assert not any((tmp_path / "evaluate-20250102-030405").iterdir())
    printed = capsys.readouterr().out
    for name in ("evaluate-20250102-030405-2", "evaluate-20250102-030405-3"):
        assert (tmp_path / name / "summary.md").is_file() and f"wrote {name}/metrics.csv" in printed
