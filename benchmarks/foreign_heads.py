"""Foreign heads marked, cloned and played: what a user's own mesh gets.

For each head of ``../shared/data/foreign_heads`` (the MakeHuman hm08 head with two of its
targets, the MediaPipe face mask) and each mesh file given, as ``fmc clone`` takes it:

- ``mark_s``: marking it (:func:`chain.clone.target_head`: :func:`recon.mark.mark` when it
  has no points), ``points``: feature points placed, ``parts``: the parts it was given,
  ``fapu_ok``: whether its FAPU can be measured (1) or the points are unreliable (0);
- ``clone_s``: cloning the generic head's tables onto it (:func:`fmc.clone.clone`);
- over the cloned tables, each low-level FAP alone at ±512 and every Xface stream
  (``../shared/data/fap_streams/xface``), played as every player reads it:
  ``inverted_triangles_max`` (target 0), ``edge_stretch_max`` (≤ 2.5),
  ``eyeball_centre_shift_max_mm`` (≤ 0.2), and ``fapu_conformance_pct``: the share of
  low-level FAPs whose feature point moves value × FAPU within 5 % at ±512 (+512 for a
  unidirectional FAP; played without the limits, which stop touching lips where they
  meet; the eyeballs' FAPs left out on a head without eyeballs);
- ``lip_gap_pbm_mm``: the inner lips' gap (2.2 to 2.3) at the p/b/m viseme (≤ 1);

then MakeHuman as a source: its jaw drop (AU 26), smile (AU 12), happy and B/M/P viseme
targets cloned onto the generic head, with the inverted triangles and edge stretch of each
at full weight, and how far the lower teeth move on average beside the chin (2.1):
MakeHuman has no teeth of its own to give (``teeth_lower_mm``, ``chin_mm``; the generic
head's own jaw opening moves them 0.76 times as far as its chin).

On MakeHuman, the marking against the points placed on it by hand
(``recon/data/makehuman_hm08_points.csv``, :func:`recon.evaluate.makehuman.reference_points`):
``marking_error_median_pct`` and ``marking_error_p90_pct`` (% of ES0; targets 3 and 8) and
the five points furthest off; on the MediaPipe mask, against its own landmarks through
the project's landmark table (:func:`mask_marking`).

Run: ``python3 benchmarks/foreign_heads.py [MESH ...] [--no-streams]``
Prints ``head.name: value`` lines.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

FOREIGN = ROOT.parent / "shared" / "data" / "foreign_heads"
XFACE = ROOT.parent / "shared" / "data" / "fap_streams" / "xface"
MASK = FOREIGN / "mediapipe_canonical_face" / "canonical_face_model.obj"
MAKEHUMAN_TARGETS = {"jaw_drop": "targets/03_Lip_Parting_and_Jaw_Opening/26.target",
                     "smile": "targets/02_Lower_Face_AUs/12.target",
                     "happy": "targets/00_Emotions/06_Happy.target",
                     "viseme_B": "hbc_visemes/B.target"}


def low_level_checks(head, player, checks) -> dict[str, float]:
    """Each low-level FAP the head has a table for, alone at ±512 (+512 only for a
    unidirectional one): the folds and stretches as played, the FAPU conformance of the
    tables as given (no limits: lips that touch stop where they meet, by design), leaving
    out the eyeballs' FAPs on a head without eyeballs."""
    from fmc.conformance import HEAD_TURN_FAPS, eyeball_centre_shift, fp_conformance
    from fmc.play import Player
    from mpeg4.catalogue import FAPS

    as_given = Player(head, limits=False)
    inverted = 0
    stretch = shift = 0.0
    ok = total = 0
    for (n, _), _table in sorted(head.fat.items(), key=lambda kv: str(kv[0])):
        if not isinstance(n, int) or n < 3 or n in HEAD_TURN_FAPS:
            continue
        for value in (512.0,) if FAPS[n].direction == "U" else (512.0, -512.0):
            parts = player.part_vertices(player.vertices({n: value}))
            inverted = max(inverted, checks.inverted(parts["skin"]))
            stretch = max(stretch, checks.stretch(parts["skin"]))
            shift = max(shift, eyeball_centre_shift(head, parts))
            fp = head.feature_points.get(FAPS[n].feature_points[0])
            if 23 <= n <= 28 and (fp is None or fp.part not in ("eye_l", "eye_r")):
                continue
            a, b = fp_conformance(head, {n: value}, rel_tol=0.05,
                                  moved=as_given.part_vertices(as_given.vertices({n: value})))
            ok, total = ok + a, total + b
    return {"inverted_triangles_max": inverted, "edge_stretch_max": stretch,
            "eyeball_centre_shift_max_mm": 1e3 * shift,
            "fapu_conformance_pct": 100.0 * ok / total if total else float("nan")}


