"""The automatic route on real photos, measured without 3D ground truth.

For each person (a folder with ``front.*``, ``side.*`` and optionally ``side_other.*``, any
of jpg, png, tif) it runs what a user runs, ``recon build FRONT SIDE -o OUT`` with no
annotations, and measures the head against the photos (:mod:`recon.evaluate.real_photos`):

- ``built`` (1, or 0 with the error quoted) and the wall time, split into detection, shape,
  texture and export (``build_seconds``, medians); ``built_without_side``: builds that left
  the side photo out because its edge cuts the face off (built from the front photo alone;
  their side figures are absent);
- ``point_agreement_ipd_pct``: RMS distance of the detected points from the head's points
  projected by the fitted cameras, % of the interpupillary distance (IPD), per photo (and
  ``point_agreement_worst_*``, the four worst points); ``point_agreement_kept_ipd_pct``, the
  same over the points the build kept as detected (not dropped, not brought under the hair
  or back to the skull);
- ``profile_line_ipd_pct``: the side photo's face-side outline from the brow to the chin
  against the rendered head's, mean distance in % IPD;
- ``cheek_psnr_db``: the textured head relit as the side photo is lit (the shading the build
  fitted to it) against that photo over the cheek, between the eye, the ear, the mouth and
  the jaw (:func:`recon.evaluate.real_photos.cheek_psnr`): where the seam between the
  photos' layers runs;
- ``silhouette_iou_front``, ``silhouette_iou_side``: the rendered head against the photo's
  head region (hair counted, below the chin left out);
- ``heldout_profile_line_ipd_pct``, ``heldout_silhouette_iou``: the same in ``side_other``,
  a view the build never saw, through a camera fitted to the points detected there;
  ``profile_line_refit_ipd_pct``, the profile line of the build's own side photo through a
  camera fitted that way (the build's own camera is fitted with the shape: this one shows
  what the refitted camera alone costs, and is what ``--front-only``'s figure compares with);
- ``identity_distance``: dlib's face-recognition embedding distance (the 128-D ResNet in
  ``face_recognition_models``) between each photo and the textured head rendered from its
  camera; ``identity_distance_other_people``: the same between different people's front
  photos, the baseline a render must beat (the usual same-person threshold is 0.6);
  ``identity_nearest_other_person[person]``: the distance from the person's front photo to
  the nearest other person's, and ``identity_closer_than_other_people``: for how many
  builds the render is nearer its photo than that; ``identity_distance_lights``: the mean
  of the same distance over three key lights (``IDENTITY_LIGHTS``: the one light of
  ``identity_distance`` is arbitrary, and on a turned face it moves the figure as much as
  the shape does);
- ``skin_delta_e``: CIEDE2000 between the photo's median skin colour (cheeks, forehead) and
  the albedo texture's, rendered unlit from the front camera; ``skin_delta_e_relit``: the
  same with the render relit as the photo is lit (times the shading the build fitted to the
  photo and took out of the texture); ``skin_delta_e_worst``: the largest over people.

One ``name[person]: value`` line per figure and person, then the medians over people with
the names above (failed builds count in ``built``; their figures are absent, not zero), and
a contact sheet (photo beside render, per view and person) under ``test-artifacts/``.

Run: ``python3 benchmarks/real_photos.py [FOLDER ...] [--with-other-sides] [--people N]``
(default: ``../shared/data/real_photos/pairs``). ``--with-other-sides`` also builds each
person from ``side_other`` as the side photo.

``--jitter PX [--seeds N]``: how much each figure owes to chance (with ``--front-only``,
also the unseen profile's line judged N more times with that noise on the judge's own
detection, ``front_only_profile_line_ipd_pct_range[person]``, and the median over people of
each one's median, ``front_only_profile_line_ipd_pct_jitter``). Each pair is built again N
times with the face mesh's landmarks moved by Gaussian noise of PX pixels (a fifth of a
pixel is about what another CPU's kernels change), and ``stability_<figure>_range[person]``
is the spread (largest minus smallest) of the figure over the unperturbed build and the N
others; ``stability_<figure>_range`` the median over people. A figure whose spread is
larger than the change being measured says nothing about that change.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

DEFAULT = ROOT.parent / "shared" / "data" / "real_photos" / "pairs"
PORTRAITS = ROOT.parent / "shared" / "data" / "real_photos" / "front"
EXTENSIONS = (".jpg", ".jpeg", ".png", ".tif", ".tiff")
FIGURES = ("built", "point_agreement_ipd_pct", "profile_line_ipd_pct", "silhouette_iou_front",
           "silhouette_iou_side", "heldout_profile_line_ipd_pct", "heldout_silhouette_iou", "identity_distance",
           "identity_distance_other_people", "skin_delta_e", "skin_delta_e_relit")


def photo(folder: Path, stem: str) -> Path | None:
    for ext in EXTENSIONS:
        for p in (folder / f"{stem}{ext}", folder / f"{stem}{ext.upper()}"):
            if p.exists():
                return p
    return None


def people(folders) -> list[tuple[str, Path, Path, Path | None]]:
    """(name, front, side, side_other) of every person folder under ``folders``."""
    out = []
    for folder in folders:
        for d in sorted(p for p in Path(folder).iterdir() if p.is_dir()):
            front, side = photo(d, "front"), photo(d, "side")
            if front and side:
                out.append((d.name, front, side, photo(d, "side_other")))
    return out


class Recogniser:
    """dlib's face-recognition embeddings, when dlib and its models are installed."""

    def __init__(self):
        try:
            import dlib
            import face_recognition_models as frm
        except ImportError as e:
            self.why = f"{e.name} is not installed (pip install -e '.[bench]')"
            self.ok = False
            return
        self.detector = dlib.get_frontal_face_detector()
        self.shape = dlib.shape_predictor(frm.pose_predictor_model_location())
        self.net = dlib.face_recognition_model_v1(frm.face_recognition_model_location())
        self.ok, self.why = True, None

    def embed(self, image: np.ndarray, box_hint: np.ndarray | None = None) -> np.ndarray | None:
        """128-D embedding of the largest face (or of the box around ``box_hint`` points)."""
        import dlib

        image = np.ascontiguousarray(image)
        if box_hint is not None:
            lo, hi = box_hint.min(axis=0), box_hint.max(axis=0)
            pad = 0.15 * (hi - lo)
            rect = dlib.rectangle(*(int(v) for v in (lo[0] - pad[0], lo[1] - pad[1], hi[0] + pad[0], hi[1] + pad[1])))
        else:
            found = self.detector(image, 1)
            if not found:
                return None
            rect = max(found, key=lambda r: r.area())
        return np.array(self.net.compute_face_descriptor(image, self.shape(image, rect)))


