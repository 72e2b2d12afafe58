"""FAP conformance on real streams: does every frame move the face as the standard says?

Plays every ``.fap`` file of the given folders (default: the Xface streams in
``../shared/data/fap_streams/xface`` and the six basic expressions built from Greta's
tables in ``../shared/data/fap_streams/greta`` (:func:`mpeg4.io.greta.read_expressions`),
written to ``.fap`` here, rising over 0.4 s, held, falling) on the
generic head and on the example's reconstructed head (built by the main job into a
temporary folder), and measures on every frame, played without the head turns:

- ``eyeball_centre_shift_max_mm``: how far an eyeball's centre moves (target ≤ 0.2);
- ``fp_conformance_pct``: share of predicted feature-point frames within max(10 %, 0.5 mm)
  of value × FAPU along the FAPs' axes (target ≥ 95);
  ``fp_conformance_played_pct``: the same against the values as the limits a face has left
  them (:mod:`fmc.limits`: lids and lips that meet, brows and cheeks held to their range),
  what the decoder was asked to play;
- ``inverted_triangles_max``: skin triangles turned over (target 0);
- ``edge_stretch_max``: longest skin edge over its neutral length (target ≤ 2.5);
- ``lid_overlap_max_mm``: a lower lid above its upper one (target ≤ 0.5);
- ``region_over_fp_max``: for each FAP the file uses, alone at its largest value there,
  the largest skin motion over its point's motion (target ≤ 1.3; the jaw FAPs excepted).

Run: ``python3 benchmarks/fap_conformance.py [DIR ...] [--heads generic,example]``.
Prints ``name: value`` lines per head and file, then the totals per head.
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
DATA = ROOT.parent / "shared" / "data" / "fap_streams"


def write_greta_streams(folder: Path, out_dir: Path, fps: float = 25.0) -> list[Path]:
    """Each basic expression as a 2 s ``.fap``: 0.4 s rise, held, 0.4 s fall."""
    from mpeg4.io.fap import FapStream, write_fap
    from mpeg4.io.greta import BASIC_EXPRESSIONS, read_expressions

    n = int(2 * fps)
    ramp = np.clip(np.minimum(np.arange(n), n - 1 - np.arange(n)) / (0.4 * fps), 0.0, 1.0)
    paths = []
    for name, expression in read_expressions(folder, BASIC_EXPRESSIONS).items():
        values = expression.values
        table = np.full((n, 68), np.nan)
        for f, v in values.items():
            table[:, f - 1] = np.round(ramp * v)
        path = out_dir / f"greta_{name}.fap"
        write_fap(FapStream.from_values(table, fps=fps, name=f"greta_{name}"), path)
        paths.append(path)
    return paths


def play_file(head, player, checks, stream) -> dict[str, float]:
    from fmc.author import JAW_FAPS
    from fmc.conformance import HEAD_TURN_FAPS, eyeball_centre_shift, fp_conformance, lid_overlap, region_over_fp
    from fmc.limits import Limits

    # The player's own limits when it has them (they read the tables once per head).
    limits = player.decode.limits or Limits(head)

    held = stream.held()
    shift = stretch = overlap = 0.0
    inverted = ok = total = played_ok = played_total = 0
    largest: dict[int, float] = {}
    for i in range(held.n_frames):
        values = {k: v for k, v in held.frame_values(i).items() if k not in HEAD_TURN_FAPS}
        for k, v in values.items():
            if isinstance(k, int) and abs(v) > abs(largest.get(k, 0.0)):
                largest[k] = v
        parts = player.part_vertices(player.vertices(values))
        shift = max(shift, eyeball_centre_shift(head, parts))
        a, b = fp_conformance(head, values, moved=parts)
        ok, total = ok + a, total + b
        a, b = fp_conformance(head, limits(values)[0], moved=parts)
        played_ok, played_total = played_ok + a, played_total + b
        inverted = max(inverted, checks.inverted(parts["skin"]))
        stretch = max(stretch, checks.stretch(parts["skin"]))
        overlap = max(overlap, lid_overlap(head, parts))
    ratios = [region_over_fp(head, n, v) for n, v in largest.items()
              if n not in JAW_FAPS and (n, 0) in head.fat and v]
    ratios = [r for r in ratios if math.isfinite(r)]
    return {"eyeball_centre_shift_max_mm": 1e3 * shift,
            "fp_conformance_pct": 100.0 * ok / total if total else float("nan"),
            "fp_conformance_played_pct": 100.0 * played_ok / played_total if played_total else float("nan"),
            "inverted_triangles_max": inverted, "edge_stretch_max": stretch,
            "lid_overlap_max_mm": 1e3 * overlap, "region_over_fp_max": max(ratios, default=float("nan")),
            "_ok": ok, "_total": total, "_played_ok": played_ok, "_played_total": played_total}


def fmt_value(v) -> str:
    """A figure as printed: whole numbers whole, the rest to two decimals."""
    return str(v) if isinstance(v, (int, np.integer)) else f"{v:.2f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="*", type=Path, help="folders of .fap files (default: the shared Xface + Greta)")
    ap.add_argument("--heads", default="generic,example", help="comma-separated: generic, example")
    args = ap.parse_args(argv)

    from fmc.conformance import SurfaceChecks
    from fmc.play import Player
    from mpeg4.generic_head import load_generic_head
    from mpeg4.io.fap import read_fap

    tmp = Path(tempfile.mkdtemp(prefix="fap_conformance_"))
    files: list[Path] = []
    dirs = args.dirs or [DATA / "xface"]
    for d in dirs:
        if not d.is_dir():
            print(f"skipped: {d} is not a folder", file=sys.stderr)
            continue
        files += sorted(d.glob("*.fap"))
    if not args.dirs and (DATA / "greta").is_dir():
        files += write_greta_streams(DATA / "greta", tmp)
    if not files:
        print("no .fap files found", file=sys.stderr)
        return 2

    heads = {}
    for name in args.heads.split(","):
        if name == "generic":
            heads[name] = load_generic_head(with_fat=True)
        elif name == "example":
            from chain.example import run_example
            from mpeg4.io import load_head

            t = time.perf_counter()
            paths = run_example(tmp / "example", speak=False, texture_size=512)
            heads[name] = load_head(paths["head"])
            print(f"example_head_build_s: {time.perf_counter() - t:.1f}")
        else:
            print(f"unknown head {name!r} (generic or example)", file=sys.stderr)
            return 2

    for hname, head in heads.items():
        player, checks = Player(head), SurfaceChecks(head)
        totals: dict[str, float] = {}
        ok = total = played_ok = played_total = 0
        for path in files:
            res = play_file(head, player, checks, read_fap(path, lenient=True))
            ok, total = ok + res.pop("_ok"), total + res.pop("_total")
            played_ok, played_total = played_ok + res.pop("_played_ok"), played_total + res.pop("_played_total")
            for k, v in res.items():
                print(f"{hname}.{path.stem}.{k}: {fmt_value(v)}")
                if not k.startswith("fp_conformance") and (isinstance(v, int) or math.isfinite(v)):
                    totals[k] = max(totals.get(k, v), v)
        totals["fp_conformance_pct"] = 100.0 * ok / total if total else float("nan")
        totals["fp_conformance_played_pct"] = 100.0 * played_ok / played_total if played_total else float("nan")
        for k in ("eyeball_centre_shift_max_mm", "fp_conformance_pct", "fp_conformance_played_pct",
                  "inverted_triangles_max", "edge_stretch_max", "lid_overlap_max_mm", "region_over_fp_max"):
            print(f"{hname}.{k}: {fmt_value(totals[k])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
