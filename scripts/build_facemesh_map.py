"""Fit the face-mesh → MPEG-4 tables ``recon/data/facemesh_mpeg4.csv`` and ``facemesh_side.csv``.

Front table: every feature point a front photo shows that the face mesh covers (groups
2–5, 8, 9: not the ears, hairline and skull, which come from the silhouette) is written as
an affine combination of three face-mesh landmarks' pixels. The three are chosen among the
eight landmarks nearest to the point, and their weights fitted by least squares (weights
summing to one), on front photos of synthetic ICT FaceKit identities (``recon.evaluate.synthetic``,
seeds 1000–1019; the benchmark uses 0–19); the triple with the smallest
leave-one-identity-out error wins. The pupils (3.5, 3.6) are the iris centres themselves.

Side table: every feature point a side photo shows (either side, but the top and back of
the skull, read off the silhouette) is an affine combination of three landmarks' depth and
height, which :func:`recon.landmarks.profile.fit_profile` carries into the side photo.
The target of the fit is the true side pixel taken back through that photo's own profile
fit, so the table absorbs what the fit and the face mesh's depth get wrong on average. The
candidates are the landmarks nearest in depth and height on the point's own side of the
face (on the midline for a midline point). The right side's rows are fitted on the front
photos mirrored, whose face mesh shows the mirrored person, and whose left side the
(unmirrored) side photo then shows as the right.

Usage: ``python3 scripts/build_facemesh_map.py [--seeds 20] [--cache DIR]`` (a few
minutes: each identity is rendered, then meshed). Needs mediapipe and ``../shared/data``.

A run today does not give the committed tables row for row: the synthetic photos have
changed since (the generic head's points, the renderer), and many points have several
triples within a hair of each other, so a fresh run gives every row other weights and
many rows other landmarks.
It gives tables of the same accuracy: on ``benchmarks/landmark_accuracy.py
--identities 10`` (seeds 0-9, not fitted on), front model points 1.56 % of the IPD
against 1.57 % with the committed tables, side points 3.33 against 3.28 %, the harder
set 1.68 against 1.66 % and 4.02 against 4.02 % (a 2-CPU AMD EPYC, December 2026).
"""

from __future__ import annotations

import argparse
import itertools
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS  # noqa: E402
from recon.landmarks.mapping import MAP_FILE, SIDE_MAP_FILE, FpMapping, write_mapping  # noqa: E402
from recon.landmarks.models import face_landmarks  # noqa: E402
from recon.landmarks.profile import MIDLINE  # noqa: E402