def lip_gap_pbm(head, player) -> float:
    """The inner lips' gap (mm) at the p/b/m viseme, full intensity."""
    parts = player.part_vertices(player.vertices({(1, 1): 63.0}))
    return 1e3 * float(np.linalg.norm(head.fp_position("2.2", parts) - head.fp_position("2.3", parts)))


def measure(name: str, path: Path, streams: list[Path], reference=None) -> dict[str, float]:
    """The head at ``path`` marked (when it has no points), cloned and played;
    ``reference(target)``, when given, adds the marking's error."""
    from chain.clone import target_head
    from fap_conformance import play_file
    from fmc.clone import clone
    from fmc.conformance import SurfaceChecks
    from fmc.heads import animated_head
    from fmc.play import Player
    from mpeg4.errors import InputError
    from mpeg4.io.fap import read_fap

    out: dict[str, float] = {}
    t = time.perf_counter()
    target, warnings = target_head(path)
    out["mark_s"] = time.perf_counter() - t
    out["points"] = len(target.feature_points)
    if reference is not None:
        out.update(reference(target))
    print(f"{name}.parts: {', '.join(target.parts)}")
    try:
        target.fapu
        out["fapu_ok"] = 1
    except InputError as e:
        out["fapu_ok"] = 0
        print(f"{name}.unreliable: {e}")
        return out
    t = time.perf_counter()
    head, _ = clone(animated_head(None), target)
    out["clone_s"] = time.perf_counter() - t
    player, checks = Player(head), SurfaceChecks(head)
    out.update(low_level_checks(head, player, checks))
    for stream in streams:
        res = play_file(head, player, checks, read_fap(stream, lenient=True))
        for k in ("inverted_triangles_max", "edge_stretch_max", "eyeball_centre_shift_max_mm"):
            if math.isfinite(res[k]):
                out[k] = max(out[k], res[k])
    out["lip_gap_pbm_mm"] = lip_gap_pbm(head, player)
    return out


def makehuman_marking(target, raw) -> dict[str, float]:
    """The MakeHuman head as marked for cloning (``target``) against the hand-placed points
    (% of ES0), its points taken on the file's own vertices (``raw``: marking keeps the
    one-part head's vertex order)."""
    from recon.evaluate.makehuman import marking_error, reference_points

    skin = raw.parts["skin"].vertices
    found = {i: b.position(skin) for i, b in target.feature_points.items() if b.part == "skin"}
    errors = marking_error(found, reference_points()[0])
    out = {"marking_error_median_pct": float(np.median(list(errors.values()))),
           "marking_error_p90_pct": float(np.percentile(list(errors.values()), 90)),
           "marking_points_compared": len(errors)}
    for i in sorted(errors, key=errors.get, reverse=True)[:5]:
        out[f"marking_error_pct.{i}"] = errors[i]
    return out


