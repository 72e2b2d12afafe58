"""Where the feature points start: automatic detection, a saved file, or the generic head.

The annotation tool opens with every point a photo can show already placed, so that the
user corrects rather than clicks. :func:`initial_annotation` chooses the start, in this
order:

1. the ``--fdp`` file, when it exists (it is the user's own work and is never replaced by
   a guess);
2. :func:`recon.landmarks.detect` (automatic detection, with a confidence per point), when
   that module is installed; points it does not give are placed as in 3;
3. the generic head's feature points, seen by an orthographic front and side camera and
   placed on each photo by :func:`fit_view`: a similarity fit to the points already known
   in that photo, or by the image centre and size when none are.

Points placed from the generic head carry confidence :data:`GUESS_CONFIDENCE` (0: nothing
in the photo supports them), so that the tool lists them for checking.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from mpeg4.catalogue import FP_IDS
from mpeg4.errors import InputError
from mpeg4.io.fdp_json import FdpFile, ViewAnnotation, read_fdp_json
from recon.landmarks import detector
from recon.landmarks.layout import generic_layout, shown_in, visible_side

__all__ = ["VIEWS", "GUESS_CONFIDENCE", "HEAD_FILL", "shown_in", "visible_side", "generic_layout", "ViewFit",
           "fit_view", "complete_views", "Initialisation", "detector", "initial_annotation"]

#: The two photos, in the order the tool shows them.
VIEWS = ("front", "side")
#: Confidence of a point placed from the generic head's proportions alone.
GUESS_CONFIDENCE = 0.0
#: With nothing known about a photo, the head's feature points span this share of its height.
HEAD_FILL = 0.5


@dataclass
class ViewFit:
    """A 2D similarity from layout metres to photo pixels: ``pixel = matrix @ p + offset``.

    Attributes
    ----------
    matrix : (2, 2) float64
        Scale times a rotation, or a reflection for a side photo facing the other way.
    offset : (2,) float64
        Pixels.
    rms_px : float or None
        Residual at the points it was fitted to; None when placed by the image size.
    known : int
        How many known points it was fitted to.
    """

    matrix: np.ndarray
    offset: np.ndarray
    rms_px: float | None
    known: int

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points, dtype=np.float64).reshape(-1, 2) @ self.matrix.T + self.offset

    @property
    def scale(self) -> float:
        """Pixels per metre."""
        return float(np.sqrt(abs(np.linalg.det(self.matrix))))


def _framing(layout: Mapping[str, np.ndarray], size: tuple[int, int], scale: float | None = None,
             centre_y: float | None = None) -> ViewFit:
    """The layout centred in the image, its height :data:`HEAD_FILL` of the image's."""
    pts = np.array(list(layout.values()))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    w, h = size
    s = HEAD_FILL * h / max(float(hi[1] - lo[1]), 1e-9) if scale is None else scale
    mid = 0.5 * (lo + hi)
    cy = (h - 1) / 2 if centre_y is None else centre_y
    return ViewFit(np.eye(2) * s, np.array([(w - 1) / 2, cy]) - s * mid, None, 0)


def fit_view(layout: Mapping[str, np.ndarray], known: Mapping[str, np.ndarray], size: tuple[int, int],
             reflect: bool = False) -> ViewFit:
    """The similarity that puts a layout on a photo's known points.

    Parameters
    ----------
    layout : mapping of str to (2,) array
        FP id → metres in image axes (see :func:`generic_layout`).
    known : mapping of str to (2,) array
        FP id → pixel of the points already placed on the photo; ids not in ``layout`` are
        ignored.
    size : (width, height)
        The photo's size in pixels.
    reflect : bool
        Also try the mirror image of the layout and keep whichever fits better (a side photo
        may face either way).

    Returns
    -------
    ViewFit
        Least-squares similarity [1]_ with two or more known points; with one, the default
        scale moved onto it; with none, :data:`HEAD_FILL` of the image height, centred.

    References
    ----------
    .. [1] S. Umeyama, "Least-squares estimation of transformation parameters between two
       point patterns", IEEE TPAMI 13(4) (1991).

    Examples
    --------
    >>> import numpy as np
    >>> layout = {"2.1": np.array([0.0, 0.1]), "3.5": np.array([0.03, 0.0]), "3.6": np.array([-0.03, 0.0])}
    >>> known = {i: 1000 * p + [400, 300] for i, p in layout.items()}
    >>> fit = fit_view(layout, known, (800, 600))
    >>> round(fit.scale, 6), round(fit.rms_px, 9)
    (1000.0, 0.0)
    """
    from skimage.transform import SimilarityTransform

    ids = [i for i in known if i in layout]
    if len(ids) >= 2:
        src = np.array([layout[i] for i in ids])
        dst = np.array([known[i] for i in ids], dtype=np.float64)
        best = None
        for flip in ((1.0, -1.0) if reflect else (1.0,)):
            f = np.diag([flip, 1.0])
            t = SimilarityTransform.from_estimate(src @ f, dst)
            if not t:  # degenerate (all points at one place)
                continue
            m = t.params[:2, :2] @ f
            off = t.params[:2, 2]
            rms = float(np.sqrt(np.mean(np.sum((src @ m.T + off - dst) ** 2, axis=1))))
            if best is None or rms < best.rms_px:
                best = ViewFit(m, off, rms, len(ids))
        if best is not None and best.scale > 0:
            return best
    fit = _framing(layout, size)
    if ids:
        fit.offset = fit.offset + np.asarray(known[ids[0]], dtype=np.float64) - fit(layout[ids[0]])[0]
        fit.rms_px, fit.known = 0.0, 1
    return fit


