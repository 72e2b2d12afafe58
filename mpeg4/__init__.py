"""MPEG-4 Face Animation core shared by reconstruction and motion cloning.

The catalogue (feature points, FAPU, FAPs, visemes, expressions), the :class:`Head`
model, Facial Animation Tables, file I/O (:mod:`mpeg4.io`) and offscreen rendering
(:mod:`mpeg4.render`, its camera :mod:`mpeg4.camera`).
"""

from .catalogue import (
    ANGLE_UNIT, EXPRESSIONS, FAP, FAPS, FAPU_DEFINITIONS, FEATURE_POINTS, FP_GROUP_SIZES, FP_IDS,
    VISEMES, Expression, FeaturePoint, Viseme, check_fp_id, fap, feature_point,
)
from .errors import InputError
from .fapu import FAPU, fapu_from_points
from .fat import (
    FAT, FaceDefMesh, FaceDefTable, FaceDefTransform, MorphSpec, apply_fat, fat_from_morph_targets,
    fat_to_morph_targets, morph_weights,
)
from .head import PART_NAMES, FeaturePointBinding, Head, Part, SparseDisplacement

__all__ = [
    "ANGLE_UNIT", "EXPRESSIONS", "FAP", "FAPS", "FAPU_DEFINITIONS", "FEATURE_POINTS", "FP_GROUP_SIZES", "FP_IDS",
    "VISEMES", "Expression", "FeaturePoint", "Viseme", "check_fp_id", "fap", "feature_point", "InputError", "FAPU",
    "fapu_from_points", "FAT", "FaceDefMesh", "FaceDefTable", "FaceDefTransform", "MorphSpec", "apply_fat",
    "fat_from_morph_targets", "fat_to_morph_targets", "morph_weights", "PART_NAMES", "FeaturePointBinding", "Head",
    "Part", "SparseDisplacement",
]

__version__ = "0.1.0"
