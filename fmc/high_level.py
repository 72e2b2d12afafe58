"""Facial Animation Tables for the visemes and expressions from a head's sculpted shapes.

Each of the 15 visemes (FAP 1) and 7 expressions (FAP 2) is a weighted sum of the head's
ARKit-named shapes, the weights read from ``fmc/data/high_level_shapes.toml``
(:data:`HIGH_LEVEL_SHAPES`); :func:`author_high_level` writes one table for each.
"""

from __future__ import annotations

import numpy as np

from mpeg4.errors import InputError
from mpeg4.fat import FAT, FaceDefTable
from mpeg4.head import Head, SparseDisplacement

from .author import _JAW_SHAPES, JAW_PARTS
from .mesh_tables import combine_shapes, mesh_table

__all__ = ["HIGH_LEVEL_SHAPES", "author_high_level"]


def _load_high_level() -> dict:
    import tomllib
    from importlib import resources

    data = tomllib.loads(resources.files("fmc").joinpath("data/high_level_shapes.toml").read_text())
    out = {}
    for kind, fap in (("visemes", 1), ("expressions", 2)):
        for key, weights in data[kind].items():
            expanded = {}
            for name, w in weights.items():
                if name.endswith("_LR"):
                    expanded[name[:-3] + "_L"] = w
                    expanded[name[:-3] + "_R"] = w
                else:
                    expanded[name] = w
            out[(fap, int(key))] = expanded
    return out


#: (1, viseme) / (2, expression) → shape name → weight at full intensity (63), from
#: ``fmc/data/high_level_shapes.toml``.
HIGH_LEVEL_SHAPES = _load_high_level()


def _high_level_displacement(head: Head, weights: dict) -> dict[str, SparseDisplacement]:
    """The weighted shapes of a viseme or expression, the skin from every shape and the
    jaw's parts (:data:`JAW_PARTS`) from the jaw shapes only; eyeballs and the upper teeth
    never move (their motion in other shapes is sculpting noise)."""
    jaw_shapes = {s for shapes in _JAW_SHAPES.values() for s in shapes}
    skin = {p for p in head.parts if p not in JAW_PARTS and not p.startswith(("eye_", "teeth_", "gums_"))
            and p != "tongue"}
    out: dict[str, SparseDisplacement] = {}
    for group, parts in ((sorted(weights), skin), (sorted(set(weights) & jaw_shapes), set(JAW_PARTS))):
        if not group:
            continue
        for part, d in combine_shapes(head, group, np.array([weights[n] for n in group]), parts).items():
            out[part] = out[part] + d if part in out else d
    return out


def author_high_level(head: Head) -> FAT:
    """FaceDefTables for the 15 visemes and 7 expressions (neutral included) from the
    head's sculpted shapes by :data:`HIGH_LEVEL_SHAPES`; intensity 63 gives the full pose."""
    from mpeg4.fat import HIGH_LEVEL_UNIT

    fat = FAT()
    for (fap, k), weights in HIGH_LEVEL_SHAPES.items():
        missing = [n for n in weights if n not in head.morph_targets]
        if missing:
            raise InputError(f"{'viseme' if fap == 1 else 'expression'} {k} needs the shapes {', '.join(missing)}, "
                             "which the head lacks", fix="author it from a head with ARKit-named shapes, or clone it")
        names = list(weights)
        disp = _high_level_displacement(head, weights) if names else {}
        if disp:
            fat.add(mesh_table(head, fap, {1.0: disp}, 63.0, HIGH_LEVEL_UNIT, high_level=k))
        else:
            fat.add(FaceDefTable(fap, k))
    return fat