def complete_views(views: Mapping[str, ViewAnnotation], sizes: Mapping[str, tuple[int, int]],
                   layout: Mapping[str, Mapping[str, np.ndarray]]) -> tuple[dict[str, ViewAnnotation], dict]:
    """Place every point a photo can show but does not have, from the generic layout.

    Each photo's missing points follow the similarity fitted to its own known points
    (:func:`fit_view`). A photo with fewer than two known points borrows the other photo's
    scale and height (photos taken from the same distance and height show the head at the
    same size and level), centred across.

    Parameters
    ----------
    views : mapping of view name to ViewAnnotation
        What is known (may lack one or both views).
    sizes : mapping of view name to (width, height)
    layout : dict
        See :func:`generic_layout`.

    Returns
    -------
    views : dict of view name to ViewAnnotation
        New annotations: the known points unchanged, the placed ones added with confidence
        :data:`GUESS_CONFIDENCE`. Placed points falling outside the photo are left out.
    report : dict
        Per view: ``placed`` (ids), ``known`` (how many points the fit used), ``rms_px``,
        ``how`` (a few words on what placed them).
    """
    known = {n: dict(views[n].points) if n in views else {} for n in VIEWS}
    side = visible_side(known["side"])
    layouts = {"front": {i: layout["front"][i] for i in shown_in("front") if i in layout["front"]},
               "side": {i: layout["side"][i] for i in shown_in("side", side) if i in layout["side"]}}
    fits = {n: fit_view(layouts[n], known[n], sizes[n], reflect=(n == "side")) for n in VIEWS}
    how = {n: f"fitted to {f.known} points" if f.known >= 2 else
           "one point and the image size" if f.known else "the image centre and size" for n, f in fits.items()}
    # A photo with too little of its own borrows the other's scale and height.
    for n, other in (("front", "side"), ("side", "front")):
        if fits[n].known < 2 <= fits[other].known:
            how[n] = f"the {other} photo's scale and height" + (" and one point" if fits[n].known else "")
            w, h = sizes[n]
            ratio = h / sizes[other][1]
            o = fits[other]
            centre = o(np.zeros(2))[0]  # where the layout's origin (head centre height) sits
            fit = _framing(layouts[n], sizes[n], scale=o.scale * ratio)
            shift_y = centre[1] * ratio - fit(np.zeros(2))[0][1]
            fit.offset = fit.offset + [0.0, shift_y]
            if fits[n].known == 1:  # keep the one known point where it is, across
                i = next(i for i in known[n] if i in layouts[n])
                fit.offset = fit.offset + [known[n][i][0] - fit(layouts[n][i])[0][0], 0.0]
            fit.known = fits[n].known
            fits[n] = fit
    out, report = {}, {}
    for n in VIEWS:
        base = views.get(n) or ViewAnnotation(width=sizes[n][0], height=sizes[n][1])
        w, h = sizes[n]
        points = dict(base.points)
        confidence = dict(base.confidence)
        placed = []
        todo = [i for i in layouts[n] if i not in points]
        if todo:
            px = fits[n](np.array([layouts[n][i] for i in todo]))
            for i, p in zip(todo, px):
                if -0.5 <= p[0] <= w - 0.5 and -0.5 <= p[1] <= h - 0.5:
                    points[i] = p
                    confidence[i] = GUESS_CONFIDENCE
                    placed.append(i)
        order = {i: k for k, i in enumerate(FP_IDS)}
        out[n] = ViewAnnotation(image=base.image, width=w, height=h,
                                points=dict(sorted(points.items(), key=lambda kv: order[kv[0]])),
                                confidence=dict(sorted(confidence.items(), key=lambda kv: order[kv[0]])))
        report[n] = {"placed": placed, "known": fits[n].known, "rms_px": fits[n].rms_px, "how": how[n]}
    return out, report


