"""tools/scene_kind_table.py: per-scene-kind gains from evaluate's metrics.csv, whatever the checkpoint's name."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
from scene_kind_table import main  # noqa: E402


def _write_metrics(path: Path, pipeline: str, scores: dict[str, tuple[float, float, float]]) -> Path:
    """metrics.csv as evaluate writes it: per image, ldr, the pipeline and its network alone."""
    lines = ["image,method,psnr_linear,pu21_psnr,psnr_mu,clipped_fraction"]
    for image, (ldr, full, network) in scores.items():
        for method, value in (("ldr", ldr), (pipeline, full), (f"{pipeline}-network", network)):
            lines.append(f"{image},{method},{value},30,30,0.015")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_table_of_a_named_checkpoint_counts_its_own_harm(tmp_path, capsys):
    """evaluate --checkpoint runs/x/main/model.pt names its rows `main`, not `hdrcam`: the table was a traceback
    (ValueError: 'hdrcam' is not in list); the harm column counts the named pipeline."""
    split = tmp_path / "split.csv"
    split.write_text("file,scene_kind,split\na.exr,daylight,val\nb.hdr,night,val\n")
    metrics = _write_metrics(tmp_path / "metrics.csv", "main", {"a": (50.0, 51.0, 49.0), "b": (40.0, 39.5, 42.0)})
    out = tmp_path / "table.md"
    assert main(["--split", str(split), "--metrics", str(metrics), "--out", str(out)]) == 0
    rows = {line.split(" | ")[0].lstrip("| "): line for line in out.read_text().splitlines()[2:]}
    assert "photos > 0.3 dB below LDR (main)" in out.read_text()
    assert rows["daylight"].endswith("| +1.00 (+1.00) | -1.00 (-1.00) | 0 |")
    assert rows["night"].endswith("| -0.50 (-0.50) | +2.00 (+2.00) | 1 |")
    assert rows["all"].endswith("| +0.25 (-0.50) | +0.50 (-1.00) | 1 |")
    capsys.readouterr()
