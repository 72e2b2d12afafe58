"""Write ``mpeg4/data/catalogue.toml`` from the project's MPEG-4 reference tables.

The reference (``../shared/reference/mpeg4-fba.md``) lays its tables out one row per item,
``|``-separated, so that a script can read them. This script reads the feature-point,
FAPU, FAP, viseme and expression tables, adds the few machine-readable fields the code
needs (mirror partners, the FAP's axis as a signed unit vector name, the kind of motion),
and writes one TOML table file that :mod:`mpeg4.catalogue` loads.

Run from the repository root::

    python scripts/catalogue_from_reference.py [../shared/reference/mpeg4-fba.md]
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_REFERENCE = ROOT.parent / "shared" / "reference" / "mpeg4-fba.md"
OUT = ROOT / "mpeg4" / "data" / "catalogue.toml"

# FAPU: (unit, first FP, second FP, axis): value = first.axis - second.axis (section 2).
FAPU = [
    ("IRISD0", "3.1", "3.3", "y", "upper and lower eyelid at the pupil (iris diameter)"),
    ("ES0", "3.5", "3.6", "x", "the two pupils"),
    ("ENS0", "3.5", "9.15", "y", "pupil level to the bottom of the nose"),
    ("MNS0", "9.15", "2.2", "y", "bottom of the nose to the mouth (inner upper lip centre)"),
    ("MW0", "8.3", "8.4", "x", "the two mouth corners"),
]

# Rotation FAPs: the rotation axis (right-handed) whose positive angle gives the
# reference's "+dir" (section 3): a positive yaw turns the gaze from +z towards +x,
# i.e. a rotation about +y; a positive pitch turns it towards -y, about +x; a positive
# head roll tilts the top of the head (+y) towards -x, about +z.
ROTATION_AXES = {23: "+y", 24: "+y", 25: "+x", 26: "+x", 48: "+x", 49: "+y", 50: "+z"}


def _rows(text: str, header_start: str) -> list[list[str]]:
    """All rows of every table whose header line starts with ``header_start``."""
    rows, inside = [], False
    for line in text.splitlines():
        if line.startswith(header_start):
            inside = True
            continue
        if inside:
            if line.startswith("|---"):
                continue
            if not line.startswith("|"):
                inside = False
                continue
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows


def _q(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


# Left/right partners, read off the location texts of section 1 (the halfway points
# name other FPs, and the eye corners are named by image side, so text matching alone
# cannot find them).
MIRROR_PAIRS = [
    ("2.4", "2.5"), ("2.6", "2.7"), ("2.8", "2.9"), ("2.11", "2.12"), ("2.13", "2.14"),
    ("3.1", "3.2"), ("3.3", "3.4"), ("3.5", "3.6"), ("3.7", "3.12"), ("3.11", "3.8"),
    ("3.9", "3.10"), ("3.13", "3.14"),
    ("4.1", "4.2"), ("4.3", "4.4"), ("4.5", "4.6"),
    ("5.1", "5.2"), ("5.3", "5.4"), ("6.3", "6.4"),
    ("8.3", "8.4"), ("8.5", "8.6"), ("8.7", "8.8"), ("8.10", "8.9"),
    ("9.1", "9.2"), ("9.5", "9.4"), ("9.7", "9.6"), ("9.13", "9.14"),
    ("10.1", "10.2"), ("10.3", "10.4"), ("10.5", "10.6"), ("10.7", "10.8"), ("10.9", "10.10"),
    ("11.3", "11.2"),
]


def _mirror(fp: dict, sides: dict[str, str]) -> str | None:
    """The partner of a left/right point (None on the midline), checked against the sides."""
    if fp["side"] == "C":
        return None
    for left, right in MIRROR_PAIRS:
        if fp["id"] in (left, right):
            assert sides[left] == "L" and sides[right] == "R", (left, right)
            return right if fp["id"] == left else left
    raise SystemExit(f"no mirror partner listed for {fp['id']}: {fp['location']}")


def main(reference: Path) -> None:
    text = reference.read_text(encoding="utf-8")
    fps = [dict(id=r[0], side=r[1], location=r[2], front=r[3], side_view=r[4])
           for r in _rows(text, "| fp | side | location")]
    faps = _rows(text, "| # | name | what moves")
    visemes = _rows(text, "| # | phonemes (SAMPA)")
    expressions = _rows(text, "| # | expression | what the face")

    # Section 1 numbers the groups 2..11 with these sizes; check them here so a change in
    # the reference cannot pass silently.
    sizes = {g: sum(1 for fp in fps if fp["id"].split(".")[0] == str(g)) for g in range(2, 12)}
    expected = {2: 14, 3: 14, 4: 6, 5: 4, 6: 4, 7: 1, 8: 10, 9: 15, 10: 10, 11: 6}
    assert sizes == expected, sizes
    assert len(faps) == 68 and len(visemes) == 15 and len(expressions) == 7

    sides = {fp["id"]: fp["side"] for fp in fps}
    out = [
        "# MPEG-4 Face Animation catalogue: feature points, FAPU, FAPs, visemes, expressions.",
        "# Written by scripts/catalogue_from_reference.py from the project's MPEG-4 reference;",
        "# edit the reference and re-run the script rather than editing this file by hand.",
        "# Frame: +x the face's own left, +y up, +z towards the viewer.",
        "",
        "feature_points = [",
    ]
    for fp in fps:
        group = int(fp["id"].split(".")[0])
        desc = fp["location"].replace("**(unverified)**", "(unverified)").replace("**", "")
        mirror = _mirror(fp, sides)
        out.append(
            f"  {{id = {_q(fp['id'])}, group = {group}, side = {_q(fp['side'])}, "
            f"front = {_q(fp['front'])}, side_view = {_q(fp['side_view'])}, "
            f"mirror = {_q(mirror or '')}, description = {_q(desc)}}},"
        )
    out += ["]", "", "fapu = ["]
    for name, a, b, axis, desc in FAPU:
        out.append(f"  {{name = {_q(name)}, first = {_q(a)}, second = {_q(b)}, axis = {_q(axis)}, "
                   f"divisor = 1024, description = {_q(desc)}}},")
    out += ["]", "angle_unit = 1e-5  # AU in radians", "", "faps = ["]
    for r in faps:
        num, name, what, unit, ub, plus_dir, axis, grp, fp = r
        num = int(num)
        if num <= 2:
            kind, ax = "high_level", ""
        elif num in ROTATION_AXES:
            kind, ax = "rotation", ROTATION_AXES[num]
        elif num in (29, 30):
            kind, ax = "scale", ""
        elif num == 47:
            kind, ax = "roll", ""
        else:
            kind, ax = "translation", axis.replace("−", "-")
            assert re.fullmatch(r"[+-][xyz]", ax), (num, axis)
        fps_of = [] if fp in ("—", "") else [s.strip() for s in fp.split(",")]
        out.append(
            f"  {{id = {num}, name = {_q(name)}, unit = {_q(unit if unit != 'na' else '')}, "
            f"direction = {_q(ub if ub != 'na' else '')}, kind = {_q(kind)}, axis = {_q(ax)}, "
            f"positive = {_q(plus_dir if plus_dir != 'na' else '')}, group = {int(grp)}, "
            f"feature_points = [{', '.join(_q(s) for s in fps_of)}], description = {_q(what)}}},"
        )
    out += ["]", "", "visemes = ["]
    for num, phon, ex in visemes:
        phonemes = [] if phon.startswith("none") else [p.strip() for p in phon.split(",")]
        examples = ex.replace("*", "")
        name = "neutral" if not phonemes else "_".join(p.replace(":", "") for p in phonemes)
        out.append(f"  {{id = {int(num)}, name = {_q(name)}, phonemes = [{', '.join(_q(p) for p in phonemes)}], "
                   f"examples = {_q('' if examples == '—' else examples)}}},")
    out += ["]", "", "expressions = ["]
    for num, name, desc in expressions:
        out.append(f"  {{id = {int(num)}, name = {_q(name)}, description = {_q(desc)}}},")
    out += ["]", ""]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(out), encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}: {len(fps)} feature points, {len(faps)} FAPs, "
          f"{len(visemes) - 1} visemes, {len(expressions) - 1} expressions")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_REFERENCE)
