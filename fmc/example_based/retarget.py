"""Retargeting at run time, and whole animations in and out.

:class:`Retargeter` precomputes everything Pyun et al.'s run time needs from a source and
a target key-model set; a frame is then its feature points' displacements d, the
parameters p = F d, the weights w(p) of the cardinal basis and the target
T_B + Σ w_i (T_i − T_B). For a whole animation the weights of all frames are one small
matrix product of the basis values with the coefficients, and the target vertices one
more with the target key-models' displacements.

:func:`read_animation` turns what a user has into source vertex frames: a GLB whose
animation drives the source head's morph targets (``fmc play``/``fmc animate`` write
those), an ``.npz`` of vertex frames, or a ``.fap`` stream played through the source
head's animation tables. :func:`retarget` is ``fmc retarget``: source key-models, target
key-models (supplied, or drafted by facial motion cloning for an animator to edit), an
input animation in, the target head with its key-models as morph targets and the
weights as a morph animation out.
"""

from __future__ import annotations

import io
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from mpeg4.errors import InputError, require_file
from mpeg4.head import Head

from .cardinal import CardinalBasis
from .key_models import EMOTIONAL, VERBAL, KeyModels, composite_key_models, key_models_from_shapes
from .parameters import Parameterisation

__all__ = ["Retargeter", "read_animation", "source_key_models", "target_key_models", "write_retargeted",
           "retarget", "KEY_MODEL_SOURCES"]

#: Where ``fmc retarget`` takes the source key-models from.
KEY_MODEL_SOURCES = ("visemes-expressions", "morph-targets")


class Retargeter:
    """Example-based cloning from a source key-model set onto a target one.

    Parameters
    ----------
    source : KeyModels
        Source base model and key-models (with a head, for feature point ids).
    target : KeyModels
        Target base model and key-models of the same names (any mesh; extra names are
        ignored, the order follows ``source``).
    feature_points : sequence of str or int, optional
        Parameterising points on the source (default
        :data:`fmc.example_based.parameters.FEATURE_POINTS`).
    threshold : float
        Relative PCA eigenvalue threshold (the paper's 1e-5).
    dtype : numpy dtype
        Of the target blend: ``np.float32`` halves the memory a frame reads (the vertices
        then carry about 1e-7 relative round-off, well below a micrometre); the weights
        are always computed in double precision.

    Attributes
    ----------
    parameterisation : Parameterisation
    basis : CardinalBasis
        Over the neutral (parameters 0) and the source key-models.
    preprocessing_seconds : float

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> face = rng.normal(size=(6, 3))
    >>> src = KeyModels.from_positions({"neutral": face, "a": face + rng.normal(size=(6, 3)),
    ...                                 "b": face + rng.normal(size=(6, 3))})
    >>> tgt = KeyModels.from_positions({n: 2 * src.positions(n) for n in ("neutral", "a", "b")})
    >>> r = Retargeter(src, tgt, feature_points=[0, 1, 2])
    >>> np.allclose(r(src.positions("b")), tgt.positions("b"))
    True

    References
    ----------
    .. [1] H. Pyun et al., "An example-based approach for facial expression cloning",
       SCA 2003, sections 4-5.
    """

    def __init__(self, source: KeyModels, target: KeyModels, feature_points: Sequence[str | int] | None = None,
                 threshold: float = 1e-5, dtype=np.float64):
        t0 = time.perf_counter()
        if not len(source):
            raise InputError("the source has no key-models", fix="give the neutral and at least one key-model")
        missing = [n for n in source.names if n not in target.names]
        if missing:
            raise InputError(f"the target lacks the key-models {', '.join(missing[:4])}"
                             f"{' ...' if len(missing) > 4 else ''}",
                             fix="give the target every source key-model (or let fmc retarget draft them with FMC)")
        self.source = source
        self.target = target.select(source.names)
        self.parameterisation = Parameterisation.fit(source, feature_points, threshold)
        vectors = np.einsum("mc,ncx->nmx", self.parameterisation.weights,
                            source.displacements[:, self.parameterisation.vertices]).reshape(len(source), -1)
        params = np.vstack([np.zeros(self.parameterisation.dimension), vectors @ self.parameterisation.matrix.T])
        self.basis = CardinalBasis(params, ["neutral"] + source.names)
        # The neutral's own weight multiplies T_B − T_B = 0: only the key-models' columns.
        self._coefficients = np.ascontiguousarray(self.basis.coefficients[:, 1:])
        self._blend = self.target.displacements.reshape(len(source), -1).astype(dtype)
        self._neutral = self.target.neutral.astype(dtype)
        self.preprocessing_seconds = time.perf_counter() - t0

    @property
    def names(self) -> list[str]:
        return self.source.names

    def _check(self, frames: np.ndarray) -> np.ndarray:
        frames = np.asarray(frames, dtype=np.float64)
        if frames.ndim == 2:
            frames = frames[None]
        if frames.ndim != 3 or frames.shape[1:] != (self.source.n_vertices, 3):
            raise InputError(f"input frames have shape {frames.shape}, the source model has {self.source.n_vertices} "
                             "vertices", fix="give frames of the source head's mesh, all parts stacked (F, V, 3)")
        return frames

    def weights(self, frames: np.ndarray) -> np.ndarray:
        """(F, N) key-model weights of (F, V, 3) source vertex frames (all parts stacked)."""
        return self.basis.basis(self.parameterisation(self._check(frames))) @ self._coefficients

    def vertices(self, weights: np.ndarray) -> np.ndarray:
        """(F, W, 3) target frames T_B + Σ w_i (T_i − T_B) for (F, N) weights."""
        w = np.atleast_2d(np.asarray(weights, dtype=self._blend.dtype))
        return self._neutral + (w @ self._blend).reshape(len(w), -1, 3)

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """(F, W, 3) target frames of (F, V, 3) source frames."""
        return self.vertices(self.weights(frames))