@dataclass
class Initialisation:
    """The annotation the tool starts from and where it came from.

    Attributes
    ----------
    fdp : FdpFile
        With ``front`` and ``side`` views (pixels of the given photos).
    source : {"file", "landmarks", "generic"}
    message : str
        One sentence for the page: what placed the points.
    """

    fdp: FdpFile
    source: str
    message: str
    report: dict = field(default_factory=dict)


def _detect_checked(detect: Callable, front, side) -> FdpFile:
    """``detect(front, side)``; when the side photo's facing is too unsure for ``recon build``
    to take, detection again with the better guess, marked unsure: the page shows the facing
    with its confidence and turns the points round at a key (:mod:`recon.annotate.turn`)."""
    from recon.landmarks.facing import UnsureFacing

    try:
        return detect(os.fspath(front), os.fspath(side))
    except UnsureFacing as e:
        found = detect(os.fspath(front), os.fspath(side), side_facing=e.found.facing)
        meta = found.metadata.setdefault("landmarks", {})
        meta["side_facing"] = {**e.found.record(), "given": False, "unsure": True}
        meta.setdefault("warnings", []).append(
            f"the side photo's facing is unsure ({e.found.describe()}): check that the nose points "
            f"{e.found.facing}, else turn the side photo's points round (T)")
        return found


def initial_annotation(front: str | os.PathLike, side: str | os.PathLike, fdp_path: str | os.PathLike | None = None,
                       detect: Callable | None | bool = True, layout: Mapping | None = None,
                       sizes: Mapping[str, tuple[int, int]] | None = None) -> Initialisation:
    """The annotation :func:`recon.annotate.annotate` opens with (see the module docstring).

    Parameters
    ----------
    front, side : path
        The photos.
    fdp_path : path, optional
        The annotation file; used when it exists.
    detect : callable, True or False
        ``detect(front, side) -> FdpFile``; True looks for :func:`recon.landmarks.detect`,
        False skips detection.
    layout : dict, optional
        :func:`generic_layout`, when the caller has it already.
    sizes : dict, optional
        ``front`` and ``side`` (width, height), when the caller has read them already.

    Returns
    -------
    Initialisation
    """
    from recon.shape.fit import attach_photo_sizes
    from recon.photos import photo_size

    if sizes is None:
        sizes = {"front": photo_size(front, "front photo"), "side": photo_size(side, "side photo")}
    photos = {"front": os.fspath(front), "side": os.fspath(side)}
    if fdp_path is not None and os.path.exists(fdp_path):
        fdp = read_fdp_json(fdp_path)
        for n in VIEWS:
            fdp.views.setdefault(n, ViewAnnotation())
        attach_photo_sizes(fdp, sizes, os.fspath(fdp_path), photos)
        counts = ", ".join(f"{len(fdp.views[n].points)} on the {n} photo" for n in VIEWS)
        return Initialisation(fdp, "file", f"Points loaded from {os.path.basename(fdp_path)} ({counts}).")
    why = None
    if detect is True:
        detect, why = detector()
    elif detect is False:
        detect, why = None, "automatic detection was not asked for"
    found = None
    if detect is not None:
        try:
            found = _detect_checked(detect, front, side)
            if not isinstance(found, FdpFile):
                raise TypeError(f"detect returned {type(found).__name__}, not an FdpFile")
            attach_photo_sizes(found, sizes, "automatic detection", photos)
        except Exception as e:  # detection is a help, not a requirement: keep the tool usable
            what = str(e) if isinstance(e, InputError) else f"{e.__class__.__name__}: {e}"
            why = f"automatic detection failed ({what})"
            # One line, as every other message: the page says the same and shows the points.
            print(f"recon: {why}; the points start from the generic head", file=sys.stderr)
            found = None
    layout = generic_layout() if layout is None else layout
    given = found.views if found is not None else {}
    views, report = complete_views(given, sizes, layout)
    fdp = found if found is not None else FdpFile()
    fdp.views = views
    if found is not None:
        extra = sum(len(r["placed"]) for r in report.values())
        msg = "Points placed by automatic detection (recon.landmarks)"
        msg += f"; {extra} it did not give were placed from the generic head." if extra else "."
        return Initialisation(fdp, "landmarks", msg, report)
    how = "; ".join(f"{n}: {report[n]['how']}" for n in VIEWS)
    msg = (f"Points placed from the generic head ({how}): {why}. Drag a few points to the face "
           "(pupils, nose tip, chin, an ear), then press G to bring the rest.")
    return Initialisation(fdp, "generic", msg, report)
