"""Make the embedded example: a front and a side photo of a synthetic person, and the
feature points' true pixels in both.

The person is ICT FaceKit identity seed ``SEED`` (standard-normal identity modes, not the
model mean) with the skin painted by :mod:`recon.evaluate.synthetic`, photographed through a
100 mm-equivalent lens from 1.8 m. Writes ``data/example/front.jpg``, ``side.jpg`` and
``example.fdp.json`` (views with their images, sizes and points; the focal length in
pixels and the true interpupillary distance in ``metadata.synthetic``). The photos' EXIF
records the lens as a camera would (focal length, sensor resolution, 35 mm equivalent),
so ``recon`` takes the perspective from the photos themselves.

Run: ``python3 scripts/make_example_photos.py`` (reads ``../shared/data/ict_facekit``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mpeg4.io.atomic import atomic_write  # noqa: E402
from mpeg4.io.fdp_json import write_fdp_json  # noqa: E402
from recon.evaluate.synthetic import default_ict_path, synthetic_pair  # noqa: E402

SEED = 5
SIZE = (1024, 1280)  # width, height
FOCAL_MM = 100.0
DISTANCE = 1.8
JPEG_QUALITY = 92
DEFAULT_OUT = ROOT / "data" / "example"


def _lens_exif(focal_px: float):
    """EXIF of the camera, as a real one records it: the lens's focal length, the sensor's
    resolution and the image size (so that ``recon`` finds the focal length in pixels by
    itself), and the 35 mm equivalent (relative to the frame's diagonal)."""
    import numpy as np
    from PIL import Image

    from recon.photos import FILM_DIAGONAL_MM

    exif = Image.Exif()
    ifd = exif.get_ifd(0x8769)
    ifd[0x920A] = FOCAL_MM  # FocalLength, mm
    ifd[0xA20E] = ifd[0xA20F] = focal_px / FOCAL_MM * 10  # FocalPlaneX/YResolution, px per cm
    ifd[0xA210] = 3  # FocalPlaneResolutionUnit: centimetre
    ifd[0xA002], ifd[0xA003] = SIZE  # PixelX/YDimension
    ifd[0xA405] = round(focal_px / float(np.hypot(*SIZE)) * FILM_DIAGONAL_MM)  # FocalLengthIn35mmFilm
    return exif


def make_example(out: Path, npz: Path | None = None) -> dict[str, Path]:
    """Render the example into ``out`` and return the written paths."""
    from PIL import Image

    from recon.evaluate.synthetic import load_ict

    pair = synthetic_pair(SEED, size=SIZE, focal_mm=FOCAL_MM, distance=DISTANCE, data=load_ict(npz),
                          texture_size=2048)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"front": out / "front.jpg", "side": out / "side.jpg", "fdp": out / "example.fdp.json"}
    exif = _lens_exif(pair.fdp.metadata["synthetic"]["focal_px"])
    for name in ("front", "side"):
        with atomic_write(paths[name], "wb") as f:
            Image.fromarray(getattr(pair, name)).save(f, format="JPEG", quality=JPEG_QUALITY, optimize=True,
                                                      exif=exif)
        pair.fdp.views[name].image = paths[name].name
    pair.fdp.metadata["synthetic"].update(
        source="ICT-FaceKit identity (ICT Face Model Light, MIT), painted by recon.evaluate.synthetic",
        focal_mm=FOCAL_MM, distance_m=DISTANCE)
    write_fdp_json(paths["fdp"], pair.fdp)
    return paths


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--npz", type=Path, default=default_ict_path())
    ap.add_argument("-o", "--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    if not args.npz.exists():
        print(f"make_example_photos: {args.npz}: ICT FaceKit data not found (fix: put ict_facekit.npz there "
              f"or pass --npz)", file=sys.stderr)
        return 2
    for kind, path in make_example(args.out, args.npz).items():
        print(f"{kind}: {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
