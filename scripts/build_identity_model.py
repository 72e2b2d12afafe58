"""Derive the statistical identity model shipped beside the generic head.

The ICT FaceKit's first 50 identity modes (of its 100; each already one standard deviation
of its PCA mode), restricted to the generic head's vertices in part order and turned into
metres, go to ``data/generic_head/identity_model.npz`` as int8 with one scale per mode
(:mod:`recon.shape.identity` reads it). Only half the modes are kept so that the tests of
the front-only route, on identities drawn with all 100, measure what the model cannot
simply contain.

Usage: ``python3 scripts/build_identity_model.py [--modes 50] [-o data/generic_head/identity_model.npz]``
(a few seconds; reads ``../shared/data/ict_facekit/ict_facekit.npz`` and the committed
``generic_head.glb``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mpeg4.generic_head import GENERIC_HEAD_DIR, load_generic_head  # noqa: E402
from recon.shape.identity import build_identity_model, write_identity_model  # noqa: E402

DEFAULT_NPZ = ROOT.parent / "shared" / "data" / "ict_facekit" / "ict_facekit.npz"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--npz", type=Path, default=DEFAULT_NPZ)
    ap.add_argument("--modes", type=int, default=50)
    ap.add_argument("-o", "--out", type=Path, default=GENERIC_HEAD_DIR / "identity_model.npz")
    args = ap.parse_args(argv)
    if not args.npz.exists():
        print(f"build_identity_model: {args.npz}: ICT FaceKit data not found (fix: put ict_facekit.npz there "
              f"or pass --npz)", file=sys.stderr)
        return 2
    with np.load(args.npz) as d:
        deltas = d["identity_deltas"][:args.modes]
    model = build_identity_model(deltas, load_generic_head())
    error = write_identity_model(model, args.out)
    print(f"written: {args.out} ({args.out.stat().st_size / 1e6:.2f} MB), {model.n_modes} modes over "
          f"{model.n_vertices} vertices, largest quantisation error {error * 1e3:.3f} mm per mode")
    return 0


if __name__ == "__main__":
    sys.exit(main())
