"""Foreign heads from the shared test data: marked, cloned and speaking within bounds."""

from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
MASK = ROOT.parent / "shared" / "data" / "foreign_heads" / "mediapipe_canonical_face" / "canonical_face_model.obj"


@pytest.mark.skipif(not MASK.exists(), reason=f"the MediaPipe face mask is not there ({MASK})")
def test_speech_on_the_mediapipe_mask_keeps_its_values_bounded(tmp_path):
    """The mask's cloned tables cannot close its lips everywhere; the lip closure used to
    run away (FAP 9 and 11 at 7174 and -60960). Now it does the best it can within one
    MNS0 of travel."""
    pytest.importorskip("mediapipe")
    from chain import clone_onto
    from fmc.animate import say
    from fmc.coarticulation import CLOSING_LIMIT
    from mpeg4.io import read_fap, save_head

    head, warnings = clone_onto(None, MASK)
    assert any("unreviewed" in w for w in warnings)
    save_head(head, tmp_path / "mask.glb")
    paths = say(tmp_path / "mask.glb", "Bob met my papa.", tmp_path / "say", preview=False)
    stream = read_fap(paths["stream"])
    lips = stream.values[:, [f - 1 for f in (4, 5, 8, 9, 10, 11, 16, 17)]]
    assert np.isfinite(lips).all() and np.abs(lips).max() <= CLOSING_LIMIT
