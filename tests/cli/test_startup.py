"""Start-up: ``hdrcam --help``, every ``hdrcam COMMAND --help`` and ``import hdrcam`` import nothing heavy
(torch, OpenCV, SciPy, colour); the network's libraries load only when a command runs one."""

from __future__ import annotations

import json
import subprocess
import sys

from hdrcam.cli import COMMAND_MODULES

HEAVY = ("torch", "cv2", "scipy", "colour")

PROBE = """
import contextlib, io, json, sys
from hdrcam.cli import main
argv = json.loads(sys.argv[1])
with contextlib.redirect_stdout(io.StringIO()) as shown:
    try:
        main(argv)
    except SystemExit as stop:
        status = stop.code
print(json.dumps({"status": status, "shown": len(shown.getvalue()),
                  "heavy": sorted(name for name in %r if name in sys.modules)}))
""" % (HEAVY,)


def _probe(argv: list[str]) -> dict:
    done = subprocess.run([sys.executable, "-c", PROBE, json.dumps(argv)], capture_output=True, text=True,
                          check=True)
    return json.loads(done.stdout)


def test_top_level_help_imports_nothing_heavy():
    result = _probe(["--help"])
    assert result == {"status": 0, "shown": result["shown"], "heavy": []} and result["shown"] > 500


def test_every_command_help_imports_nothing_heavy():
    for command in COMMAND_MODULES:
        argv = [command, "bracket", "--help"] if command == "capture" else \
            [command, "psf", "--help"] if command == "calibrate" else [command, "--help"]
        result = _probe(argv)
        assert result["status"] == 0 and result["shown"] > 100, (command, result)
        assert result["heavy"] == [], (command, result)


def test_import_hdrcam_imports_nothing_heavy():
    done = subprocess.run([sys.executable, "-c", "import sys, hdrcam; print(sorted(n for n in %r if n in "
                           "sys.modules) + sorted(n for n in ('numpy',) if n in sys.modules))" % (HEAVY,)],
                          capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
