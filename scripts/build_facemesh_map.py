"""Fit the face-mesh → MPEG-4 table ``recon/data/facemesh_mpeg4.csv``.

For every feature point a front photo shows that the face mesh covers (groups 2–5, 8, 9:
not the ears, hairline and skull, which come from the silhouette), the point is written as
an affine combination of three face-mesh landmarks. The three are chosen among the eight
landmarks nearest to the point, and their weights fitted by least squares (weights summing
to one), on front photos of synthetic ICT FaceKit identities (``recon.synthetic``, seeds
1000–1019; the benchmark uses 0–19); the triple with the smallest leave-one-identity-out
error wins. The pupils (3.5, 3.6) are the iris centres themselves.

Usage: ``python3 scripts/build_facemesh_map.py [--seeds 20] [--cache DIR]`` (about two
minutes: each identity is rendered, then meshed). Needs mediapipe and ``../shared/data``.
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
from recon.landmarks.mapping import MAP_FILE, FpMapping, write_mapping  # noqa: E402
from recon.landmarks.models import face_landmarks  # noqa: E402

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
    "2.10": "below the lower lip, midline", "2.11": "chin outline, left", "2.12": "chin outline, right",
    "2.13": "lower jaw, left", "2.14": "lower jaw, right",
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
}
#: The pupils are the iris centres (the mesh's own landmarks 473 and 468), not a fit.
IRIS = {"3.5": (473, 474, 476), "3.6": (468, 469, 471)}


def mapped_points() -> list[str]:
    """FP ids the table covers."""
    return [i for i in FP_IDS if FEATURE_POINTS[i].front != "N" and FEATURE_POINTS[i].group in (2, 3, 4, 5, 8, 9)]


def calibration_data(seeds, cache: Path | None = None):
    """Per seed: (478, 3) landmarks, FP id → true front pixel, IPD in pixels."""
    from recon.synthetic import synthetic_pair

    out = []
    for s in seeds:
        f = None if cache is None else cache / f"facemesh_{s}.npz"
        if f is not None and f.exists():
            d = np.load(f, allow_pickle=False)
            truth = dict(zip(d["ids"].tolist(), d["truth"]))
            out.append((d["landmarks"], truth))
            continue
        pair = synthetic_pair(s)
        faces = face_landmarks(pair.front)
        if not faces:
            print(f"seed {s}: no face found, skipped", file=sys.stderr)
            continue
        truth = pair.fdp.views["front"].points
        if f is not None:
            f.parent.mkdir(parents=True, exist_ok=True)
            np.savez(f, landmarks=faces[0], ids=np.array(list(truth)), truth=np.array(list(truth.values())))
        out.append((faces[0], truth))
        print(f"seed {s}: meshed", file=sys.stderr)
    return out


def _fit(base: np.ndarray, du: np.ndarray, dv: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(u, v) minimising |base + u du + v dv - target|² over all identities (arrays (N, 2))."""
    a = np.stack([du.reshape(-1), dv.reshape(-1)], axis=1)
    b = (target - base).reshape(-1)
    # A faint ridge keeps nearly collinear triples from wild weights.
    lam = 1e-3 * np.trace(a.T @ a)
    return np.linalg.solve(a.T @ a + lam * np.eye(2), a.T @ b)


def fit_row(fp: str, data, n_near: int = 8) -> FpMapping:
    """The best triple and weights for one feature point."""
    lms = np.array([d[0][:, :2] for d in data])  # (N, 478, 2)
    truth = np.array([d[1][fp] for d in data])  # (N, 2)
    ipd = np.array([np.linalg.norm(d[1]["3.5"] - d[1]["3.6"]) for d in data])
    if fp in IRIS:
        tri = IRIS[fp]
        err = np.linalg.norm(lms[:, tri[0]] - truth, axis=1) / ipd * 100
        return FpMapping(fp, tri, (1.0, 0.0, 0.0), float(np.median(err)), ANATOMY[fp])
    mean_d = np.mean(np.linalg.norm(lms[:, :468] - truth[:, None], axis=2) / ipd[:, None], axis=0)
    near = np.argsort(mean_d)[:n_near]
    best = None
    for tri in itertools.combinations(near, 3):
        a, b, c = (lms[:, k] for k in tri)
        loo = []
        for k in range(len(data)):
            keep = np.arange(len(data)) != k
            u, v = _fit(a[keep], (b - a)[keep], (c - a)[keep], truth[keep])
            if max(abs(u), abs(v), abs(1 - u - v)) > MAX_WEIGHT:
                break
            p = a[k] + u * (b - a)[k] + v * (c - a)[k]
            loo.append(np.linalg.norm(p - truth[k]) / ipd[k] * 100)
        if len(loo) < len(data):
            continue
        score = float(np.mean(loo))
        if best is None or score < best[0]:
            best = (score, tri)
    tri = best[1]
    a, b, c = (lms[:, k] for k in tri)
    u, v = _fit(a, b - a, c - a, truth)
    p = a + u * (b - a) + v * (c - a)
    err = np.linalg.norm(p - truth, axis=1) / ipd * 100
    w = (1 - u - v, u, v)
    return FpMapping(fp, tuple(int(k) for k in tri), tuple(float(x) for x in w), float(np.median(err)), ANATOMY[fp])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20, help="How many calibration identities (from seed 1000).")
    ap.add_argument("--cache", type=Path, default=None, help="Keep the meshed photos here between runs.")
    ap.add_argument("-o", "--out", type=Path, default=ROOT / "recon" / MAP_FILE)
    args = ap.parse_args(argv)
    seeds = list(range(FIRST_SEED, FIRST_SEED + args.seeds))
    data = calibration_data(seeds, args.cache)
    rows = [fit_row(fp, data) for fp in mapped_points()]
    header = f"""MediaPipe face mesh landmarks -> MPEG-4 feature points (recon.landmarks.mapping).
Each row: fp = w0 * L[a] + w1 * L[b] + w2 * L[c] (weights sum to 1) over face mesh landmarks
a b c (0-467 surface, 468-477 irises, centre first). Fitted by scripts/build_facemesh_map.py
to front photos of {len(data)} synthetic ICT FaceKit identities (seeds {seeds[0]}-{seeds[-1]}),
three of the eight nearest landmarks chosen by leave-one-identity-out error (weights within
+-2.5); fit_error_pct is
the median error on those photos in % of the distance between the pupils. Regenerate with the
script rather than editing by hand."""
    write_mapping(args.out, rows, header)
    errs = np.array([r.fit_error_pct for r in rows])
    for r in rows:
        print(f"{r.fp}: {r.fit_error_pct:.2f} % IPD  {r.landmarks} {tuple(round(x, 3) for x in r.weights)}")
    print(f"median of the rows' errors: {np.median(errs):.2f} % IPD over {len(rows)} points -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