FIRST_SEED = 1000
#: Larger weights reach far outside the landmarks' triangle, where a real face's mesh may
#: not follow the synthetic ones.
MAX_WEIGHT = 2.5
#: Where each row's landmarks are, in words (the feature point's own description is in the
#: catalogue).
ANATOMY = {
    "2.1": "bottom of the chin outline", "2.2": "inner upper lip, midline", "2.3": "inner lower lip, midline",
    "2.4": "inner lip corner, left", "2.5": "inner lip corner, right", "2.6": "inner upper lip, left half",
    "2.7": "inner upper lip, right half", "2.8": "inner lower lip, left half", "2.9": "inner lower lip, right half",
    "2.10": "chin boss (most prominent point of the chin), midline", "2.11": "chin outline, left", "2.12": "chin outline, right",
    "2.13": "angle of the jaw (gonion), left", "2.14": "angle of the jaw (gonion), right",
    "3.1": "upper lid margin, left eye", "3.2": "upper lid margin, right eye", "3.3": "lower lid margin, left eye",
    "3.4": "lower lid margin, right eye", "3.5": "left iris centre", "3.6": "right iris centre",
    "3.7": "outer eye corner, left", "3.8": "inner eye corner, right", "3.9": "below the lower lid, left eye",
    "3.10": "below the lower lid, right eye", "3.11": "inner eye corner, left", "3.12": "outer eye corner, right",
    "3.13": "upper lid fold, left eye", "3.14": "upper lid fold, right eye",
    "4.1": "inner end of the eyebrow, left", "4.2": "inner end of the eyebrow, right",
    "4.3": "top of the eyebrow, left", "4.4": "top of the eyebrow, right",
    "4.5": "outer end of the eyebrow, left", "4.6": "outer end of the eyebrow, right",
    "5.1": "cheek beside the mouth, left", "5.2": "cheek beside the mouth, right",
    "5.3": "cheekbone, left", "5.4": "cheekbone, right",
    "8.1": "outer upper lip, midline", "8.2": "outer lower lip, midline", "8.3": "mouth corner, left",
    "8.4": "mouth corner, right", "8.5": "outer upper lip, left half", "8.6": "outer upper lip, right half",
    "8.7": "outer lower lip, left half", "8.8": "outer lower lip, right half", "8.9": "Cupid's bow peak, right",
    "8.10": "Cupid's bow peak, left",
    "9.1": "outer edge of the nose wing, left", "9.2": "outer edge of the nose wing, right",
    "9.3": "tip of the nose", "9.4": "base of the nose wing, right", "9.5": "base of the nose wing, left",
    "9.6": "side of the nose bridge by the eye, right", "9.7": "side of the nose bridge by the eye, left",
    "9.12": "nose bridge, midline", "9.13": "side of the nose bridge, left", "9.14": "side of the nose bridge, right",
    "9.15": "under the nose, midline",
    "10.1": "top of the ear, left", "10.2": "top of the ear, right", "10.3": "back of the ear, left",
    "10.4": "back of the ear, right", "10.5": "ear lobe, left", "10.6": "ear lobe, right",
    "10.7": "where the lobe joins the face, left", "10.8": "where the lobe joins the face, right",
    "10.9": "where the ear joins the head, left", "10.10": "where the ear joins the head, right",
    "11.1": "hairline, midline", "11.2": "end of the hairline, right", "11.3": "end of the hairline, left",
}
#: The pupils are the iris centres (the mesh's own landmarks 473 and 468), not a fit.
IRIS = {"3.5": (473, 474, 476), "3.6": (468, 469, 471)}


def mapped_points() -> list[str]:
    """FP ids the front table covers."""
    return [i for i in FP_IDS if FEATURE_POINTS[i].front != "N" and FEATURE_POINTS[i].group in (2, 3, 4, 5, 8, 9)]


def side_points() -> list[str]:
    """FP ids the side table covers: what a side photo of either side shows, but the top
    and the back of the skull (11.4–11.6), which the silhouette gives."""
    return [i for i in FP_IDS if FEATURE_POINTS[i].side_view != "N" and i not in ("11.4", "11.5", "11.6")]


def _pair(seed: int, cache: Path | None):
    """Front and side photo with their true pixels, rendered or from the cache."""
    from recon.evaluate.synthetic import synthetic_pair

    f = None if cache is None else cache / f"pair_{seed}.npz"
    if f is not None and f.exists():
        d = np.load(f, allow_pickle=False)
        return (d["front"], d["side"], dict(zip(d["fids"].tolist(), d["fpts"])),
                dict(zip(d["sids"].tolist(), d["spts"])))
    p = synthetic_pair(seed)
    tf, ts = p.fdp.views["front"].points, p.fdp.views["side"].points
    if f is not None:
        f.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(f, front=p.front, side=p.side, fids=np.array(list(tf)), fpts=np.array(list(tf.values())),
                            sids=np.array(list(ts)), spts=np.array(list(ts.values())))
    return p.front, p.side, tf, ts


def calibration_data(seeds, cache: Path | None = None) -> list[dict]:
    """Per seed: the face mesh of the front photo and of its mirror image, each with its
    profile fit on the side photo, and the true pixels of both photos."""
    from recon.landmarks.front import detect_front
    from recon.landmarks.side import register_profile

    out = []
    for s in seeds:
        front, side, tf, ts = _pair(s, cache)
        if not face_landmarks(front):
            print(f"seed {s}: no face found, skipped", file=sys.stderr)
            continue
        item = {"seed": s, "truth_front": tf, "truth_side": ts}
        for key, photo in (("direct", front), ("mirrored", np.ascontiguousarray(front[:, ::-1]))):
            f = detect_front(photo)
            fit, _ = register_profile(side, f, photo.shape[0])
            item[key] = (f.extras["landmarks"], fit, f.ipd_px)
        out.append(item)
        print(f"seed {s}: meshed, profile fit cost {item['direct'][1].cost:.2f} px", file=sys.stderr)
    return out


