"""Tables whose skin moves no further than a little more than their own point."""

import numpy as np
import pytest

from fmc.author import JAW_FAPS
from fmc.bound import RATIO, bound_motion
from fmc.conformance import region_over_fp
from mpeg4 import FAPS
from mpeg4.generic_head import load_generic_head


def test_motion_past_the_point_saturates_smoothly_and_keeps_its_direction():
    rng = np.random.default_rng(7)
    d = rng.normal(size=(500, 3))
    d *= (np.linspace(0.0, 5.0, 500) / np.linalg.norm(d, axis=1))[:, None]  # lengths 0..5
    held = np.zeros(500, bool)
    held[-1] = True
    out = bound_motion(d, own=1.0, ratio=1.3, held=held)
    m, n = np.linalg.norm(d, axis=1), np.linalg.norm(out, axis=1)
    np.testing.assert_array_equal(out[m <= 1.0], d[m <= 1.0])  # up to the point's motion: as it was
    np.testing.assert_array_equal(out[-1], d[-1])  # held
    free = ~held
    assert n[free].max() < 1.3
    assert np.all(np.diff(n[free]) >= -1e-12)  # longer in, longer out
    cos = (out * d).sum(axis=1)[m > 0] / (n * m)[m > 0]
    np.testing.assert_allclose(cos, 1.0, atol=1e-12)
    # The slope is 1 where the cap starts: no kink in the field.
    eps = 1e-6
    a = bound_motion(np.array([[1.0 + eps, 0, 0]]), 1.0)[0, 0] - 1.0
    assert a == pytest.approx(eps, rel=1e-4)
    assert not np.shares_memory(out, d)


def test_the_generic_heads_regions_do_not_outrun_their_points():
    """Every low-level translation table but the jaw's, alone at ±300 and ±512: no skin
    vertex moves more than RATIO times the table's own point (1.67 before, for push_t_lip)."""
    head = load_generic_head(with_fat=True)
    worst = {}
    for (n, hl) in head.fat:
        if hl or n in JAW_FAPS or not 3 <= n <= 68 or FAPS[n].kind != "translation":
            continue
        for v in (-512.0, -300.0, 300.0, 512.0):
            r = region_over_fp(head, n, v)
            if np.isfinite(r):
                worst[n] = max(worst.get(n, 0.0), r)
    assert len(worst) >= 50
    over = {n: round(r, 3) for n, r in worst.items() if r > RATIO + 1e-6}
    assert not over, over