def measure(name, front, side, other, out: Path, rec: Recogniser, texture_size: int, say) -> tuple[dict, dict]:
    """Build one person and measure; returns (figures, pictures for the contact sheet)."""
    from mpeg4.errors import InputError
    from mpeg4.io import read_fdp_json
    from recon.build import run_build
    from recon.photos import read_photo

    fig, pics = {}, {}
    built = []
    t0 = time.perf_counter()
    try:
        run_build(front, side, None, out, texture_size=texture_size, result=built)
    except InputError as e:
        fig["built"] = 0
        fig["error"] = str(e)
        fig["seconds"] = round(time.perf_counter() - t0, 1)
        return fig, pics
    fig["built"] = 1
    fig["seconds"] = round(time.perf_counter() - t0, 1)
    res = built[0]
    for step in ("detection", "shape", "texture", "export"):
        fig[f"seconds_{step}"] = round(res.timings.get(step, float("nan")), 2)
    # How far each photo's pixels may land from their skin (the view lines weigh them by it).
    for view, r in zip(("front", "side"), res.skin.registration_m):
        fig[f"registration_{view}_mm"] = round(1000 * float(r), 2)
    fig["glasses"] = ",".join(res.skin.glasses) or "none"  # the photos whose frames were inpainted
    head = res.head
    found = read_fdp_json(out / "annotations.fdp.json")
    facing = found.metadata.get("landmarks", {}).get("side_facing", {}).get("facing", "left")
    images = {"front": read_photo(front), "side": read_photo(side)}
    views = [v for v in ("front", "side") if v in found.views]
    if "side" not in views:
        fig["side_not_used"] = 1  # the build left the side photo out (its edge cuts the face off)
    for view in views:
        measure_view(fig, pics, head, res.cameras[view].camera, images[view], found.views[view].points, view,
                     facing, rec, res.skin.lighting.get(view))
    # The same head and photo through a camera fitted as for a photo the build never saw
    # (to the points detected there alone): what the front-only figure is compared with.
    try:
        fig["profile_line_refit_ipd_pct"], *_ = unseen_figures(head, front, side)
    except InputError as e:
        fig["refit_error"] = str(e)
    if other is not None:
        try:
            line, iou, img, cam, mask = unseen_figures(head, front, other)
        except InputError as e:
            fig["heldout_error"] = str(e)
        else:
            fig["heldout_profile_line_ipd_pct"], fig["heldout_silhouette_iou"] = line, iou
            pics["held-out"] = (img, render_lit(head, cam), mask)
    return fig, pics