def _fit(base: np.ndarray, du: np.ndarray, dv: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(u, v) minimising |base + u du + v dv - target|² over all identities (arrays (N, 2))."""
    a = np.stack([du.reshape(-1), dv.reshape(-1)], axis=1)
    b = (target - base).reshape(-1)
    # A faint ridge keeps nearly collinear triples from wild weights.
    lam = 1e-3 * np.trace(a.T @ a)
    return np.linalg.solve(a.T @ a + lam * np.eye(2), a.T @ b)


def fit_combination(coords: np.ndarray, truth: np.ndarray, ipd: np.ndarray, near: np.ndarray):
    """The best triple among ``near`` landmarks and its weights.

    Parameters
    ----------
    coords : (N, 478, 2)
        Landmark coordinates per identity.
    truth : (N, 2)
        The point, in the same coordinates.
    ipd : (N,)
        Distance between the pupils in those coordinates.
    near : (M,) int
        Candidate landmarks.

    Returns
    -------
    tri : tuple of 3 int, weights : tuple of 3 float, err : (N,) float (% IPD)
        None when no triple reaches the point within weights of ``MAX_WEIGHT``.
    """
    best = None
    n = len(coords)
    for tri in itertools.combinations(near, 3):
        a, b, c = (coords[:, k] for k in tri)
        loo = []
        for k in range(n):
            keep = np.arange(n) != k
            u, v = _fit(a[keep], (b - a)[keep], (c - a)[keep], truth[keep])
            if max(abs(u), abs(v), abs(1 - u - v)) > MAX_WEIGHT:
                break
            p = a[k] + u * (b - a)[k] + v * (c - a)[k]
            loo.append(np.linalg.norm(p - truth[k]) / ipd[k] * 100)
        if len(loo) < n:
            continue
        score = float(np.mean(loo))
        if best is None or score < best[0]:
            best = (score, tri)
    if best is None:
        return None
    tri = best[1]
    a, b, c = (coords[:, k] for k in tri)
    u, v = _fit(a, b - a, c - a, truth)
    p = a + u * (b - a) + v * (c - a)
    err = np.linalg.norm(p - truth, axis=1) / ipd * 100
    return tuple(int(k) for k in tri), (1 - u - v, u, v), err


def fit_row(fp: str, data, n_near: int = 8) -> FpMapping:
    """The front table's row for one feature point."""
    lms = np.array([d["direct"][0][:, :2] for d in data])  # (N, 478, 2)
    truth = np.array([d["truth_front"][fp] for d in data])  # (N, 2)
    ipd = np.array([np.linalg.norm(d["truth_front"]["3.5"] - d["truth_front"]["3.6"]) for d in data])
    if fp in IRIS:
        tri = IRIS[fp]
        err = np.linalg.norm(lms[:, tri[0]] - truth, axis=1) / ipd * 100
        return FpMapping(fp, tri, (1.0, 0.0, 0.0), float(np.median(err)), ANATOMY[fp])
    mean_d = np.mean(np.linalg.norm(lms[:, :468] - truth[:, None], axis=2) / ipd[:, None], axis=0)
    near = np.argsort(mean_d)[:n_near]
    tri, w, err = fit_combination(lms, truth, ipd, near)  # the nearest always reach it
    return FpMapping(fp, tri, tuple(float(x) for x in w), float(np.median(err)), ANATOMY[fp])


def fit_side_row(fp: str, data, n_near: int = 8) -> FpMapping:
    """The side table's row for one feature point (its depth and height from landmarks)."""
    f = FEATURE_POINTS[fp]
    # The right side's points are the mirrored person's, whose left the side photo shows.
    key, shown = ("mirrored", f.mirror) if f.side == "R" else ("direct", fp)
    coords, truth, ipd, lateral = [], [], [], []
    for d in data:
        lm, fit, ipd_px = d[key]
        coords.append(lm[:, [2, 1]])
        truth.append(fit.inverse(d["truth_side"][shown][None])[0])
        ipd.append(ipd_px)
        mid = np.mean(lm[list(MIDLINE), 0])
        lateral.append((lm[:, 0] - mid) / ipd_px)  # the face's left is the photo's right
    coords, truth, ipd, lateral = np.array(coords), np.array(truth), np.array(ipd), np.mean(lateral, axis=0)
    allowed = {"C": np.abs(lateral) < 0.05, "L": lateral > 0.05, "R": lateral < -0.05}[f.side]
    allowed[468:] = False  # not the irises
    mean_d = np.mean(np.linalg.norm(coords - truth[:, None], axis=2) / ipd[:, None], axis=0)
    order = np.flatnonzero(allowed)[np.argsort(mean_d[allowed])]
    # A point far from every landmark (the ear) needs landmarks spread wider to be reached
    # within the weights' bound: every second, then every fourth of the nearer ones.
    for stride in (1, 2, 4):
        found = fit_combination(coords, truth, ipd, order[:n_near * stride:stride])
        if found is not None:
            break
    else:
        raise RuntimeError(f"{fp}: no landmark triple reaches it within weights of +-{MAX_WEIGHT}")
    tri, w, err = found
    return FpMapping(fp, tri, tuple(float(x) for x in w), float(np.median(err)), ANATOMY[fp])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="How many calibration identities (from seed 1000).")
    ap.add_argument("--cache", type=Path, default=None, help="Keep the rendered photos here between runs.")
    ap.add_argument("--only", choices=("front", "side"), default=None, help="Fit one of the two tables.")
    args = ap.parse_args(argv)
    seeds = list(range(FIRST_SEED, FIRST_SEED + args.seeds))
    data = calibration_data(seeds, args.cache)
    common = f"""to {len(data)} synthetic ICT FaceKit identities (seeds {seeds[0]}-{seeds[-1]}), three of the eight
nearest landmarks chosen by leave-one-identity-out error (weights within +-{MAX_WEIGHT}); fit_error_pct
is the median error on those photos in % of the distance between the pupils. Regenerate
with the script rather than editing by hand."""
    tables = []
    if args.only in (None, "front"):
        rows = [fit_row(fp, data) for fp in mapped_points()]
        header = f"""MediaPipe face mesh landmarks -> MPEG-4 feature points (recon.landmarks.mapping).
Each row: fp = w0 * L[a] + w1 * L[b] + w2 * L[c] (weights sum to 1) over face mesh landmarks
a b c (0-467 surface, 468-477 irises, centre first), in the front photo's pixels. Fitted by
scripts/build_facemesh_map.py on front photos {common}"""
        tables.append((ROOT / "recon" / MAP_FILE, rows, header))
    if args.only in (None, "side"):
        rows = [fit_side_row(fp, data) for fp in side_points()]
        header = f"""MediaPipe face mesh landmarks -> MPEG-4 feature points of a side photo (recon.landmarks.side).
Each row: (depth, height) = w0 * L[a] + w1 * L[b] + w2 * L[c] (weights sum to 1) over the face
mesh landmarks' depth and row in the front photo, which the profile fit
(recon.landmarks.profile) carries into the side photo. Fitted by scripts/build_facemesh_map.py
on side photos (the right side's rows on mirrored front photos) {common}"""
        tables.append((ROOT / "recon" / SIDE_MAP_FILE, rows, header))
    for path, rows, header in tables:
        write_mapping(path, rows, header)
        errs = np.array([r.fit_error_pct for r in rows])
        for r in rows:
            print(f"{r.fp}: {r.fit_error_pct:.2f} % IPD  {r.landmarks} {tuple(round(x, 3) for x in r.weights)}")
        print(f"median of the rows' errors: {np.median(errs):.2f} % IPD over {len(rows)} points -> {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
