"""Author the generic head's complete Facial Animation Tables and store them beside it.

The 66 low-level FAPs (from the sculpted shapes, ``fmc.author.author_from_shapes``), the
15 visemes and 7 expressions (``fmc.high_level.author_high_level``) go to
``data/generic_head/generic_head_fat.npz`` (int16-quantised, see ``mpeg4.io.fat_npz``);
``mpeg4.generic_head.load_generic_head(with_fat=True)`` attaches them.

Usage: ``python3 scripts/build_generic_fat.py [-o data/generic_head/generic_head_fat.npz]``
(about a second; it reads the committed ``generic_head.glb``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fmc.author import author_from_shapes  # noqa: E402
from fmc.high_level import author_high_level  # noqa: E402
from mpeg4.generic_head import GENERIC_HEAD_DIR, load_generic_head  # noqa: E402
from mpeg4.io.fat_npz import quantisation_error, write_fat_npz  # noqa: E402


def build_generic_fat(head=None):
    """The generic head's full FAT set (a fresh authoring) and its per-FAP report."""
    head = load_generic_head() if head is None else head
    fat, report = author_from_shapes(head)
    fat.update(author_high_level(head))
    return fat, report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", type=Path, default=GENERIC_HEAD_DIR / "generic_head_fat.npz")
    args = ap.parse_args(argv)
    head = load_generic_head()
    fat, report = build_generic_fat(head)
    write_fat_npz(fat, args.out)
    size = args.out.stat().st_size
    print(f"written: {args.out} ({len(fat)} tables, {size / 1e6:.2f} MB; "
          f"largest quantisation error {quantisation_error(fat, head.fapu) * 1e6:.2f} um)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