def unseen_figures(head, front, side) -> tuple:
    """(profile line % IPD, silhouette IoU, image, camera, rendered mask) of the head against
    a profile photo through a camera fitted as :func:`unseen_view` fits it."""
    from recon.evaluate import real_photos as rp

    img, pts, cam, facing = unseen_view(head, front, side)
    mask, _ = rp.rendered_mask(head, cam)
    region = rp.head_region(img)
    line = rp.profile_line(region, mask, pts, facing, rp.ipd_px(head, cam))
    return line, rp.silhouette_iou(region, mask, pts.get("2.1", [0, img.shape[0]])[1]), img, cam, mask


def unseen_view(head, front, side) -> tuple:
    """A profile photo the build never saw: (image, points detected there, the camera fitted
    to them and the head, which way it faces). The focal length is the pair's EXIF, as a
    two-photo build would take it."""
    from recon.landmarks import detect
    from recon.photos import photos_focal_px, read_photo
    from recon.texture.cameras import fit_camera

    seen = detect(front, side)
    img = read_photo(side)
    pts = seen.views["side"].points
    focal, _ = photos_focal_px(front, side)
    cam = fit_camera(head.fp_positions(), pts, img.shape[1], img.shape[0], focal_px=focal, where=str(side)).camera
    return img, pts, cam, seen.metadata["landmarks"]["side_facing"]["facing"]


