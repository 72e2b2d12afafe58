"""Writing a build's output folder: the head files, its annotations, a preview and the provenance.

``head.glb``, ``head.obj`` + ``head.mtl`` + the textures, ``head.fdp.json``
(:func:`bundle_fdp`: the head's feature points and the photos' annotations, with the
provenance stamped by :func:`build_time`) and ``preview.png`` (:func:`preview_with_photos`).
:class:`PhotoPair` and :class:`BuildResult`, what a build reads and gives, are defined here
so that this module needs nothing of :mod:`recon.build`, which re-exports them.
"""

from __future__ import annotations

import hashlib
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head

from .texture.cameras import FittedCamera

__all__ = ["PhotoPair", "BuildResult", "bundle_fdp", "build_time", "preview_with_photos"]


@dataclass
class PhotoPair:
    """A front and a side photo with their annotations, or a front photo alone.

    Attributes
    ----------
    front, side : (H, W, 3) uint8
        ``side`` is None for a front photo alone.
    fdp : mpeg4.io.fdp_json.FdpFile
        With ``front`` and ``side`` views; their sizes and points match the photos as read.
    paths : dict of str to str
        ``front``, ``side`` and ``fdp`` as given (for provenance and errors).
    scale : float
        The photos' size as read over their size in the files (below 1 when they were over
        :data:`recon.photos.MAX_PHOTO_PIXELS`); focal lengths in the files' pixels are
        multiplied by it.
    views : dict of str to ViewAnnotation, optional
        The annotations as the file gives them, in the files' pixels (``fdp.views`` when
        None); what the bundle records.
    """

    front: np.ndarray
    side: np.ndarray | None
    fdp: object
    paths: dict[str, str] = field(default_factory=dict)
    scale: float = 1.0
    views: dict | None = None

    @property
    def given_views(self) -> dict:
        return self.fdp.views if self.views is None else self.views


@dataclass
class BuildResult:
    """A built head and what went into it.

    Attributes
    ----------
    head : Head
        Textured; ``metadata["build"]`` records the options and the fit.
    cameras : dict of str to FittedCamera
        Of the texture's photos (``front``, ``side``, ``mirrored``).
    skin : recon.texture.SkinTexture
    timings : dict of str to float
        Seconds per step: ``shape``, ``texture``, ``atlas`` (with ``--atlas``), and from
        :func:`run_build` also ``detection`` (when the points were detected), ``export``
        (writing the bundle) and ``total`` (from the command's start).
    """

    head: Head
    cameras: dict[str, FittedCamera]
    skin: object
    timings: dict[str, float]


def _sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mpeg4-heads")
    except PackageNotFoundError:
        return "unknown"


def build_time(created: str | None = None) -> str:
    """The provenance time stamp: ``created`` if given, else ``SOURCE_DATE_EPOCH`` (seconds
    since 1970, the reproducible-builds convention) if set, else now; ISO 8601, UTC."""
    if created is not None:
        return created
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch:
        try:
            t = int(epoch)
        except ValueError:
            raise InputError(f"SOURCE_DATE_EPOCH is {epoch!r}, not a whole number of seconds",
                             where="environment", fix="set it to seconds since 1970-01-01 UTC, or unset it") from None
    else:
        t = time.time()
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t))


def bundle_fdp(head: Head, shape: PhotoPair, texture: PhotoPair | None, options: dict,
               created: str | None = None, provenance: dict | None = None):
    """The ``head.fdp.json`` of a build: 3D points, bindings, texture coordinates, FAPU, the
    annotations of the shape's photos and the provenance (inputs with their SHA-256,
    options, version, time: see :func:`build_time`; ``provenance`` adds entries)."""
    from mpeg4.io import fdp_from_head

    fdp = fdp_from_head(head)
    fdp.views = shape.given_views
    inputs = {"shape": {k: {"path": v, "sha256": _sha256(v)} for k, v in shape.paths.items()}}
    if texture is not None:
        inputs["texture"] = {k: {"path": v, "sha256": _sha256(v)} for k, v in texture.paths.items()}
    meta = {k: v for k, v in fdp.metadata.items() if k not in ("duplicated_vertices",)}
    meta["provenance"] = {"tool": "recon build", "version": _version(), "inputs": inputs, "options": options,
                          "created": build_time(created), **(provenance or {})}
    fdp.metadata = meta
    return fdp


def preview_with_photos(head: Head, pair: PhotoPair, size: int = 720) -> np.ndarray:
    """(H, W, 3) uint8: the input photo(s), then the head's labelled front, side and
    three-quarter renders, all ``size`` pixels high."""
    import cv2

    from mpeg4.preview import preview_image

    sheet = preview_image(head, size=size)
    photos = []
    for im in (pair.front, pair.side) if pair.side is not None else (pair.front,):
        h, w = im.shape[:2]
        scale = size / h
        small = cv2.resize(im, (max(1, round(w * scale)), size), interpolation=cv2.INTER_AREA)
        photos.append(small)
    strip = np.concatenate(photos, axis=1)
    pad = np.full((sheet.shape[0] - size, strip.shape[1], 3), 255, np.uint8)
    left = np.concatenate([strip, pad], axis=0)
    cv2.putText(left, "input photos", (12, size + 30), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (40, 40, 40), 1, cv2.LINE_AA)
    return np.concatenate([left, sheet], axis=1)


def _write_bundle(result: BuildResult, shape: PhotoPair, texture: PhotoPair | None, options: dict,
                  folder: Path, say, created: str | None = None, provenance: dict | None = None) -> dict[str, Path]:
    import cv2

    from mpeg4.io import save_head, write_fdp_json
    from mpeg4.io.obj import write_obj

    head = result.head
    paths = {"head": folder / "head.glb", "obj": folder / "head.obj", "mtl": folder / "head.mtl",
             "texture": folder / "texture.png", "fdp": folder / "head.fdp.json", "preview": folder / "preview.png"}
    say("writing head.glb")
    save_head(head, paths["head"])
    say("writing head.obj, head.mtl and the textures")
    write_obj(head, paths["obj"], texture_names={"skin": "texture.png"})
    paths.update({f"texture_{n}": folder / f"head_{n}.png" for n, p in head.parts.items()
                  if p.texture is not None and n != "skin"})
    fdp = bundle_fdp(head, shape, texture, options, created, provenance)
    fdp.metadata["obj_parts"] = {n: {"centre": None if p.centre is None else p.centre.tolist()}
                                 for n, p in head.parts.items()}
    write_fdp_json(paths["fdp"], fdp)
    say("rendering preview.png")
    image = preview_with_photos(head, texture or shape)
    ok, data = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    paths["preview"].write_bytes(data.tobytes())
    return paths