def mask_marking(target, path: Path) -> dict[str, float]:
    """The MediaPipe mask as marked for cloning against its own landmarks: its vertex ``i`` is the
    face mesh's landmark ``i``, so the project's landmark → feature point table
    (:func:`recon.landmarks.mapping.load_mapping`, fitted to photos: its rows' own error
    is 1-5 % of the IPD) applied to the vertices gives where the points belong (% of the
    ES0 of those points, the eyes' centres between their corners)."""
    import trimesh

    from recon.landmarks.mapping import load_mapping

    v = np.asarray(trimesh.load(path, process=False, force="mesh", maintain_order=True).vertices, dtype=np.float64)
    reference = {fp: np.asarray(r.weights) @ v[list(r.landmarks)] for fp, r in load_mapping().items()
                 if max(r.landmarks) < len(v)}
    es0 = abs(reference["3.7"][0] + reference["3.11"][0] - reference["3.12"][0] - reference["3.8"][0]) / 2
    found = {i: b.position(v) for i, b in target.feature_points.items() if b.part == "skin"}
    errors = [100.0 * float(np.linalg.norm(found[i] - reference[i])) / es0 for i in reference if i in found]
    return {"marking_error_vs_facemesh_median_pct": float(np.median(errors)),
            "marking_error_vs_facemesh_p90_pct": float(np.percentile(errors, 90)),
            "marking_points_compared": len(errors)}


def makehuman_as_source(glb: Path) -> dict[str, float]:
    """MakeHuman's own targets cloned onto the generic head: each at full weight."""
    from fmc.clone.cloning import clone_targets
    from fmc.conformance import SurfaceChecks
    from mpeg4.generic_head import load_generic_head
    from mpeg4.io import load_head

    source = load_head(glb)
    generic = load_generic_head()
    t = time.perf_counter()
    cloned = clone_targets(source, generic)
    out = {"clone_s": time.perf_counter() - t}
    moved = generic.copy()
    moved.morph_targets = cloned
    checks = SurfaceChecks(generic)
    for name in cloned:
        parts = moved.morphed({name: 1.0})
        skin = parts["skin"]
        out[f"{name}.inverted_triangles"] = checks.inverted(skin)
        out[f"{name}.edge_stretch"] = checks.stretch(skin)
        # The lower teeth follow the chin (they stayed up when MakeHuman had none to give).
        chin = np.linalg.norm(generic.fp_position("2.1", parts) - generic.fp_position("2.1"))
        teeth = np.linalg.norm(parts["teeth_lower"] - generic.parts["teeth_lower"].vertices, axis=1).mean()
        out[f"{name}.teeth_lower_mm"] = 1000 * teeth
        out[f"{name}.chin_mm"] = 1000 * chin
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("meshes", nargs="*", type=Path, help="more head meshes (GLB, glTF, OBJ, PLY)")
    ap.add_argument("--no-streams", action="store_true", help="skip the Xface streams")
    args = ap.parse_args(argv)
    from fap_conformance import fmt_value
    from mpeg4.io import save_head
    from recon.evaluate.makehuman import MAKEHUMAN_DIR, makehuman_head

    streams = [] if args.no_streams or not XFACE.is_dir() else sorted(XFACE.glob("*.fap"))
    tmp = Path(tempfile.mkdtemp(prefix="foreign_heads_"))
    heads: dict[str, Path] = {}
    references = {}
    makehuman = None
    if (MAKEHUMAN_DIR / "base.obj").exists():
        makehuman = tmp / "makehuman.glb"
        raw = makehuman_head(targets=MAKEHUMAN_TARGETS)
        save_head(raw, makehuman)
        heads["makehuman"] = makehuman
        references["makehuman"] = lambda target: makehuman_marking(target, raw)
    if MASK.exists():
        heads["mediapipe_mask"] = MASK
        references["mediapipe_mask"] = lambda target: mask_marking(target, MASK)
    for p in args.meshes:
        heads[p.stem] = p
    if not heads:
        print(f"no heads: {FOREIGN} is absent and no mesh was given", file=sys.stderr)
        return 2
    for name, path in heads.items():
        for k, v in measure(name, path, streams, references.get(name)).items():
            print(f"{name}.{k}: {fmt_value(v)}", flush=True)
    if makehuman is not None:
        from recon.mark import mark_file

        mark_file(makehuman)  # the source needs its points beside it
        for k, v in makehuman_as_source(makehuman).items():
            print(f"makehuman_source.{k}: {fmt_value(v)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
