"""The one-line refusal of a bracket without a usable point source: the count it gives as found is the sum of
the reasons it lists (README, `calibrate psf`: "Refused in one line")."""
from __future__ import annotations

import re

from hdrcam.cli import main


def test_the_found_count_adds_up_when_sources_are_clipped_whole(tmp_path, capsys):
    """Bright pinholes behind no DOE clip whole and are masked before detection, so they were named as spots
    beside a count that left them out: "1 found - 6 spots clipped in every frame, ..., 1 too close to the
    frame's edge"."""
    assert main(["capture", "bracket", "--camera", "sim", "--profile", "simulated", "--scene", "pinholes:1e9",
                 "--psf", "dirac", "--stops", "3", "--ev-step", "3", "--seed", "0", "--size", "256x192",
                 "--out", str(tmp_path / "b")]) == 0
    capsys.readouterr()
    assert main(["calibrate", "psf", str(tmp_path / "b"), "--size", "15", "--profile", "simulated",
                 "--out", str(tmp_path / "r")]) == 1
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0, error
    found = re.search(r"no usable point source: (\d+) found - (.*)$", error)
    assert found, error
    listed = [int(count) for count in re.findall(r"(?:^|, )(\d+) ", found.group(2))]
    assert "spots clipped in every frame" in error and sum(listed) == int(found.group(1)), error
