"""A head from a front photo alone against ground truth: identities the model cannot contain.

The shipped identity model holds the ICT FaceKit's first 50 identity modes
(:mod:`recon.shape.identity`); the identities here are drawn with all 100
(``neutral + sum z_i identity_i``, z ~ N(0, 1), fixed seeds, as in
``benchmarks/shape_accuracy.py``), so half of what makes each face is outside the model.
Each identity's feature points are projected into a front camera 1024 px high (and a side
camera for the two-photo figure), orthographic or a 50 mm-equivalent pinhole at 1 m, with
pixel noise sigma. Three heads are measured against the identity, per vertex, after
removing the free translation (the mean offset of the front photo's feature points):

- ``generic``: the undeformed generic head, placed by the similarity that best takes its
  feature points to the identity's true 3D points (the best the template can do);
- ``front_only``: :func:`recon.shape.fit.fit_head_front` on the front photo's points (the
  focal length given for the pinhole camera, and also estimated, ``front_only_estimated``);
- ``two_photos``: the calibration of the front and side points and the DFFD from the
  identity model's head fitted to them (:func:`recon.shape.fit.fit_head`'s route), and
  ``two_photos_from_generic``, the DFFD from the generic head itself (the route before the
  model).

Medians over the ICT full face area and its narrow face area (no ears, neck or scalp); then
the same three heads for the MakeHuman hm08 head (``../shared/data/foreign_heads``, a face
from another family: marked by ``fmc mark``'s route, photographed the same way, measured as
the distance of the narrow face from its surface); then the time of a whole ``recon build FRONT`` on the embedded example's 1024-px front photo
(detection, fit, texture, bundle).

Run: ``python3 benchmarks/front_only.py [--identities 20] [--noise 0 2]``
Prints ``name: value unit`` lines.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from shape_accuracy import F_50MM, NPZ, identity_vertices, part_vertices, project  # noqa: E402

FACE = slice(0, 9409)  # ICT "Full face area"
NARROW = slice(0, 6706)  # ICT "Narrow face area"


def _error(vertices, fitted, truth_skin, truth_fp, ids) -> np.ndarray:
    """Per-vertex distance (mm) after removing the mean offset of the feature points ``ids``."""
    off = np.mean([fitted.fp_position(i) - truth_fp[i] for i in ids], axis=0)
    return np.linalg.norm(vertices - off - truth_skin, axis=1) * 1000


def shape_errors(data, generic, k: int, sigma: float, perspective: bool) -> dict[str, np.ndarray]:
    """Per-vertex skin errors (mm) of each head for identity ``k``."""
    from recon.shape.calibrate import calibrate
    from recon.shape.deform import deform_head, fit_similarity
    from recon.shape.fit import identity_start
    from recon.shape.from_front import fit_front

    truth = generic.with_vertices(part_vertices(generic, identity_vertices(data, np.random.default_rng(1000 + k))))
    tfp, tskin = truth.fp_positions(), truth.skin.vertices
    ipd = np.linalg.norm(tfp["3.5"] - tfp["3.6"]) * 1000
    rng = np.random.default_rng(k * 100 + int(sigma * 10) + perspective)
    views = {v: {i: p + rng.normal(0, sigma, 2) for i, p in project(tfp, v, perspective).items()}
             for v in ("front", "side")}
    focal = F_50MM if perspective else None
    out = {}
    seen = list(views["front"])
    rest = np.array([generic.fp_position(i) for i in seen])
    sim = fit_similarity(rest, np.array([tfp[i] for i in seen]))
    placed = generic.with_vertices({n: sim(p.vertices) for n, p in generic.parts.items()})
    out["generic"] = _error(placed.skin.vertices, placed, tskin, tfp, seen)
    tries = {"front_only": dict(focal_px=focal, estimate_focal=False)}
    if perspective:
        tries["front_only_estimated"] = dict(focal_px=None, estimate_focal=True)
    for name, kw in tries.items():
        ff = fit_front(views["front"], 1024, 1024, generic, ipd_mm=ipd, **kw)
        head = deform_head(ff.head, ff.points)
        out[name] = _error(head.skin.vertices, head, tskin, tfp, seen)
    cal = calibrate(views["front"], views["side"], generic, ipd_mm=ipd, focal_px=focal, front_size=(1024, 1024),
                    side_size=(1024, 1024), height_tol_mm=30)
    goal = {i: p for i, p in cal.points.items() if cal.source[i] != "generic"}
    start, _ = identity_start(generic, goal)
    for name, base in (("two_photos", start), ("two_photos_from_generic", generic)):
        head = deform_head(base, goal)
        out[name] = _error(head.skin.vertices, head, tskin, tfp, seen)
    return out


def makehuman_head():
    """The MakeHuman hm08 head (:mod:`recon.evaluate.makehuman`), marked by ``fmc mark``'s
    route (:func:`recon.mark.mark`)."""
    from recon.evaluate.makehuman import makehuman_head as raw_head
    from recon.mark import mark

    return mark(raw_head(), where="MakeHuman hm08 head").head


def makehuman_errors(generic, target) -> dict[str, np.ndarray]:
    """Per-vertex distance (mm) of each head's narrow face from the MakeHuman surface,
    after removing the mean offset of the front photo's feature points (exact pixels,
    orthographic; no correspondence: the nearest surface point)."""
    import trimesh

    from recon.shape.calibrate import calibrate
    from recon.shape.deform import deform_head, fit_similarity
    from recon.shape.fit import identity_start
    from recon.shape.from_front import fit_front

    tfp = target.fp_positions()
    tfp = {i: p for i, p in tfp.items() if i in generic.feature_points}
    surface = trimesh.Trimesh(target.skin.vertices, target.skin.triangles, process=False)
    views = {v: project(tfp, v, False) for v in ("front", "side")}
    seen = [i for i in views["front"] if i in generic.feature_points]
    ipd = np.linalg.norm(tfp["3.5"] - tfp["3.6"]) * 1000

    def distance(head):
        off = np.mean([head.fp_position(i) - tfp[i] for i in seen], axis=0)
        _, d, _ = trimesh.proximity.closest_point(surface, head.skin.vertices[NARROW] - off)
        return d * 1000

    out = {}
    sim = fit_similarity(np.array([generic.fp_position(i) for i in seen]), np.array([tfp[i] for i in seen]))
    out["generic"] = distance(generic.with_vertices({n: sim(p.vertices) for n, p in generic.parts.items()}))
    ff = fit_front(views["front"], 1024, 1024, generic, ipd_mm=ipd, estimate_focal=False)
    out["front_only"] = distance(deform_head(ff.head, ff.points))
    cal = calibrate(views["front"], views["side"], generic, ipd_mm=ipd, front_size=(1024, 1024),
                    side_size=(1024, 1024), height_tol_mm=30)
    goal = {i: p for i, p in cal.points.items() if cal.source[i] != "generic"}
    out["two_photos"] = distance(deform_head(identity_start(generic, goal)[0], goal))
    return out


def build_seconds() -> float:
    """Wall time of ``recon build FRONT -o OUT`` on the embedded example's front photo."""
    from recon.build import run_build

    front = ROOT / "data" / "example" / "front.jpg"
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run_build(front, None, None, Path(tmp) / "out")
        return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--identities", type=int, default=20)
    ap.add_argument("--noise", type=float, nargs="+", default=[0.0, 2.0])
    ap.add_argument("--no-speed", action="store_true", help="skip the timed build")
    ap.add_argument("--no-makehuman", action="store_true", help="skip the MakeHuman head")
    args = ap.parse_args(argv)
    from recon.evaluate.machine import describe_machine

    print(f"# machine: {describe_machine()}")
    if not NPZ.exists():
        print(f"skipped: {NPZ} is absent (the ICT FaceKit test data)")
        return 0
    from mpeg4.generic_head import load_generic_head

    data = np.load(NPZ)
    generic = load_generic_head()
    results: dict[tuple, list] = {}
    t0 = time.perf_counter()
    for k in range(args.identities):
        for perspective in (False, True):
            for sigma in args.noise:
                for name, err in shape_errors(data, generic, k, sigma, perspective).items():
                    results.setdefault(("persp" if perspective else "ortho", sigma, name), []).append(err)
        print(f"identity {k + 1}/{args.identities} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
    for (cam, sigma, name), errs in sorted(results.items()):
        e = np.stack(errs)
        print(f"{name}_{cam}_sigma{sigma:g}px_face_median_mm: {np.median(e[:, FACE]):.2f} "
              f"(narrow face {np.median(e[:, NARROW]):.2f}, face p95 {np.percentile(e[:, FACE], 95):.2f})")
    for name in ("generic", "front_only", "two_photos", "two_photos_from_generic"):
        e = np.stack(results[("ortho", args.noise[0], name)])
        print(f"{name}_face_median_mm: {np.median(e[:, FACE]):.2f}")
        print(f"{name}_narrow_face_median_mm: {np.median(e[:, NARROW]):.2f}")
    from recon.evaluate.makehuman import MAKEHUMAN_DIR

    if (MAKEHUMAN_DIR / "base.obj").exists() and not args.no_makehuman:
        try:
            target = makehuman_head()
        except Exception as e:  # no detector here, or the marking failed: say so, go on
            print(f"# makehuman: not measured ({e})")
        else:
            for name, d in makehuman_errors(generic, target).items():
                print(f"makehuman_{name}_narrow_face_median_mm: {np.median(d):.2f} (p95 {np.percentile(d, 95):.2f})")
    if not args.no_speed:
        print(f"front_only_build_seconds: {build_seconds():.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
