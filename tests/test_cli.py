"""The command lines: help texts, python -m, one-line errors."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from chain.cli import recon_app
from fmc.cli import app as fmc_app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()


@pytest.mark.parametrize("app, commands", [(recon_app, ["example", "fit", "build", "batch", "annotate", "preview"]),
                                           (fmc_app, ["info", "convert", "author", "play", "say", "animate", "clone", "fap-info"])])
def test_help_describes_every_command(app, commands):
    out = runner.invoke(app, ["--help"])
    assert out.exit_code == 0
    for c in commands:
        assert c in out.output
        sub = runner.invoke(app, [c, "--help"])
        assert sub.exit_code == 0 and len(sub.output) > 100


@pytest.mark.parametrize("module", ["recon", "fmc"])
def test_python_m_works(module):
    out = subprocess.run([sys.executable, "-m", module, "--help"], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0 and "Usage" in out.stdout


@pytest.mark.parametrize("argv, needle", [
    (["fmc", "info", "no_such_head.glb"], "no_such_head.glb: head file not found"),
    (["fmc", "fap-info", "no_such.fap"], "no_such.fap"),
    (["recon", "preview", "missing.obj"], "missing.obj"),
    (["recon", "annotate", "nope.jpg", "side.jpg", "--no-browser"], "nope.jpg: front photo not found"),
])
def test_missing_files_give_one_line_errors(argv, needle, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT))  # this checkout's packages, whatever is installed
    out = subprocess.run([sys.executable, "-m", *argv], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert out.returncode == 2
    assert needle in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert "Traceback" not in out.stderr


def test_readme_starts_with_the_two_commands_ci_runs():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert lines[0] == "```bash" and lines[3] == "```"
    install, test = lines[1], lines[2]
    assert "install.sh" in install and "recon example" in install
    ci = (ROOT / ".ci" / "run").read_text()
    assert "bash install.sh" in ci and test in ci
