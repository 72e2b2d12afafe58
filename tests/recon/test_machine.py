"""The machine line the benchmarks print beside their figures."""

import os

import numpy as np

from recon.evaluate.machine import LIBRARIES, describe_machine


def test_the_machine_line_names_the_processor_count_and_each_library():
    line = describe_machine()
    assert f"{os.cpu_count()} CPUs" in line
    assert f"numpy {np.__version__}" in line
    assert all(name in line for name in LIBRARIES)
    assert "\n" not in line