def measure_view(fig: dict, pics: dict, head, cam, image: np.ndarray, pts: dict, view: str, facing: str,
                 rec: Recogniser, lighting=None) -> None:
    """The figures of one photo (point agreement, silhouette; profile line on a side photo,
    skin colour and identity on a front photo) into ``fig``, its pictures into ``pics``.
    ``lighting``: the light the build fitted to this photo and took out of the texture
    (``recon.texture.delight.Lighting``), to relight the albedo as the photo is lit."""
    from recon.evaluate import real_photos as rp

    ipd = rp.ipd_px(head, cam)
    mask, albedo = rp.rendered_mask(head, cam, textured=True)
    region = rp.head_region(image)
    fig[f"point_agreement_{view}_ipd_pct"] = rp.point_agreement(head, cam, pts)
    misses = rp.point_misses(head, cam, pts)
    fig[f"point_agreement_worst_{view}"] = ", ".join(f"{i} {d:.0f} %" for i, d in
                                                    sorted(misses.items(), key=lambda kv: -kv[1])[:4])
    # The same over the points the build kept as detected (not dropped, not brought under
    # the hair or back to the skull): how well the head follows what it was given.
    from mpeg4.catalogue import FEATURE_POINTS

    fit = head.metadata.get("fit", {})
    own = {i: FEATURE_POINTS[i].mirror or i for i in pts} if view == "side" else {i: i for i in pts}
    gone = {i for i, d in fit.get("dropped_points", {}).items() if d.get("view") in (view, "both")}
    kept = [d for i, d in misses.items() if fit.get("point_sources", {}).get(i) in ("front+side", "front", "side", "mirror")
            and i not in gone and own[i] not in gone]
    if kept and "point_sources" in fit:
        fig[f"point_agreement_kept_{view}_ipd_pct"] = float(np.sqrt(np.mean(np.square(kept))))
    chin = pts.get("2.1", [0, image.shape[0]])[1]
    fig[f"silhouette_iou_{view}"] = rp.silhouette_iou(region, mask, chin)
    if view == "side":
        fig["profile_line_ipd_pct"] = rp.profile_line(region, mask, pts, facing, ipd)
        cheek = rp.cheek_box(pts, image.shape[:2])
        shaded = rp.relit(albedo, lighting) if lighting is not None else albedo
        if cheek is not None and shaded is not None:
            import cv2

            inside = cv2.erode((mask & region).astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
            fig["cheek_psnr_db"] = rp.cheek_psnr(image, shaded, cheek & inside)
    else:
        fig["skin_delta_e"] = rp.skin_delta_e(image, albedo, mask, pts, ipd)
        if lighting is not None:
            relit = rp.relit(albedo, lighting)
            if relit is not None:
                fig["skin_delta_e_relit"] = rp.skin_delta_e(image, relit, mask, pts, ipd)
    lit = render_lit(head, cam)
    if rec.ok and view == "front":
        e_photo, e_render = rec.embed(image), rec.embed(lit)
        if e_photo is not None and e_render is not None:
            fig["identity_distance"] = float(np.linalg.norm(e_photo - e_render))
            fig["_embedding"] = e_photo
            # The one key light above is arbitrary: on a turned face it lights one cheek and
            # shades the other whatever the photo's light, which moves the figure by as much
            # as a change of shape does (s001: 0.543 with it, 0.536 mirrored, 0.465 from the
            # camera). The mean over IDENTITY_LIGHTS tells the two apart.
            lights = [rec.embed(render_lit(head, cam, light)) for light in IDENTITY_LIGHTS]
            lights = [float(np.linalg.norm(e_photo - e)) for e in lights if e is not None]
            if lights:
                fig["identity_distance_lights"] = float(np.mean(lights))
    pics[view] = (image, lit, mask)


def measure_front_only(name, front, side, out: Path, rec: Recogniser, texture_size: int) -> tuple[dict, dict]:
    """Build one person from the front photo alone and measure it on that photo and, when
    there is one, on the profile photo the build never saw (through a camera fitted to the
    points detected there)."""
    from mpeg4.errors import InputError
    from mpeg4.io import read_fdp_json
    from recon.build import run_build
    from recon.photos import read_photo

    fig, pics = {}, {}
    built = []
    t0 = time.perf_counter()
    try:
        run_build(front, None, None, out, texture_size=texture_size, result=built)
    except InputError as e:
        fig.update(built=0, error=str(e), seconds=round(time.perf_counter() - t0, 1))
        return fig, pics
    fig.update(built=1, seconds=round(time.perf_counter() - t0, 1))
    res = built[0]
    fig["_head"] = res.head
    fig["glasses"] = ",".join(res.skin.glasses) or "none"
    head = res.head
    fit = head.metadata["fit"]
    fig["focal_from"] = fit["focal_from"]
    cam = res.cameras["front"].camera
    if cam.perspective:
        from recon.photos import FILM_DIAGONAL_MM

        fig["focal_35mm"] = round(cam.focal_px * FILM_DIAGONAL_MM / float(np.hypot(cam.width, cam.height)), 1)
        fig["camera_distance_cm"] = round(float(np.linalg.norm(cam.centre - head.fp_position("9.3"))) * 100, 1)
    found = read_fdp_json(out / "annotations.fdp.json")
    measure_view(fig, pics, head, cam, read_photo(front), found.views["front"].points, "front", "left", rec,
                 res.skin.lighting.get("front"))
    if side is not None:
        try:
            img, pts, unseen, facing = unseen_view(head, front, side)
        except InputError as e:
            fig["side_error"] = str(e)
        else:
            measure_view(fig, pics, head, unseen, img, pts, "side", facing, rec)
    return fig, pics


#: Key lights (camera frame: x right, y up, z towards the camera) of
#: ``identity_distance_lights``: the renderer's default above the left, its mirror image
#: above the right, and a light at the camera.
IDENTITY_LIGHTS = ((-0.3, 0.4, 1.0), (0.3, 0.4, 1.0), (0.0, 0.0, 1.0))


def render_lit(head, cam, light=None) -> np.ndarray:
    """(H, W, 3) uint8: the textured head through ``cam``, lit by the renderer's default key
    light or by ``light`` (a direction towards it in the camera frame)."""
    from mpeg4.preview import head_meshes
    from mpeg4.render import render

    return render(head_meshes(head), cam, samples=4, light=light)


def contact_sheet(rows: dict, path: Path, height: int = 240) -> None:
    """Photo, render and their outlines overlaid, per view, one row per person."""
    import cv2

    lines = []
    for name, pics in rows.items():
        tiles = []
        for view, (img, lit, mask) in pics.items():
            scale = height / img.shape[0]
            size = (int(img.shape[1] * scale), height)
            over = img.copy()
            edge = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
            over[cv2.dilate(edge.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0] = (255, 40, 40)
            for t in (over, lit):
                tile = cv2.resize(t, size)
                cv2.putText(tile, f"{name} {view}", (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 0), 1)
                tiles.append(tile)
        if tiles:
            lines.append(np.hstack(tiles))
    if not lines:
        return
    width = max(line.shape[1] for line in lines)
    sheet = np.vstack([np.pad(line, ((0, 0), (0, width - line.shape[1]), (0, 0))) for line in lines])
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="*", type=Path, default=[DEFAULT])
    ap.add_argument("--with-other-sides", action="store_true", help="also build from side_other as the side photo")
    ap.add_argument("--people", type=int, default=None, help="at most this many people (a smoke run)")
    ap.add_argument("--texture-size", type=int, default=1024)
    ap.add_argument("--sheet", type=Path, default=ROOT / "test-artifacts" / "real_photos_sheet.png")
    ap.add_argument("--front-only", action="store_true",
                    help="build each pair from its front photo alone too (judged on the profile it never saw), "
                         "and each portrait under --portraits")
    ap.add_argument("--portraits", type=Path, nargs="*", default=[PORTRAITS],
                    help="folders of frontal portraits for --front-only (every photo in them and their subfolders)")
    ap.add_argument("--jitter", type=float, default=0.0,
                    help="also rebuild each pair with this much noise on the face mesh's landmarks, pixels")
    ap.add_argument("--seeds", type=int, default=3, help="rebuilds per pair for --jitter")
    args = ap.parse_args(argv)
    from recon.evaluate.machine import describe_machine

    print(f"# machine: {describe_machine()}")
    for f in args.folders:
        if not f.is_dir():
            print(f"real_photos: {f} is not a folder of people", file=sys.stderr)
            return 2
    todo = people(args.folders)[:args.people]
    if args.with_other_sides:
        todo += [(f"{n}+other", fr, o, s) for n, fr, s, o in todo if o is not None]
    if not todo:
        print("real_photos: no person folder with front.* and side.* found", file=sys.stderr)
        return 2
    rec = Recogniser()
    if not rec.ok:
        print(f"# identity not measured: {rec.why}")
    results, sheet = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, front, side, other in todo:
            fig, pics = measure(name, front, side, other, Path(tmp) / name, rec, args.texture_size, print)
            results[name] = fig
            sheet[name] = pics
            for k, v in fig.items():
                if k.startswith("_"):
                    continue
                print(f"{k}[{name}]: {v:.3f}" if isinstance(v, float) else f"{k}[{name}]: {v}", flush=True)
    embeddings = {n: f["_embedding"] for n, f in results.items() if "_embedding" in f and "+" not in n}
    names = sorted(embeddings)
    others = [float(np.linalg.norm(embeddings[a] - embeddings[b])) for i, a in enumerate(names) for b in names[i + 1:]]
    # Each render against the person's nearest other person: does it look more like its
    # own photo than anyone else's photo does?
    closer = []
    for name, f in results.items():
        own = name.split("+")[0]
        near = [float(np.linalg.norm(embeddings[own] - embeddings[b])) for b in names if b != own and own in embeddings]
        if near and "identity_distance" in f:
            print(f"identity_nearest_other_person[{name}]: {min(near):.3f}")
            closer.append(f["identity_distance"] < min(near))
    contact_sheet(sheet, args.sheet)
    print(f"# contact sheet: {args.sheet}")
    if args.front_only:
        front_only(todo, args, rec, results)
    if args.jitter > 0:
        stability(todo, args, rec, results)

    def median(key):
        vals = [f[key] for f in results.values() if key in f and np.isfinite(f[key])]
        return float(np.median(vals)) if vals else float("nan")

    built = sum(f["built"] for f in results.values())
    print(f"built: {built} of {len(results)}")
    print(f"built_without_side: {sum(f.get('side_not_used', 0) for f in results.values())} (the side photo cuts "
          f"the face off: from the front photo alone)")
    pa = [f[k] for f in results.values() for k in ("point_agreement_front_ipd_pct", "point_agreement_side_ipd_pct")
          if k in f]
    print(f"point_agreement_ipd_pct: {np.median(pa) if pa else float('nan'):.3f}")
    pk = [f[k] for f in results.values() for k in ("point_agreement_kept_front_ipd_pct",
                                                    "point_agreement_kept_side_ipd_pct") if k in f]
    print(f"point_agreement_kept_ipd_pct: {np.median(pk) if pk else float('nan'):.3f}")
    for key in FIGURES[2:-4]:
        print(f"{key}: {median(key):.3f}")
    print(f"profile_line_refit_ipd_pct: {median('profile_line_refit_ipd_pct'):.3f}")
    print(f"identity_distance: {median('identity_distance'):.3f}")
    print(f"identity_distance_lights: {median('identity_distance_lights'):.3f}")
    print(f"identity_distance_other_people: {np.median(others) if others else float('nan'):.3f}")
    print(f"identity_closer_than_other_people: {sum(closer)} of {len(closer)}")
    print(f"skin_delta_e: {median('skin_delta_e'):.3f}")
    print(f"skin_delta_e_relit: {median('skin_delta_e_relit'):.3f}")
    print(f"cheek_psnr_db: {median('cheek_psnr_db'):.2f}")
    print(f"skin_delta_e_worst: {worst(results.values(), 'skin_delta_e'):.3f}")
    print(f"build_seconds: {median('seconds'):.1f} (detection {median('seconds_detection'):.1f}, shape "
          f"{median('seconds_shape'):.1f}, texture {median('seconds_texture'):.1f}, export "
          f"{median('seconds_export'):.1f}; medians, texture {args.texture_size} px)")
    return 0


#: The figures ``--jitter`` follows.
STABILITY_FIGURES = ("point_agreement_kept_side_ipd_pct", "profile_line_ipd_pct", "silhouette_iou_side",
                     "profile_line_refit_ipd_pct")


@contextlib.contextmanager
def noisy_face_mesh(px: float, seed: int):
    """The face mesh's landmarks moved by Gaussian noise of ``px`` pixels while inside."""
    import recon.landmarks.front as front_module
    import recon.landmarks.models as models

    exact = models.face_landmarks
    rng = np.random.default_rng(seed)

    def noisy(image):
        return [f + np.c_[rng.normal(0.0, px, (len(f), 2)), np.zeros(len(f))] for f in exact(image)]

    models.face_landmarks = front_module.face_landmarks = noisy
    try:
        yield
    finally:
        models.face_landmarks = front_module.face_landmarks = exact


def stability(todo, args, rec: Recogniser, results: dict) -> None:
    """``--jitter``: each pair rebuilt with noise on the face mesh's landmarks; prints the
    spread of :data:`STABILITY_FIGURES` per person and its median."""
    spreads = {key: [] for key in STABILITY_FIGURES}
    for name, front, side, other in [t for t in todo if "+" not in t[0]]:
        runs = [results[name]]
        for seed in range(1, args.seeds + 1):
            with noisy_face_mesh(args.jitter, seed), tempfile.TemporaryDirectory() as tmp:
                fig, _ = measure(name, front, side, None, Path(tmp) / name, rec, args.texture_size, lambda _: None)
            runs.append(fig)
        print(f"stability_built[{name}]: {sum(f['built'] for f in runs)} of {len(runs)}")
        for key in STABILITY_FIGURES:
            vals = [f[key] for f in runs if isinstance(f.get(key), float) and np.isfinite(f[key])]
            if len(vals) > 1:
                spreads[key].append(float(np.ptp(vals)))
                print(f"stability_{key}_range[{name}]: {np.ptp(vals):.3f} ({min(vals):.3f} to {max(vals):.3f})")
    for key, v in spreads.items():
        print(f"stability_{key}_range: {np.median(v) if v else float('nan'):.3f} (noise {args.jitter:g} px, "
              f"{args.seeds} rebuilds)")


def unseen_spread(head, front, side, args) -> list[float]:
    """``--front-only`` with ``--jitter``: the unseen profile's line judged again with the
    noise on the face mesh of the judge's own detection (the build is left as it is)."""
    from mpeg4.errors import InputError

    vals = []
    for seed in range(1, args.seeds + 1):
        with noisy_face_mesh(args.jitter, seed):
            try:
                vals.append(float(unseen_figures(head, front, side)[0]))
            except InputError as e:  # a refused detection is one draw less
                print(f"# unseen profile not judged (seed {seed}): {e}")
    return vals


def worst(rows, key) -> float:
    """The largest finite value of a figure over people (nan when none has it)."""
    vals = [f[key] for f in rows if key in f and isinstance(f[key], float) and np.isfinite(f[key])]
    return float(max(vals)) if vals else float("nan")


def portraits(folders) -> list[tuple[str, Path]]:
    """(name, photo) of every photo under ``folders``."""
    out = []
    for folder in folders:
        if Path(folder).is_dir():
            out += [(f"{p.parent.name}/{p.stem}", p) for p in sorted(Path(folder).rglob("*"))
                    if p.suffix.lower() in EXTENSIONS]
    return out


def front_only(todo, args, rec: Recogniser, two_photo: dict) -> None:
    """``--front-only``: each pair's front photo alone (beside its two-photo figures), then
    each portrait; prints ``front_only_*`` lines and a contact sheet."""
    results, sheet = {}, {}
    runs = [(n, fr, s) for n, fr, s, _ in todo if "+" not in n] + [(n, p, None) for n, p in portraits(args.portraits)]
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, front, side) in enumerate(runs):
            fig, pics = measure_front_only(name, front, side, Path(tmp) / f"p{k}", rec, args.texture_size)
            results[name], sheet[name] = fig, pics
            for key, v in fig.items():
                if not key.startswith("_"):
                    print(f"front_only_{key}[{name}]: {v:.3f}" if isinstance(v, float) else
                          f"front_only_{key}[{name}]: {v}", flush=True)
            if args.jitter > 0 and side is not None and "profile_line_ipd_pct" in fig:
                vals = [fig["profile_line_ipd_pct"]] + unseen_spread(fig["_head"], front, side, args)
                fig["profile_line_jitter_median"] = float(np.median(vals))
                print(f"front_only_profile_line_ipd_pct_range[{name}]: {np.ptp(vals):.3f} ({min(vals):.3f} to "
                      f"{max(vals):.3f}, median {np.median(vals):.3f}; the judge's detection with "
                      f"{args.jitter:g} px of noise)", flush=True)
            fig.pop("_head", None)
    path = args.sheet.with_name(args.sheet.stem + "_front_only.png")
    contact_sheet(sheet, path)
    print(f"# front-only contact sheet: {path}")

    def median(rows, key):
        vals = [f[key] for f in rows if key in f and isinstance(f[key], float) and np.isfinite(f[key])]
        return float(np.median(vals)) if vals else float("nan")

    pairs = [results[n] for n, _, s in runs if s is not None]
    alone = [results[n] for n, _, s in runs if s is None]
    print(f"front_only_built: {sum(f['built'] for f in results.values())} of {len(results)}")
    same = [f for n, f in two_photo.items() if "+" not in n]  # the same pairs, their own profiles
    for key in ("profile_line_ipd_pct", "silhouette_iou_side"):
        print(f"front_only_{key}: {median(pairs, key):.3f} (two photos: {median(same, key):.3f}"
              + (f"; through a camera fitted as here: {median(same, 'profile_line_refit_ipd_pct'):.3f})"
                 if key == "profile_line_ipd_pct" else ")"))
    if args.jitter > 0:
        print(f"front_only_profile_line_ipd_pct_jitter: {median(pairs, 'profile_line_jitter_median'):.3f} (the "
              f"median over people of each one's median over {args.seeds + 1} judgements)")
    for key in ("identity_distance", "skin_delta_e", "skin_delta_e_relit", "silhouette_iou_front",
                "point_agreement_front_ipd_pct"):
        print(f"front_only_portraits_{key}: {median(alone, key):.3f}")
    # The portraits' skin tones, built from the front photo alone (issue: de-lighting on every tone).
    print(f"skin_delta_e_front_set: {median(alone, 'skin_delta_e'):.3f} (worst {worst(alone, 'skin_delta_e'):.3f}, "
          f"relit {median(alone, 'skin_delta_e_relit'):.3f}, {sum('skin_delta_e' in f for f in alone)} portraits)")
    print(f"front_only_seconds: {median(list(results.values()), 'seconds'):.1f}")


if __name__ == "__main__":
    raise SystemExit(main())
