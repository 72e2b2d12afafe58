"""Shape accuracy against ground truth: ICT FaceKit identities seen by two synthetic cameras.

For each identity (``neutral + sum z_i identity_i``, z ~ N(0, 1), fixed seeds) its feature
points (the generic head's bindings evaluated on the identity's vertices) are projected
into a front and a side camera 1024 px high, orthographic or a 50 mm-equivalent pinhole,
with pixel noise sigma; :func:`recon.shape.calibrate.calibrate` recovers 3D points (given the true
interpupillary distance) and the generic head is fitted to them three ways: similarity
only (baseline), thin-plate RBF, and the exact Sibson DFFD. The per-vertex error against
the identity is measured after removing the free translation (the photos fix no origin),
taken as the mean offset of the feature points.

Then the same from photos (``--photos N`` people, 0 to skip): synthetic front and side photos
of painted ICT identities (``recon.evaluate.synthetic``), clean and from the harder set
(``hard_pair``: hair with volume, skin types I–VI, clothes, glasses, busy backgrounds), go
through the automatic route — ``recon.landmarks.detect_images``, then
``recon.shape.fit.fit_head`` as ``recon build`` runs it (unreviewed points, outliers
dropped; the true interpupillary distance and focal length given), then the profile moved
onto the side photo's outline (``recon.build.follow_side_outline``, as the build does
it) — and the head is measured against the identity the same way: over the face, over the
top of the skull (above the middle of the hairline, 11.1), which the hard set's hair hides,
per hair style, and over the face's midline from the brow to the chin before and after the
profile step (``_profile_points_only`` and ``_profile``).

Run: ``python3 benchmarks/shape_accuracy.py [--identities 20] [--photos 6] [--heatmap out.png]``
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
NPZ = ROOT.parent / "shared" / "data" / "ict_facekit" / "ict_facekit.npz"
FACE = slice(0, 9409)  # ICT "Full face area"
F_50MM = 1024 * 50.0 / 24.0  # 50 mm lens on a 24 mm-high sensor, 1024 px high
DISTANCE = 1.0  # camera to head centre, metres (perspective)


def identity_vertices(data, rng, n_modes=100):
    z = rng.standard_normal(n_modes)
    v = data["vertices"].astype(np.float64) + np.tensordot(z, data["identity_deltas"][:n_modes].astype(np.float64), 1)
    return v * 0.01  # cm → m


def part_vertices(head, ict):
    from mpeg4.generic_head import ict_vertex_ids

    return {name: ict[idx] for name, idx in ict_vertex_ids(head).items()}


def project(points, view, perspective, size=1024):
    """FP id → pixel for one synthetic photo; only the points that view can show."""
    from mpeg4 import FEATURE_POINTS

    out = {}
    c = (size - 1) / 2
    for i, p in points.items():
        fp = FEATURE_POINTS[i]
        if view == "front":
            if fp.front == "N":
                continue
            depth = DISTANCE - p[2]
            s = F_50MM / depth if perspective else 3000.0
            out[i] = np.array([c + p[0] * s, c - p[1] * s])
        else:  # camera on +x: shows the face's left side, the nose points to the image's left
            if fp.side_view == "N" or fp.side == "R":
                continue
            depth = DISTANCE - p[0]
            s = F_50MM / depth if perspective else 3000.0
            out[i] = np.array([c - p[2] * s, c - p[1] * s])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--identities", type=int, default=20)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.0, 1.0, 3.0])
    ap.add_argument("--far-field", choices=["similarity", "affine"], default="similarity",
                    help="how the bounding control points follow the feature points")
    ap.add_argument("--photos", type=int, default=6,
                    help="people built from synthetic photos, clean and hard (0: skip)")
    ap.add_argument("--heatmap", type=Path, help="write a per-vertex error render of the first identity (DFFD, exact)")
    args = ap.parse_args(argv)
    from recon.evaluate.machine import describe_machine

    print(f"# machine: {describe_machine()}")
    if not NPZ.exists():
        print(f"skipped: {NPZ} is absent (the ICT FaceKit test data)")
        return 0
    from mpeg4.generic_head import load_generic_head
    from recon.shape.calibrate import calibrate
    from recon.shape.deform import deform_head, fit_similarity

    data = np.load(NPZ)
    generic = load_generic_head()
    results = {}
    t0 = time.perf_counter()
    heat = None
    for k in range(args.identities):
        ict = identity_vertices(data, np.random.default_rng(1000 + k))
        truth_parts = part_vertices(generic, ict)
        truth = generic.with_vertices(truth_parts)
        truth_fp = truth.fp_positions()
        truth_skin = truth.skin.vertices
        ipd = np.linalg.norm(truth_fp["3.5"] - truth_fp["3.6"]) * 1000
        for perspective in (False, True):
            for sigma in args.noise:
                rng = np.random.default_rng(k * 100 + int(sigma * 10) + perspective)
                views = {}
                for view in ("front", "side"):
                    px = project(truth_fp, view, perspective)
                    views[view] = {i: p + rng.normal(0, sigma, 2) for i, p in px.items()}
                cal = calibrate(views["front"], views["side"], generic, ipd_mm=ipd,
                                focal_px=F_50MM if perspective else None,
                                front_size=(1024, 1024), side_size=(1024, 1024), height_tol_mm=30)
                goal = {i: p for i, p in cal.points.items() if cal.source[i] != "generic"}
                ids = list(goal)
                rest = np.array([generic.fp_position(i) for i in ids])
                heads = {"similarity": fit_similarity(rest, np.array([goal[i] for i in ids]))(generic.skin.vertices)}
                for method in ("rbf", "dffd"):
                    out = deform_head(generic, goal, method=method, far_field=args.far_field)
                    heads[method] = out.skin.vertices
                for method, v in heads.items():
                    # Remove the free translation: the mean offset of the feature points.
                    fitted = generic.with_vertices({"skin": v})
                    off = np.mean([fitted.fp_position(i) - truth_fp[i] for i in ids], axis=0)
                    err = np.linalg.norm(v - off - truth_skin, axis=1) * 1000
                    key = ("persp" if perspective else "ortho", sigma, method)
                    results.setdefault(key, []).append(err)
                    if heat is None and method == "dffd" and sigma == 0 and not perspective:
                        heat = (fitted.with_vertices({"skin": v - off}), err)
        print(f"identity {k + 1}/{args.identities} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    for (cam, sigma, method), errs in sorted(results.items()):
        e = np.stack(errs)
        face, skin = e[:, FACE].ravel(), e.ravel()
        print(f"{cam} sigma={sigma:g}px {method:<10} face: median {np.median(face):.2f} mm, mean {face.mean():.2f} mm, "
              f"p95 {np.percentile(face, 95):.2f} mm; skin: median {np.median(skin):.2f} mm, mean {skin.mean():.2f} mm, "
              f"p95 {np.percentile(skin, 95):.2f} mm")
    if args.heatmap and heat is not None:
        write_heatmap(*heat, args.heatmap)
        print(f"heatmap: {args.heatmap}")
    photo_summary = from_photos(generic, args.photos) if args.photos else ""
    d = np.stack(results[("ortho", 0.0, "dffd")])[:, FACE]
    b = np.stack(results[("ortho", 0.0, "similarity")])[:, FACE]
    print(f"summary: {args.identities} identities, orthographic exact points, face region: DFFD median "
          f"{np.median(d):.2f} mm / mean {d.mean():.2f} mm vs similarity baseline {np.median(b):.2f} / {b.mean():.2f} mm"
          + photo_summary)
    return 0


def from_photos(generic, people: int) -> str:
    """Heads built from synthetic photos by the automatic route, clean and hard; prints the
    error lines and returns the summary's part."""
    from mpeg4.errors import InputError
    from recon.evaluate.synthetic import hard_pair, synthetic_pair
    from recon.landmarks import detect_images, mediapipe_available
    from recon.build import follow_side_outline
    from recon.shape.fit import fit_head

    if not mediapipe_available():
        print("photos: skipped (mediapipe is not installed)")
        return ""
    v = generic.skin.vertices
    skull = v[:, 1] >= generic.fp_position("11.1")[1]
    profile = ((np.abs(v[:, 0]) < 0.001) & (v[:, 1] < generic.fp_position("4.1")[1])
               & (v[:, 1] > generic.fp_position("2.1")[1]) & (v[:, 2] > generic.fp_position("3.5")[2]))
    out = {}
    for name, make in (("clean", synthetic_pair), ("hard", hard_pair)):
        errs = {"face": [], "skull_top": [], "profile_points_only": [], "profile": []}
        by_hair = {}
        failed = 0
        for seed in range(people):
            t0 = time.perf_counter()
            pair = make(seed)
            truth = pair.person.head
            try:
                fdp = detect_images(pair.front, pair.side)
                fdp.metadata["reviewed"] = False  # as recon build marks detected points: outliers dropped
                head, cal = fit_head(fdp, generic=generic, ipd_mm=pair.person.ipd_mm, focal_px=pair.focal_px)
            except InputError as e:
                failed += 1
                print(f"photos {name} person {seed}: not built ({e})")
                continue
            ids = [i for i, s in cal.source.items() if s != "generic"]

            def error(h):
                off = np.mean([h.fp_position(i) - truth.fp_position(i) for i in ids], axis=0)
                return np.linalg.norm(h.skin.vertices - off - truth.skin.vertices, axis=1) * 1000

            errs["profile_points_only"].append(error(head)[profile])
            head, _ = follow_side_outline(head, fdp, pair.side, cal, pair.focal_px)
            err = error(head)
            errs["profile"].append(err[profile])
            errs["face"].append(err[FACE])
            errs["skull_top"].append(err[skull])
            hair = pair.look.hair if pair.look else "painted"
            by_hair.setdefault(hair, []).append(err[skull])
            print(f"photos {name} person {seed} ({pair.look.name if pair.look else 'clean'}): face median "
                  f"{np.median(err[FACE]):.2f} mm, skull top median {np.median(err[skull]):.2f} mm "
                  f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
        print(f"photos_{name}_built: {people - failed} of {people}")
        for region, e in errs.items():
            if e:
                e = np.concatenate(e)
                out[(name, region)] = np.median(e)
                print(f"photos_{name}_{region}_median: {np.median(e):.2f} mm (mean {e.mean():.2f}, "
                      f"p95 {np.percentile(e, 95):.2f})")
        if name == "hard":
            for hair, e in sorted(by_hair.items()):
                e = np.concatenate(e)
                print(f"photos_hard_skull_top_{hair}_median: {np.median(e):.2f} mm (p95 {np.percentile(e, 95):.2f}, "
                      f"{len(by_hair[hair])} people)")
    parts = [f"{n} face {out[(n, 'face')]:.2f} / skull top {out[(n, 'skull_top')]:.2f} mm"
             for n in ("clean", "hard") if (n, "face") in out]
    return f"; from photos ({people} people, medians): " + ", ".join(parts) if parts else ""


def write_heatmap(head, err_mm, path):
    """Front and side renders of the skin coloured by per-vertex error (0 blue … 5 mm red)."""
    import cv2

    from mpeg4.camera import Camera
    from mpeg4.render import RenderMesh, render

    skin = head.skin
    t = np.clip(err_mm / 5.0, 0, 1)
    colours = (cv2.applyColorMap((t * 255).astype(np.uint8)[:, None], cv2.COLORMAP_TURBO)[:, 0, ::-1]) / 255.0
    mesh = RenderMesh(skin.vertices, skin.triangles, colour=(1, 1, 1), vertex_colours=colours)
    panels = []
    for yaw in (0.0, 90.0):
        cam = Camera.fit(skin.vertices[FACE], 600, 720, yaw_deg=yaw, margin=0.08)
        panels.append(render([mesh], cam))
    image = np.concatenate(panels, axis=1)
    cv2.imwrite(str(path), image[..., ::-1])


if __name__ == "__main__":
    sys.exit(main())
