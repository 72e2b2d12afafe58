"""Draw the shipped feature-point triangulation of Facial Motion Cloning over the generic
head's skin in the alignment space (angle across, height up).

Usage: ``python3 scripts/render_fp_triangulation.py [-o docs/fp_triangulation.png]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fmc.clone import alignment_space, load_fp_triangulation, vertex_positions  # noqa: E402
from mpeg4.generic_head import load_generic_head  # noqa: E402
from mpeg4.io.atomic import atomic_write  # noqa: E402


def _draw(tri, pos, skin, lo, hi, width):
    """One panel: the skin's vertices (grey), the triangles, the vertices named."""
    scale = (width - 1) / (hi - lo)[0]
    image = np.full((int((hi - lo)[1] * scale) + 1, width, 3), 255, np.uint8)

    def px(p):
        return int(round((p[0] - lo[0]) * scale)), int(round(image.shape[0] - 1 - (p[1] - lo[1]) * scale))

    for p in skin:
        x, y = px(p)
        if 0 <= x < width and 0 <= y < image.shape[0]:
            image[y, x] = (200, 200, 200)
    for t in tri.triangles:
        for a, b in ((0, 1), (1, 2), (2, 0)):
            cv2.line(image, px(pos[t[a]]), px(pos[t[b]]), (90, 90, 90), 1, cv2.LINE_AA)
    for name, p, frame in zip(tri.names, pos, tri.frame):
        cv2.circle(image, px(p), 3, (200, 120, 40) if frame else (40, 40, 200), -1, cv2.LINE_AA)
        cv2.putText(image, name, (px(p)[0] + 4, px(p)[1] - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1,
                    cv2.LINE_AA)
    cv2.rectangle(image, (0, 0), (width - 1, image.shape[0] - 1), (0, 0, 0), 1)
    return image


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "docs" / "fp_triangulation.png")
    ap.add_argument("--width", type=int, default=1600, help="image width in pixels")
    args = ap.parse_args(argv)
    head = load_generic_head()
    tri = load_fp_triangulation()
    pos = vertex_positions(head, tri)[:, :2]
    skin = alignment_space(head, head.skin.vertices)[:, :2]
    # The whole frame, and below it the face at a larger scale.
    image = np.concatenate([_draw(tri, pos, skin, np.array([-np.pi, -1.6]), np.array([np.pi, 2.2]), args.width),
                            _draw(tri, pos, skin, np.array([-0.75, -0.08]), np.array([0.75, 1.45]), args.width)])
    ok, data = cv2.imencode(".png", image[..., ::-1])
    with atomic_write(args.out, "wb") as f:
        f.write(data.tobytes())
    print(f"written: {args.out} ({len(data) / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
