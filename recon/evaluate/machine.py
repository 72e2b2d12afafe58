"""What a benchmark ran on: the processor and the versions of the numeric libraries.

The same code gave different detected points on two machines (most likely the face
mesh's network, which runs on the CPU, computing a little differently on another
processor; a profile fit may then settle in another local optimum), so a benchmark's
figures are only comparable with the machine's description beside them.
"""

from __future__ import annotations

import os
import platform
from importlib import metadata

__all__ = ["LIBRARIES", "describe_machine"]

#: Distributions whose versions a benchmark's figures depend on.
LIBRARIES = ("numpy", "scipy", "scikit-image", "opencv-contrib-python-headless", "mediapipe")


def _processor() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown processor"


def describe_machine() -> str:
    """One line: processor, CPU count, Python and the versions of :data:`LIBRARIES`
    (``absent`` for one that is not installed)."""
    versions = []
    for name in LIBRARIES:
        try:
            versions.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            versions.append(f"{name} absent")
    return (f"{_processor()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
            + ", ".join(versions))
