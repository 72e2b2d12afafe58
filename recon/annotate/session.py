"""One annotation session: two photos, one ``fdp.json``, and what the page asks of them.

The web server (:mod:`recon.annotate.server`) only translates HTTP to these methods; all
file handling is here, and it touches three files: the two photos (read) and the
annotation file (read and written), plus that file's backup.

Saving never loses the user's last good file: the new content is validated first
(:func:`mpeg4.io.fdp_json.validate_fdp`) and written atomically; a file that is not this
session's own work (there before the session started, or changed on disk by someone else
and overwritten on the user's say-so) is first copied to ``F.fdp.json.bak``, with the
file's own permissions. A file changed on disk since the session last read or wrote it is
not overwritten unless the user says so, and that holds between processes too: the check
and the write happen under an exclusive lock (``fcntl``) on ``.F.fdp.json.lock`` beside the
file, so of two ``recon annotate`` saving one file at the same moment, the second is told
of the first's save as a conflict.

The photos are opened once, when the session starts, and served from those open files: a
photo renamed or replaced by a link to another file afterwards changes nothing.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import io
import os
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS
from mpeg4.errors import InputError
from mpeg4.io.atomic import atomic_write
from mpeg4.io.fdp_json import FORMAT, FdpFile, ViewAnnotation, parse_fdp, write_fdp_json

from .placement import GUESS_CONFIDENCE, VIEWS, complete_views, generic_layout, initial_annotation, shown_in

__all__ = ["LOW_CONFIDENCE", "Photo", "SaveConflict", "AnnotationSession", "default_fdp_path"]

#: Points below this confidence are listed for checking.
LOW_CONFIDENCE = 0.5

# Formats every browser shows; anything else is sent re-encoded as PNG.
_WEB_FORMATS = {"JPEG": "image/jpeg", "PNG": "image/png", "WEBP": "image/webp", "GIF": "image/gif"}


class SaveConflict(Exception):
    """The annotation file changed on disk since this session last read or wrote it."""


@dataclass
class Photo:
    """One of the two photos, as displayed: upright by its EXIF orientation, as every stage
    of recon reads it (:mod:`recon.photos`).

    Attributes
    ----------
    view : {"front", "side"}
    path : Path
    width, height : int
        As displayed (:func:`recon.photos.photo_size`).
    media_type : str
    note : str or None
        Something the user should know about how the photo is shown.
    reencode : bool
        Sent as a PNG of the displayed pixels instead of the file itself (a rotated photo,
        or a format browsers do not show).
    """

    view: str
    path: Path
    width: int
    height: int
    media_type: str
    note: str | None = None
    reencode: bool = False
    _png: bytes | None = field(default=None, repr=False)
    _fd: int | None = field(default=None, repr=False)

    @classmethod
    def open(cls, view: str, path) -> Photo:
        from PIL import Image

        from recon.photos import photo_size

        kind = f"{view} photo"
        w, h = photo_size(path, kind)  # checks the file and says what is wrong with it
        path = Path(path).resolve()
        try:  # the link the user gave is followed once, here; none after
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0))
        except OSError as e:
            raise InputError(f"cannot open the photo ({e.strerror})", where=os.fspath(path),
                             fix="check that it is a file you can read") from None
        try:
            with Image.open(io.BytesIO(_read_all(fd))) as im:
                fmt, orientation = im.format, im.getexif().get(0x0112, 1)
        except Exception:
            os.close(fd)
            raise
        media = _WEB_FORMATS.get(fmt)
        note = None
        reencode = media is None
        if orientation not in (1, None):
            # Browsers differ in whether they turn an image drawn in SVG upright: send the
            # upright pixels themselves.
            note = f"shown upright by its EXIF orientation tag ({orientation}), as recon reads it"
            reencode = True
        return cls(view, path, w, h, "image/png" if reencode else media, note, reencode, _fd=fd)

    def content(self) -> bytes:
        """The bytes to send: the file as it was opened, or PNG bytes of its displayed
        pixels (see ``reencode``)."""
        if self._fd is None:
            raise InputError("the photo was closed", where=os.fspath(self.path))
        if not self.reencode:
            return _read_all(self._fd)
        if self._png is None:
            from PIL import Image

            from recon.photos import decode_photo

            buf = io.BytesIO()
            image = decode_photo(_read_all(self._fd), os.fspath(self.path), f"{self.view} photo")
            Image.fromarray(image).save(buf, format="PNG", compress_level=1)
            self._png = buf.getvalue()
        return self._png

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def _read_all(fd: int) -> bytes:
    """The whole of an open file, from its start (its current offset untouched)."""
    size = os.fstat(fd).st_size
    chunks, at = [], 0
    while True:
        chunk = os.pread(fd, max(size - at, 1 << 16), at)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)
        at += len(chunk)


def default_fdp_path(front) -> Path:
    """``<front photo without extension>.fdp.json`` beside the front photo."""
    front = Path(front)
    return front.with_name(front.stem + ".fdp.json")


def _hash(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except FileNotFoundError:
        return None


def lock_path(fdp_path: Path) -> Path:
    """The lock file beside an annotation file: ``.F.fdp.json.lock``."""
    return fdp_path.with_name("." + fdp_path.name + ".lock")


@contextlib.contextmanager
def file_lock(fdp_path: Path, exclusive: bool = True):
    """Hold an ``fcntl`` lock on the annotation file's lock file: exclusive to check and
    write, shared to read. Every ``recon annotate`` process takes it, so a check and the
    write after it are one step for all of them. Where the lock file cannot be made (a
    folder only readable), a read goes on unlocked; a write fails there anyway."""
    try:
        fd = os.open(lock_path(fdp_path), os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o600)
    except OSError as e:
        if exclusive:
            raise InputError(f"cannot write beside the annotation file ({e.strerror})", where=fdp_path,
                             fix="give --fdp a path in a folder you can write to") from None
        yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _write_file(session, fdp: FdpFile, force: bool) -> str | None:
    """Write ``fdp`` to ``session.fdp_path`` as both sessions save (the caller holds its
    thread lock; this takes the file lock every process takes).

    Refuses (:class:`SaveConflict`) a file changed on disk since the session read or wrote
    it, unless ``force``; keeps what was there before as ``.bak`` (with the file's own
    permissions) when it was not this session's own last write; writes atomically. Returns
    the backup's path, or None.
    """
    with file_lock(session.fdp_path):
        on_disk = _hash(session.fdp_path)
        if on_disk is not None and on_disk != session._disk and not force:
            raise SaveConflict(f"{session.fdp_path} changed on disk since this page loaded it")
        backup = None
        if on_disk is not None and (session._foreign or on_disk != session._disk):
            mode = session.fdp_path.stat().st_mode
            with atomic_write(session.backup_path, "wb", permissions=mode) as f:
                f.write(session.fdp_path.read_bytes())
            backup = os.fspath(session.backup_path)
        try:
            write_fdp_json(session.fdp_path, fdp)
        except OSError as e:
            raise InputError(f"cannot write the annotation file ({e.strerror})", where=session.fdp_path,
                             fix="give --fdp a path in a folder you can write to") from None
        session._foreign = False
        session._disk = _hash(session.fdp_path)
        session.saved_at = session.fdp_path.stat().st_mtime
    return backup


def _colour(rgb) -> str:
    return "#" + "".join(f"{c:02x}" for c in rgb)


class AnnotationSession:
    """Two photos and their annotation file.

    Parameters
    ----------
    front, side : path
        The photos.
    fdp_path : path, optional
        The annotation file, read when it exists and written on save;
        :func:`default_fdp_path` when None.
    detect : callable or bool
        Passed to :func:`recon.annotate.placement.initial_annotation`.
    ipd_mm, focal_px : float, optional
        For the 3D preview's fit (see :func:`recon.shape.fit.fit_head`); without ``focal_px``,
        the focal length the photos record in their EXIF, if any (:attr:`camera_note`
        says which).
    background : bool
        Place the first points by automatic detection in a thread, so that the page can
        load meanwhile (:meth:`wait_ready`; every method that needs the points waits for
        them). A file that exists is still read at once.
    """

    def __init__(self, front, side, fdp_path=None, detect=True, ipd_mm: float | None = None,
                 focal_px: float | None = None, background: bool = False):
        self.photos = {"front": Photo.open("front", front), "side": Photo.open("side", side)}
        self.fdp_path = Path(fdp_path) if fdp_path is not None else default_fdp_path(front)
        if self.fdp_path.is_dir():
            raise InputError("expected an annotation file, found a folder", where=self.fdp_path,
                             fix="give a file name such as person.fdp.json")
        self._layout = None
        self._detect = detect
        self._lock = threading.Lock()
        self._ready = threading.Event()
        self._failure: BaseException | None = None
        sizes = {n: (p.width, p.height) for n, p in self.photos.items()}
        if background and detect and not self.fdp_path.exists():
            # Detection takes a second or two: the server starts and the page loads meanwhile.
            # (A user's file is read here and now, so that its errors stop the command.)
            threading.Thread(target=self._initialise, args=(front, side, detect, sizes), daemon=True,
                             name="recon-annotate-detect").start()
        else:
            self._initialise(front, side, detect, sizes)
            if self._failure is not None:
                raise self._failure
        self._disk = _hash(self.fdp_path)
        self._foreign = self._disk is not None  # on disk, and not written by this session
        self.saved_at: float | None = self.fdp_path.stat().st_mtime if self._disk else None
        self._tmp = tempfile.TemporaryDirectory(prefix="recon-annotate-")
        self.glb: bytes | None = None
        self.fits = 0
        self.camera_note = "focal length given"
        if focal_px is None:
            from recon.photos import photos_focal_px

            focal_px, self.camera_note = photos_focal_px(front, side)
        self.fit_options = {"focal_px": focal_px} | ({} if ipd_mm is None else {"ipd_mm": ipd_mm})

    def _initialise(self, front, side, detect, sizes) -> None:
        try:
            init = initial_annotation(front, side, self.fdp_path, detect=detect, sizes=sizes)
            self.initialisation = init
            self._base = init.fdp  # what the file holds besides the views; kept on save
            self.views: dict[str, ViewAnnotation] = {n: init.fdp.views[n] for n in VIEWS}
        except BaseException as e:  # kept for whoever asks for the points
            self._failure = e
        finally:
            self._ready.set()

    def wait_ready(self, timeout: float | None = None) -> None:
        """Wait until the first points are placed (see ``background``); raises what placing
        them raised."""
        if not self._ready.wait(timeout):
            raise TimeoutError("the first points are still being placed")
        if self._failure is not None:
            raise self._failure

    # --- what the page needs ------------------------------------------------------
    def state(self) -> dict:
        """Everything the page starts from (JSON-ready)."""
        self.wait_ready()
        from mpeg4.preview import GROUP_COLOURS

        return {
            "photos": {n: {"name": p.path.name, "width": p.width, "height": p.height, "note": p.note}
                       for n, p in self.photos.items()},
            "file": {"path": os.fspath(self.fdp_path), "name": self.fdp_path.name,
                     "exists": self._disk is not None, "saved_at": self.saved_at,
                     "backup": os.fspath(self.backup_path)},
            "views": self.views_json(self.views),
            "initialisation": {"source": self.initialisation.source, "message": self.initialisation.message,
                               "warnings": self._base.metadata.get("landmarks", {}).get("warnings", [])},
            "side_facing": self.side_facing,
            "catalogue": [{"id": i, "group": fp.group, "side": fp.side, "front": fp.front,
                           "side_view": fp.side_view, "mirror": fp.mirror, "description": fp.description}
                          for i, fp in ((i, FEATURE_POINTS[i]) for i in FP_IDS)],
            "shown": {"front": shown_in("front"), "side_L": shown_in("side", "L"), "side_R": shown_in("side", "R")},
            "colours": {str(g): _colour(c) for g, c in GROUP_COLOURS.items()},
            "low_confidence": LOW_CONFIDENCE,
        }

    @property
    def backup_path(self) -> Path:
        return self.fdp_path.with_name(self.fdp_path.name + ".bak")

    @staticmethod
    def views_json(views: dict[str, ViewAnnotation]) -> dict:
        return {n: {"points": {i: [float(c) for c in p] for i, p in v.points.items()},
                    "confidence": {i: float(c) for i, c in v.confidence.items()}}
                for n, v in views.items()}

    def parse_views(self, data) -> dict[str, ViewAnnotation]:
        """The two views from the page's JSON, checked like a file (raises InputError).

        ``data`` is ``{"front": {"points": {...}, "confidence": {...}}, "side": {...}}``;
        the image names and sizes are the session's, whatever the page sends.
        """
        where = "the page's points"
        if not isinstance(data, dict) or set(data) - set(VIEWS):
            raise InputError(f"expected an object with 'front' and 'side', found "
                             f"{sorted(data) if isinstance(data, dict) else type(data).__name__}", where=where,
                             fix="send {\"front\": {\"points\": {...}}, \"side\": {\"points\": {...}}}")
        views = {}
        for n in VIEWS:
            v = data.get(n) or {"points": {}}
            if not isinstance(v, dict) or set(v) - {"points", "confidence"}:
                raise InputError(f"view '{n}' must be an object with 'points' and optionally 'confidence'",
                                 where=f"{where}, {n}", fix="send only points and confidence")
            views[n] = {"image": self._image_name(n), "width": self.photos[n].width,
                        "height": self.photos[n].height, "points": v.get("points", {})}
            if v.get("confidence"):
                views[n]["confidence"] = v["confidence"]
        fdp = parse_fdp({"format": FORMAT, "version": 1, "views": views}, where=where)
        for n, v in fdp.views.items():
            extra = sorted(set(v.confidence) - set(v.points))
            if extra:
                raise InputError(f"confidence given for points that are not placed: {', '.join(extra)}",
                                 where=f"{where}, {n}.confidence", fix="drop their confidence")
        return fdp.views

    def _image_name(self, view: str) -> str:
        """The photo's path relative to the annotation file's folder (absolute if elsewhere)."""
        photo = self.photos[view].path
        folder = self.fdp_path.resolve().parent
        try:
            return os.fspath(photo.relative_to(folder))
        except ValueError:
            return os.fspath(photo)

    # --- saving and loading -------------------------------------------------------
    def save(self, data, force: bool = False) -> dict:
        """Write the page's points to the annotation file (see the module docstring).

        Raises
        ------
        InputError
            The points are not a valid annotation (nothing is written).
        SaveConflict
            The file changed on disk since this session last read or wrote it.
        """
        self.wait_ready()
        views = self.parse_views(data)
        with self._lock:
            fdp = FdpFile(views=views, points3d=self._base.points3d, bindings=self._base.bindings,
                          texcoords=self._base.texcoords, fapu=self._base.fapu,
                          metadata=dict(self._base.metadata), version=self._base.version)
            fdp.metadata["reviewed"] = True  # a person placed or checked these points on the page
            fdp.metadata["annotate"] = {"initialised_from": self.initialisation.source,
                                        "photos": {n: self._image_name(n) for n in VIEWS}}
            backup = _write_file(self, fdp, force)
            self.views = views
        return {"path": os.fspath(self.fdp_path), "saved_at": self.saved_at, "backup": backup,
                "points": {n: len(v.points) for n, v in views.items()}}

    def load(self) -> dict:
        """The views as the annotation file holds them now (it becomes the session's base).

        Raises
        ------
        FileNotFoundError
            Nothing has been saved yet.
        InputError
            The file is not a valid annotation of these photos.
        """
        self.wait_ready()
        from mpeg4.io.fdp_json import read_fdp_json
        from recon.shape.fit import attach_photo_sizes

        with self._lock, file_lock(self.fdp_path, exclusive=False):
            if not self.fdp_path.exists():
                raise FileNotFoundError(self.fdp_path)
            fdp = read_fdp_json(self.fdp_path)
            for n in VIEWS:
                fdp.views.setdefault(n, ViewAnnotation())
            attach_photo_sizes(fdp, {n: (p.width, p.height) for n, p in self.photos.items()}, os.fspath(self.fdp_path),
                               {n: p.path.name for n, p in self.photos.items()})
            self._base = fdp
            self.views = {n: fdp.views[n] for n in VIEWS}
            disk = _hash(self.fdp_path)
            self._foreign = self._foreign or disk != self._disk  # someone else's version: back it up on save
            self._disk = disk
            self.saved_at = self.fdp_path.stat().st_mtime
        return {"views": self.views_json(self.views), "saved_at": self.saved_at}

    @property
    def side_facing(self) -> dict | None:
        """Where the nose points in the side photo as detection read it (``facing``,
        ``confidence``, ``given``, ``unsure``; ``turned`` once the user turned the points round);
        None when the points did not come from detection."""
        return self._base.metadata.get("landmarks", {}).get("side_facing")

    # --- help with the points -----------------------------------------------------
    def turn(self, data) -> dict:
        """The page's points with the side photo's placed again for the other facing
        (:func:`recon.annotate.turn.turn_side`: detection told the facing, else mirrored)."""
        from .placement import detector
        from .turn import turn_side

        self.wait_ready()
        views = self.parse_views(data)
        detect = self._detect
        if detect is True:
            detect = detector()[0]
        elif not callable(detect):
            detect = None
        sizes = {n: (p.width, p.height) for n, p in self.photos.items()}
        turned, report = turn_side(views, {n: p.path for n, p in self.photos.items()}, sizes, self.layout(), detect)
        with self._lock:
            meta = self._base.metadata.setdefault("landmarks", {})
            meta["side_facing"] = {"facing": report["facing"], "turned": True, "given": True}
        return {"views": self.views_json(turned), "side_facing": self.side_facing, **report}

    def layout(self) -> dict:
        if self._layout is None:
            self._layout = generic_layout()
        return self._layout

    def complete(self, data, replace_guesses: bool = False) -> dict:
        """The page's points with every missing one placed from the generic head.

        With ``replace_guesses``, points still at :data:`GUESS_CONFIDENCE` (placed from the
        generic head, not touched since) are placed again, by the generic head fitted to
        the other points: a few points dragged into place bring the rest with them.
        """
        self.wait_ready()
        views = self.parse_views(data)
        if replace_guesses:
            for v in views.values():
                for i in [i for i, c in v.confidence.items() if c <= GUESS_CONFIDENCE]:
                    del v.points[i], v.confidence[i]
        sizes = {n: (p.width, p.height) for n, p in self.photos.items()}
        filled, report = complete_views(views, sizes, self.layout())
        return {"views": self.views_json(filled), "placed": {n: report[n]["placed"] for n in VIEWS},
                "how": {n: report[n]["how"] for n in VIEWS}}

    def fit(self, data) -> dict:
        """Fit the generic head to the page's points; the GLB is kept in :attr:`glb`.

        Returns a summary: 3D points, where each came from, height disagreements between
        the photos (mm), the camera and size assumptions, the time taken. Heights that
        disagree by more than :func:`recon.shape.fit.fit_head` accepts still give a preview, with
        the refusal as ``warning`` (the files ``recon build`` makes keep the check).
        """
        self.wait_ready()
        from mpeg4.io import save_head
        from recon.shape.fit import fit_head

        views = self.parse_views(data)
        t0 = time.perf_counter()
        warning = None
        with self._lock:
            try:
                head, cal = fit_head(FdpFile(views=views), where="the page's points", **self.fit_options)
            except InputError as e:
                if "heights of the points marked in both photos disagree" not in e.what:
                    raise
                # A preview is still worth showing: the page lists the disagreements.
                head, cal = fit_head(FdpFile(views=views), where="the page's points", height_tol_mm=float("inf"),
                                     **self.fit_options)
                warning = f"{e.what}; {e.fix}"
            # The preview shows the shape: no morph targets or tables to carry.
            head.morph_targets = {}
            head.fat = None
            path = Path(self._tmp.name) / "preview.glb"
            save_head(head, path)
            self.glb = path.read_bytes()
            self.fits += 1
        return {"glb": f"/api/head.glb?fit={self.fits}", "seconds": round(time.perf_counter() - t0, 3),
                "points3d": {i: [round(float(c), 6) for c in p] for i, p in head.fp_positions().items()},
                "sources": cal.source, "roll_deg": round(cal.roll_deg, 3), "yaw_deg": round(cal.yaw_deg, 3),
                "assumptions": cal.assumptions,
                "height_residual_mm": {i: round(float(r), 2) for i, r in cal.height_residual_mm.items()},
                "warning": warning, "bytes": len(self.glb)}

    def close(self) -> None:
        self._tmp.cleanup()
        for p in self.photos.values():
            p.close()
