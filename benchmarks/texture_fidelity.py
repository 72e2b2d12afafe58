"""Texture fidelity: re-projection PSNR/SSIM, seam smoothness and albedo error on ICT identities.

For each identity (seeds 1000+k; ``recon.evaluate.synthetic``: painted skin, 1024x1280 photos
through a 100 mm-equivalent lens at 1.8 m, lit by a key light that moves with the camera
plus ambient) the head is built twice from the two photos and the feature points' true
pixels (``recon.build.build_head``, 2048² texture): keeping the photos' light in the
texture (``keep_lighting=True``, the *lit* texture) and with each photo's light taken out
(the default, the *albedo* texture, ``recon.texture.delight``).

* Re-projection. The lit texture is rendered unlit with the front photo's fitted camera and
  compared with the photo where the skin is seen inside the front region
  (``recon.evaluate.fidelity.reprojection``); then with the side photo's fitted camera against the
  side photo, over all the skin it sees and over the skin the texture takes from the side
  photo, with the mean colour difference (render minus photo, grey levels) over the cheek
  in front of the ear (``recon.evaluate.fidelity.cheek_vertices``: skin facing the side
  camera within 45°, between the eyes' and the jaw's heights) and the streak figure there:
  the render's mean squared horizontal and vertical gradients, each against the photo's
  own (``cheek_gradient_x_ratio``, ``_y_ratio``), and ``cheek_streaks``, the second over
  the first: 1 when the texture keeps the photo's grain, above 1 for horizontal streaks
  (``recon.evaluate.fidelity.side_reprojection``). The albedo texture is compared the same way but
  rendered *relit with the photo's light* (``recon.evaluate.synthetic.PHOTO_LIGHT``, ambient
  ``PHOTO_AMBIENT``; ``albedo_*`` lines): rendered unlit it could not match a lit photo.
  The de-lighting itself never sees that light.
* Albedo error. Both textures against the painted colour at every skin vertex
  (``recon.evaluate.synthetic.skin_albedo``, skin-tone vertices only: no hair, brows, lips, lashes):
  mean absolute colour error per region (``face``: all; ``front``: the front photo's region
  but the cheek; ``cheek``: as above; ``side``: the side photo's layer), the
  cheek's brightness step against the front, and the error of the face's left-right
  difference (``recon.evaluate.fidelity.albedo_error``).
* Seams: each texture's layers blended three ways, mean gradient magnitude in an 8-pixel
  band across the layers' borders (``recon.evaluate.fidelity.seam_smoothness``; ``albedo_seam_*``
  for the albedo texture's).

The embedded example (ICT identity 5, photographed the same way) comes first.

Run: ``python3 benchmarks/texture_fidelity.py [--identities 10]``
Prints ``name: value unit`` lines; the last line is a summary.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

_REGIONS = ("face", "front", "cheek", "side")


def _measure(pair, masks, person, data, ipd, focal, size):
    """Figures of the lit and the albedo texture of one photo pair."""
    from recon.build import build_head
    from recon.evaluate.fidelity import albedo_error, reprojection, seam_smoothness, side_reprojection
    from recon.evaluate.synthetic import PHOTO_AMBIENT, PHOTO_LIGHT, skin_albedo

    out = {}
    fm, sm = (None, None) if masks is None else (masks["front"], masks["side"])
    truth = None if person is None else skin_albedo(person, data)
    for kind, keep, light in (("lit", True, None), ("albedo", False, (PHOTO_LIGHT, PHOTO_AMBIENT))):
        r = build_head(pair, ipd_mm=ipd, focal_px=focal, texture_size=size, keep_lighting=keep)
        out[kind] = {"front": reprojection(r.head, pair.front, r.cameras["front"], fm, light=light),
                     "side": side_reprojection(r.head, r.skin, pair.side, r.cameras["side"], sm, light=light),
                     "delight_s": r.skin.timings.get("delight", 0.0)}
        if truth is not None:
            out[kind]["albedo"] = albedo_error(r.head, r.skin, truth, r.cameras["side"], skin_tone=person.skin_rgb,
                                               albedo_gain=not keep)
        out["seams" if keep else "albedo_seams"] = seam_smoothness(r.skin.layers, r.skin.masks)
    return out


def _print_case(prefix, m):
    for kind in ("lit", "albedo"):
        p = f"{prefix}_" if kind == "lit" else f"{prefix}_albedo_"
        fid, side = m[kind]["front"], m[kind]["side"]
        print(f"{p}psnr: {fid.psnr_db:.2f} dB")
        print(f"{p}ssim: {fid.ssim:.4f}")
        print(f"{p}side_psnr: {side.psnr_db:.2f} dB")
        print(f"{p}side_ssim: {side.ssim:.4f}")
        print(f"{p}side_layer_psnr: {side.side_layer_psnr_db:.2f} dB")
        print(f"{p}cheek_grey_difference: {side.cheek_grey:.1f} grey")
        gx, gy = side.cheek_gradient
        print(f"{p}cheek_gradient_x_ratio: {gx:.3f}")
        print(f"{p}cheek_gradient_y_ratio: {gy:.3f}")
        print(f"{p}cheek_streaks: {side.cheek_streaks:.3f}")
    for kind in ("lit", "albedo"):
        a = m[kind].get("albedo")
        if a is None:
            continue
        for reg in _REGIONS:
            print(f"{prefix}_{kind}_texture_albedo_mae_{reg}: {a.mae[reg]:.2f} grey")
        print(f"{prefix}_{kind}_texture_cheek_minus_front: {a.cheek_minus_front:+.2f} grey")
        print(f"{prefix}_{kind}_texture_left_right_error: {a.left_right:.2f} grey")
    for key, name in (("seams", "seam_gradient"), ("albedo_seams", "albedo_seam_gradient")):
        for k, v in m[key].items():
            print(f"{prefix}_{name}_{k}: {v:.3f} grey/px")
    print(f"{prefix}_delight_time: {m['albedo']['delight_s']:.3f} s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--identities", type=int, default=10)
    ap.add_argument("--texture-size", type=int, default=2048)
    args = ap.parse_args(argv)
    from recon.build import PhotoPair, load_pair
    from recon.example import EXAMPLE_FDP, example_camera
    from recon.evaluate.synthetic import default_ict_path, load_ict, make_person, synthetic_pair

    have_ict = default_ict_path().exists()
    data = load_ict() if have_ict else None
    cam = example_camera()
    pair = load_pair(EXAMPLE_FDP)
    person = make_person(5, data) if have_ict else None  # scripts/make_example_photos.py's SEED
    _print_case("example", _measure(pair, None, person, data, cam["ipd_mm"], cam["focal_px"], args.texture_size))
    if not have_ict:
        print(f"skipped: {default_ict_path()} is absent (the ICT FaceKit test data)")
        return 0
    rows = []
    for k in range(args.identities):
        seed = 1000 + k
        t0 = time.perf_counter()
        sp = synthetic_pair(seed, data=data)
        p = PhotoPair(sp.front, sp.side, sp.fdp, {})
        m = _measure(p, sp.masks, sp.person, data, sp.person.ipd_mm, sp.focal_px, args.texture_size)
        lit, alb, seams = m["lit"], m["albedo"], m["seams"]
        fid, side = lit["front"], lit["side"]
        la, aa = lit["albedo"], alb["albedo"]
        rows.append((fid.psnr_db, fid.ssim, seams["multiband"], seams["feather"], seams["hard"],
                     side.psnr_db, side.ssim, side.side_layer_psnr_db, side.cheek_grey,
                     alb["front"].psnr_db, alb["side"].psnr_db, alb["side"].side_layer_psnr_db, alb["side"].cheek_grey,
                     la.mae["face"], la.mae["cheek"], la.cheek_minus_front, la.left_right,
                     aa.mae["face"], aa.mae["cheek"], aa.cheek_minus_front, aa.left_right, alb["delight_s"],
                     m["albedo_seams"]["multiband"], m["albedo_seams"]["feather"], m["albedo_seams"]["hard"],
                     side.cheek_streaks, alb["side"].cheek_streaks))
        print(f"identity_{seed}: lit psnr {fid.psnr_db:.2f} dB, ssim {fid.ssim:.4f}; side psnr {side.psnr_db:.2f} dB, "
              f"side layer {side.side_layer_psnr_db:.2f} dB, cheek {side.cheek_grey:+.1f} grey, streaks "
              f"{side.cheek_streaks:.2f}; albedo relit psnr "
              f"{alb['front'].psnr_db:.2f} dB, side {alb['side'].psnr_db:.2f} dB, cheek {alb['side'].cheek_grey:+.1f} "
              f"grey; albedo error face/cheek lit {la.mae['face']:.1f}/{la.mae['cheek']:.1f}, de-lit "
              f"{aa.mae['face']:.1f}/{aa.mae['cheek']:.1f} grey; seam gradient multiband "
              f"{seams['multiband']:.3f} / feather {seams['feather']:.3f} / hard {seams['hard']:.3f} grey/px "
              f"({time.perf_counter() - t0:.1f} s)", flush=True)
    a = np.array(rows)
    names = ("psnr", "ssim", "seam_multiband", "seam_feather", "seam_hard", "side_psnr", "side_ssim",
             "side_layer_psnr", "cheek_grey_difference", "albedo_psnr", "albedo_side_psnr", "albedo_side_layer_psnr",
             "albedo_cheek_grey_difference", "lit_texture_albedo_mae_face", "lit_texture_albedo_mae_cheek",
             "lit_texture_cheek_minus_front", "lit_texture_left_right_error", "albedo_texture_albedo_mae_face",
             "albedo_texture_albedo_mae_cheek", "albedo_texture_cheek_minus_front",
             "albedo_texture_left_right_error", "delight_time", "albedo_seam_multiband", "albedo_seam_feather",
             "albedo_seam_hard", "cheek_streaks", "albedo_cheek_streaks")
    units = ("dB", "", "grey/px", "grey/px", "grey/px", "dB", "", "dB", "grey", "dB", "dB", "dB", "grey",
             "grey", "grey", "grey", "grey", "grey", "grey", "grey", "grey", "s", "grey/px", "grey/px", "grey/px", "", "")
    worst_max = {2, 3, 4, 13, 14, 16, 17, 18, 20, 21, 22, 23, 24, 25, 26}
    for j, (n, u) in enumerate(zip(names, units)):
        print(f"{n}_median: {np.median(a[:, j]):.4f} {u}".rstrip())
        worst = "max" if j in worst_max else "min"  # signed differences: the min is the darkest
        print(f"{n}_{worst}: {getattr(a[:, j], worst)():.4f} {u}".rstrip())
    ordered = int(np.sum((a[:, 2] < a[:, 3]) & (a[:, 2] < a[:, 4])))
    ordered_albedo = int(np.sum((a[:, 22] < a[:, 23]) & (a[:, 22] < a[:, 24])))
    print(f"summary: {len(a)} identities; lit texture (unlit render) re-projection PSNR median "
          f"{np.median(a[:, 0]):.1f} dB, side {np.median(a[:, 5]):.1f} dB, cheek {np.median(a[:, 8]):+.1f} grey, "
          f"streaks {np.median(a[:, 25]):.2f}; "
          f"albedo texture relit with the photo's light PSNR {np.median(a[:, 9]):.1f} dB, side "
          f"{np.median(a[:, 10]):.1f} dB, cheek {np.median(a[:, 12]):+.1f} grey; albedo error (face/cheek) lit "
          f"{np.median(a[:, 13]):.1f}/{np.median(a[:, 14]):.1f}, de-lit {np.median(a[:, 17]):.1f}/"
          f"{np.median(a[:, 18]):.1f} grey; multiresolution seams smoother than feathered and hard in "
          f"{ordered}/{len(a)} (lit), {ordered_albedo}/{len(a)} (albedo)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
