"""Fixtures of the annotation page's browser tests."""

import os
import select
import signal
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _start(*args):
    """``python -m recon annotate ARGS --no-browser``: the process and the page's URL."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "recon", "annotate", *map(str, args), "--no-browser"], cwd=ROOT,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ready, _, _ = select.select([proc.stdout], [], [], 60)
    line = proc.stdout.readline() if ready else ""
    if not line.startswith("annotate: "):
        proc.kill()
        pytest.fail(f"recon annotate did not start: {line!r} {proc.stderr.read()}")
    return proc, line.split(" ", 1)[1].strip()


def _stop(proc):
    """Ctrl-C, as a user stops it (killed if it does not stop within 10 s)."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@pytest.fixture
def annotate_cli():
    """``start(*args) -> (process, url)`` and ``stop(process)`` for ``recon annotate``."""
    return SimpleNamespace(start=_start, stop=_stop)
