import numpy as np
import pytest

from mpeg4 import FAPU, InputError, fapu_from_points


def _points(**over):
    p = {"3.1": [0.032, 0.0355, 0.09], "3.3": [0.032, 0.0245, 0.09], "3.5": [0.032, 0.03, 0.095],
         "3.6": [-0.032, 0.03, 0.095], "9.15": [0, -0.012, 0.11], "2.2": [0, -0.029, 0.105],
         "8.3": [0.025, -0.03, 0.1], "8.4": [-0.025, -0.03, 0.1]}
    p.update(over)
    return {k: np.array(v) for k, v in p.items()}


def test_fapu_formulas():
    f = fapu_from_points(_points())
    assert f.IRISD0 == pytest.approx(0.011)
    assert f.ES0 == pytest.approx(0.064)
    assert f.ENS0 == pytest.approx(0.042)
    assert f.MNS0 == pytest.approx(0.017)
    assert f.MW0 == pytest.approx(0.050)
    assert f.unit("MNS") == pytest.approx(0.017 / 1024)
    assert f.unit("AU") == 1e-5
    assert f.of_fap(3) == f.unit("MNS") and f.of_fap(48) == 1e-5


def test_missing_or_swapped_points_are_reported():
    p = _points()
    del p["9.15"]
    with pytest.raises(InputError, match="feature point 9.15 is missing; it is needed to measure ENS0"):
        fapu_from_points(p, where="x.glb")
    with pytest.raises(InputError, match="ES0 .* is not positive.*swapped"):
        fapu_from_points(_points(**{"3.5": [-0.032, 0.03, 0.095], "3.6": [0.032, 0.03, 0.095]}))
    with pytest.raises(InputError, match="unknown FAP unit"):
        FAPU(1, 1, 1, 1, 1).unit("XX")