# --- animations in --------------------------------------------------------------------

def read_animation(path: str | os.PathLike, source: Head) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Source vertex frames of an animation file.

    Parameters
    ----------
    path : str or os.PathLike
        ``.glb`` with a morph-weight animation of a head with the source's mesh (its own
        morph targets and its animation tables' intervals); ``.npz`` with ``vertices``
        (F, V, 3) in metres, all of the source's parts stacked in its part order or the
        skin alone, and ``times`` (F,) seconds or ``fps``; ``.fap`` played through the
        source head's animation tables.
    source : Head

    Returns
    -------
    frames : (F, V, 3) float
        All parts stacked.
    times : (F,) float
        Seconds from the first frame.
    warnings : list of str
    """
    path = require_file(path, "animation file")
    ext = Path(path).suffix.lower()
    neutral = np.concatenate([p.vertices for p in source.parts.values()])
    if ext == ".npz":
        return _read_npz(path, source, neutral)
    if ext == ".fap":
        from mpeg4.io import read_fap

        from ..play import Player

        if source.fat is None or not len(source.fat):
            raise InputError("a .fap stream needs the source head's animation tables, and it has none",
                             where=path, fix="author them (fmc author SOURCE -o SOURCE_WITH_FAT.glb) and use that head")
        stream = read_fap(path)
        if stream.n_frames == 0:
            raise InputError("the stream has no frames", where=path, fix="give a .fap file with at least one frame")
        frames = np.array(list(Player(source).play(stream)))
        return frames, (stream.frame_numbers - stream.frame_numbers[0]) / stream.fps, []
    if ext in (".glb", ".gltf"):
        return _read_glb(path, source, neutral)
    raise InputError(f"cannot read animations from '{ext or 'no extension'}' files", where=path,
                     fix="give a .glb (morph-weight animation), .npz (vertex frames) or .fap stream")


def _read_npz(path: str, source: Head, neutral: np.ndarray):
    with np.load(path) as data:
        if "vertices" not in data:
            raise InputError(f"no 'vertices' array (found: {', '.join(data.files) or 'nothing'})", where=path,
                             fix="store the frames as vertices=(F, V, 3) metres")
        v = np.asarray(data["vertices"], dtype=np.float64)
        if v.ndim != 3 or v.shape[2] != 3:
            raise InputError(f"'vertices' has shape {v.shape}, expected (frames, vertices, 3)", where=path)
        n = len(v)
        if "times" in data:
            times = np.asarray(data["times"], dtype=np.float64).reshape(-1)
        else:
            fps = float(data["fps"]) if "fps" in data else 25.0
            times = np.arange(n) / fps
    if len(times) != n or (np.diff(times) <= 0).any():
        raise InputError(f"'times' must hold {n} increasing values (seconds)", where=path)
    skin = source.skin.n_vertices
    if v.shape[1] == len(neutral):
        frames = v
    elif v.shape[1] == skin:  # the skin alone: the other parts stay neutral
        frames = np.broadcast_to(neutral, (n, *neutral.shape)).copy()
        frames[:, :skin] = v
    else:
        raise InputError(f"the frames have {v.shape[1]} vertices; the source head has {len(neutral)} "
                         f"(all parts) and {skin} on its skin", where=path,
                         fix="give frames of the source head's mesh")
    if not np.isfinite(frames).all():
        raise InputError("the frames contain NaN or infinity", where=path)
    return frames, times - times[0], []


def _read_glb(path: str, source: Head, neutral: np.ndarray):
    from mpeg4.fat import fat_to_morph_targets
    from mpeg4.io.gltf import read_glb, read_glb_animation

    head = read_glb(path)
    anim = read_glb_animation(path)
    if anim is None or not anim.weights:
        raise InputError("the GLB has no morph-weight animation", where=path,
                         fix="give a GLB with an animation of its morph targets (fmc play and fmc animate write them)")
    for name, part in source.parts.items():
        if name not in head.parts or head.parts[name].n_vertices != part.n_vertices:
            have = head.parts[name].n_vertices if name in head.parts else 0
            raise InputError(f"the animated head's part '{name}' has {have} vertices, the source's {part.n_vertices}",
                             where=path, fix="animate the source head itself (the same mesh)")
    targets = dict(head.morph_targets)
    if head.fat is not None and len(head.fat):
        targets.update(fat_to_morph_targets(head.fat, head.fapu)[0])
    offsets = dict(zip(source.parts, np.cumsum([0] + [p.n_vertices for p in source.parts.values()][:-1]).tolist()))
    base = np.concatenate([head.parts[n].vertices for n in source.parts])
    frames = np.broadcast_to(base, (len(anim.times), *base.shape)).copy()
    unknown = sorted(set(anim.weights) - set(targets))
    if unknown:
        raise InputError(f"the animation drives morph targets the file does not define: {', '.join(unknown[:3])}",
                         where=path)
    for name, w in anim.weights.items():
        for part, d in targets[name].items():
            if part in offsets:
                frames[:, offsets[part] + d.indices] += w[:, None, None] * d.vectors
    warnings = []
    if any(np.abs(q[:, :3]).max() > 1e-9 for q in anim.rotations.values()):
        warnings.append(f"the animation turns {', '.join(sorted(anim.rotations))}; key-models carry expressions "
                        "only, so the rotations are left out")
    return frames, anim.times - anim.times[0], warnings


# --- key-models -------------------------------------------------------------------------

def source_key_models(head: Head, kind: str = "visemes-expressions") -> KeyModels:
    """The source key-models of a head.

    ``"visemes-expressions"``: the 14 visemes and 6 expressions (its own morph targets of
    those names, :data:`~fmc.example_based.key_models.VERBAL` and
    :data:`~fmc.example_based.key_models.EMOTIONAL`, if it has them all, else mixed from
    its ARKit-named shapes) and their 84 composites. ``"morph-targets"``: its morph
    targets as they are (each must move the feature points differently).
    """
    if kind not in KEY_MODEL_SOURCES:
        raise InputError(f"unknown key-model source '{kind}'", fix=f"use one of {', '.join(KEY_MODEL_SOURCES)}")
    if kind == "morph-targets":
        if not head.morph_targets:
            raise InputError("the source head has no morph targets to use as key-models",
                             fix="give a head with key-models as named morph targets, or use visemes-expressions")
        return KeyModels.from_head(head)
    pure = list(VERBAL) + list(EMOTIONAL)
    keys = (KeyModels.from_head(head, pure) if all(n in head.morph_targets for n in pure)
            else key_models_from_shapes(head))
    return composite_key_models(keys)[0]


def target_key_models(source: KeyModels, target: Head) -> tuple[KeyModels, list[str]]:
    """The target key-models for a source set: the target head's own morph targets of the
    source's names; composites built from its own pure visemes and expressions when it has
    those but not the composites; and whatever is still missing drafted by facial motion
    cloning (:func:`fmc.clone.clone`) of the source key-models.

    Returns
    -------
    keys : KeyModels
    notes : list of str
        What was drafted, for the user.
    """
    names = source.names
    have = [n for n in names if n in target.morph_targets]
    notes = []
    pure = list(VERBAL) + list(EMOTIONAL)
    if len(have) < len(names) and all(n in target.morph_targets for n in pure) and set(pure) <= set(names):
        composed = composite_key_models(KeyModels.from_head(target, pure))[0]
        target = composed.to_head()
        notes.append("composited the target's own visemes and expressions")
        have = [n for n in names if n in target.morph_targets]
    missing = [n for n in names if n not in have]
    if missing:
        from ..clone import clone

        moving = source.morph_targets()
        src = Head(source.head.parts, source.head.feature_points, {n: moving[n] for n in missing},
                   metadata=source.head.metadata)
        drafted, warnings = clone(src, target)
        merged = target.copy()
        merged.fat = None
        merged.morph_targets = {**{n: target.morph_targets[n] for n in have}, **drafted.morph_targets}
        target = merged
        notes.append(f"drafted {len(missing)} of {len(names)} target key-models by facial motion cloning "
                     "(write them with --drafts, edit them, and pass that file as the target)")
        notes.extend(warnings)
    return KeyModels.from_head(target, names), notes


# --- animations out ---------------------------------------------------------------------

def write_retargeted(target: KeyModels, weights: np.ndarray, times: np.ndarray, out_dir: str | os.PathLike,
                     npz: bool = False, name: str = "retargeted") -> dict[str, Path]:
    """Write the target's animation: ``animation.glb`` (the target head, its key-models as
    morph targets and the weights as their animation) and with ``npz`` ``frames.npz``
    (``vertices`` (F, W, 3) float32 metres, ``times``, ``weights``, ``names``)."""
    from mpeg4.io.atomic import atomic_write
    from mpeg4.io.gltf import GlbAnimation, write_glb

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    head = target.to_head()
    anim = GlbAnimation(np.asarray(times, dtype=np.float64),
                        {n: weights[:, i] for i, n in enumerate(target.names)}, name=name)
    paths = {"animation": out / "animation.glb"}
    write_glb(head, paths["animation"], animation=anim)
    if npz:
        paths["frames"] = out / "frames.npz"
        frames = target.neutral + (weights @ target.displacements.reshape(len(target), -1)).reshape(len(weights), -1, 3)
        buf = io.BytesIO()
        np.savez_compressed(buf, vertices=frames.astype(np.float32), times=np.asarray(times, dtype=np.float64),
                            weights=weights, names=np.array(target.names))
        with atomic_write(paths["frames"], "wb") as f:
            f.write(buf.getvalue())
    return paths


def retarget(source_path: str | os.PathLike, target_path: str | os.PathLike, animation_path: str | os.PathLike,
             out_dir: str | os.PathLike, key_models: str = "visemes-expressions", drafts: str | os.PathLike | None = None,
             npz: bool = False, progress: Callable[[str], None] | None = None) -> dict[str, Path]:
    """``fmc retarget``: clone an animation of the source head onto the target head by
    example-based cloning (:class:`Retargeter`).

    Parameters
    ----------
    source_path : path
        Source head (GLB) with its key-models as morph targets, or with ARKit-named
        shapes for ``key_models="visemes-expressions"``.
    target_path : path
        Target head (GLB, or OBJ with its fdp.json); key-models it lacks are drafted by
        facial motion cloning.
    animation_path : path
        Input animation of the source (:func:`read_animation`).
    out_dir : path
        Output folder.
    key_models : {"visemes-expressions", "morph-targets"}
        See :func:`source_key_models`.
    drafts : path, optional
        Also write the target head with all its key-models as morph targets (GLB), for
        an animator to edit and pass back as the target.
    npz : bool
        Also write the target vertex frames.

    Returns
    -------
    dict of str to Path
    """
    from mpeg4.io import load_head, save_head

    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    for path, kind in ((source_path, "source head"), (target_path, "target head"), (animation_path, "animation file")):
        require_file(path, kind)  # before any of the work
    source = load_head(source_path)
    skeys = source_key_models(source, key_models)
    say(f"{len(skeys)} source key-models")
    tkeys, notes = target_key_models(skeys, load_head(target_path))
    for n in notes:
        say(n)
    frames, times, warnings = read_animation(animation_path, source)
    for w in warnings:
        say(f"warning: {w}")
    r = Retargeter(skeys, tkeys)
    say(f"{r.parameterisation.dimension} parameters from {len(r.parameterisation.feature_points)} feature points; "
        f"weight functions in {r.preprocessing_seconds:.2f} s")
    t = time.perf_counter()
    weights = r.weights(frames)
    say(f"{len(frames)} frames in {1000 * (time.perf_counter() - t) / len(frames):.3f} ms per frame")
    paths = write_retargeted(tkeys, weights, times, out_dir, npz=npz, name=Path(animation_path).stem)
    if drafts is not None:
        paths["drafts"] = Path(save_head(tkeys.to_head(), drafts))
    say(f"done in {time.perf_counter() - t0:.1f} s")
    return paths
