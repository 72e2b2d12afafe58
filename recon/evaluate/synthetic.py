"""Synthetic photo pairs with known feature points, from ICT FaceKit identities.

A person here is an ICT FaceKit identity (the model mean plus standard-normal identity
modes, fixed seed) on the generic head's topology, with a skin painted by this module:
a skin tone with blotches and blush, lips, eyebrows, a lash line, short scalp hair and an
iris colour, all seeded and laid out on the neutral head so that they follow the anatomy
of every identity. :func:`photograph` renders it through a pinhole or orthographic camera;
:func:`synthetic_pair` gives a front and a side photo with the feature points' true pixels,
which is the embedded example (``scripts/make_example_photos.py``) and the ground truth of
the texture, landmark and batch tests and benchmarks.

The ICT FaceKit (MIT, USC Institute for Creative Technologies) is read from
``../shared/data/ict_facekit/ict_facekit.npz`` beside the project unless a path is given.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mpeg4.camera import Camera, look_rotation
from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.head import Head
from mpeg4.io.fdp_json import FdpFile, ViewAnnotation
from mpeg4.render import RenderMesh, render

from .ict import default_ict_path, identity_head, identity_vertices, load_ict
from .dressing import Look, background_image, dress, fitzpatrick_rgb, hair_top, hard_look
from .paint import Person, make_person, skin_albedo

__all__ = ["PHOTO_LIGHT", "PHOTO_AMBIENT", "skin_albedo", "default_ict_path", "load_ict", "identity_vertices",
           "identity_head", "Person", "make_person", "photograph", "photo_labels", "LABELS", "PhotoPair",
           "synthetic_pair", "hard_pair", "Look", "view_camera",
           "visible_points", "perfect_detector", "CONVENTIONS", "MeshFile", "remeshed_identity"]

#: The light of :func:`photograph`: the direction towards the key light in the camera's
#: frame (it moves with the camera), and the ambient share (see :func:`mpeg4.render.render`).
PHOTO_LIGHT = (-0.35, 0.45, 1.0)
PHOTO_AMBIENT = 0.42


def view_camera(view: str, target: np.ndarray, width: int, height: int, focal_px: float | None = None,
                distance: float = 1.5, scale_px: float | None = None) -> Camera:
    """A camera looking at ``target`` from the front (+z) or the face's left (+x).

    Parameters
    ----------
    view : {"front", "side"}
    target : (3,) float
        Point on the optical axis, metres.
    width, height : int
    focal_px : float, optional
        Pinhole focal length in pixels; orthographic (``scale_px``) when None.
    distance : float
        Metres from the target (pinhole).
    scale_px : float, optional
        Pixels per metre (orthographic).
    """
    yaw = {"front": 0.0, "side": 90.0}[view]
    rot = look_rotation(yaw)
    centre = np.asarray(target, float) + rot[2] * distance
    if focal_px is None:
        return Camera(width, height, rot, centre, scale_px=scale_px or 3000.0)
    return Camera(width, height, rot, centre, focal_px=focal_px)


def photograph(person: Person, camera: Camera, background=(0.86, 0.87, 0.89)) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) uint8 photo of a person and the (H, W) bool mask of the person in it.

    ``background``: an RGB colour in [0, 1] (a studio wall that darkens a little towards the
    bottom), or an (H, W, 3) uint8 image (:func:`recon.evaluate.dressing.background_image`)
    behind the person, blended along the antialiased edges.
    """
    if isinstance(background, np.ndarray) and background.ndim == 3:
        meshes = person.meshes()
        black, depth = render(meshes, camera, background=(0.0, 0.0, 0.0), return_depth=True, samples=8,
                              ambient=PHOTO_AMBIENT, light=PHOTO_LIGHT)
        white = render(meshes, camera, background=(1.0, 1.0, 1.0), samples=8, ambient=PHOTO_AMBIENT,
                       light=PHOTO_LIGHT)
        # The two renders differ only where the background shows: by its share times 255.
        clear = (white.astype(np.float32) - black).mean(axis=2, keepdims=True) / 255.0
        img = black + np.clip(clear, 0, 1) * background.astype(np.float32)
        return np.clip(np.round(img), 0, 255).astype(np.uint8), np.isfinite(depth)
    img, depth = render(person.meshes(), camera, background=background, return_depth=True, samples=8,
                        ambient=PHOTO_AMBIENT, light=PHOTO_LIGHT)
    mask = np.isfinite(depth)
    h = img.shape[0]
    shade = np.linspace(1.02, 0.9, h)[:, None, None]
    bg = np.clip(np.asarray(background) * 255 * shade, 0, 255)
    # Antialiased edges keep the renderer's blend with the flat background; elsewhere the gradient.
    flat = np.all(img == np.round(np.asarray(background) * 255).astype(np.uint8), axis=2) & ~mask
    img = img.copy()
    img[flat] = np.broadcast_to(bg, img.shape)[flat].astype(np.uint8)
    return img, mask


#: What :func:`photo_labels` marks each pixel as.
LABELS = {"background": 0, "head": 1, "hair": 2, "clothes": 3, "glasses": 4}


def photo_labels(person: Person, camera: Camera) -> np.ndarray:
    """(H, W) uint8: what each pixel of the person's photo shows (:data:`LABELS`): the head
    (skin, eyes, mouth), hair with volume, clothes, glasses or the background."""
    step = 40  # codes drawn as grey levels far apart, read back by rounding
    flat = [RenderMesh(m.vertices, m.triangles, colour=(LABELS["head"] * step / 255.0,) * 3)
            for m in person.meshes()[:len(person.meshes()) - len(person.dress)]]
    flat += [RenderMesh(m.vertices, m.triangles, colour=(LABELS[kind] * step / 255.0,) * 3) for kind, m in person.dress]
    img = render(flat, camera, background=(0.0, 0.0, 0.0), samples=0, ambient=1.0, light=PHOTO_LIGHT)
    return np.clip(np.round(img[..., 0] / step), 0, max(LABELS.values())).astype(np.uint8)


def visible_points(head: Head, view: str) -> list[str]:
    """FP ids a person would mark on a front or a left-side photo (the catalogue's views)."""
    out = []
    for i, fp in FEATURE_POINTS.items():
        if i not in head.feature_points:
            continue
        if view == "front" and fp.front != "N":
            out.append(i)
        elif view == "side" and fp.side_view != "N" and fp.side in ("C", "L"):
            out.append(i)
    return out


@dataclass
class PhotoPair:
    """A front and a side photo of a synthetic person, with the truth about them.

    Attributes
    ----------
    person : Person
    front, side : (H, W, 3) uint8
    masks : dict of str to (H, W) bool
        Where the head is in each photo.
    cameras : dict of str to Camera
    fdp : FdpFile
        The visible feature points' true pixels in both views (image sizes set).
    look : Look or None
        How the person is dressed and photographed (None: the clean set).
    labels : dict of str to (H, W) uint8, or None
        With a look, what each pixel shows (:func:`photo_labels`).
    """

    person: Person
    front: np.ndarray
    side: np.ndarray
    masks: dict[str, np.ndarray]
    cameras: dict[str, Camera]
    fdp: FdpFile
    look: Look | None = None
    labels: dict[str, np.ndarray] | None = None

    @property
    def focal_px(self) -> float | None:
        return self.cameras["front"].focal_px


def synthetic_pair(seed: int, size: tuple[int, int] = (1024, 1280), focal_mm: float | None = 100.0,
                   distance: float = 1.8, data: dict | None = None, texture_size: int = 1024,
                   look: Look | None = None, expression: Mapping[str, float] | None = None) -> PhotoPair:
    """A front and a side (left profile) photo of the person drawn from ``seed``.

    Parameters
    ----------
    seed : int
    size : (width, height)
        Photo size in pixels.
    focal_mm : float or None
        Lens focal length on a 24 mm-high sensor (pinhole); orthographic when None, with
        the same scale at the target.
    distance : float
        Camera to head, metres.
    data : dict, optional
        The ICT FaceKit arrays (:func:`load_ict`).
    texture_size : int
        Resolution of the painted skin tiles.
    look : Look, optional
        Hair volume, skin type, clothes, glasses and background
        (:mod:`recon.evaluate.dressing`); the truth of 11.5 (the top of the hair) then lies
        on the hair. None: the clean set (painted hair, a plain wall).
    expression : mapping of str to float, optional
        ICT expression name → weight, the person's pose in both photos (e.g. lids half
        closed: ``{"eyeBlink_L": 0.5, "eyeBlink_R": 0.5}``); the truth is the posed head.
    """
    skin_rgb = None
    if look is not None and look.skin_type is not None:
        skin_rgb = fitzpatrick_rgb(look.skin_type) * np.random.default_rng(40_000 + seed).uniform(0.97, 1.03, 3)
    person = make_person(seed, data, texture_size=texture_size, skin_rgb=skin_rgb, expression=expression)
    if look is not None:
        dress(person, look)
    head = person.head
    w, h = size
    f = None if focal_mm is None else h * focal_mm / 24.0
    lo, hi = head.bounds
    # Aim at the middle of the head's box: the front camera on the midline, the side camera
    # at the middle of the head's depth (nose to the back of the skull).
    y_mid = 0.5 * (head.fp_position("11.4")[1] + lo[1])
    z_mid = 0.5 * (head.fp_position("9.3")[2] + head.fp_position("11.6")[2])
    targets = {"front": np.array([0.0, y_mid, z_mid]), "side": np.array([0.0, y_mid, z_mid])}
    scale = None if f is not None else h * 100.0 / 24.0 / distance
    fdp = FdpFile(metadata={"synthetic": {"seed": seed, "focal_px": f, "ipd_mm": round(person.ipd_mm, 4)}})
    photos, masks, cams, labels = {}, {}, {}, {}
    truth = {i: head.fp_position(i) for i in head.feature_points}
    if look is not None:
        truth["11.5"] = hair_top(person)
        fdp.metadata["synthetic"]["look"] = look.name
    for k, view in enumerate(("front", "side")):
        cam = view_camera(view, targets[view], w, h, focal_px=f, distance=distance, scale_px=scale)
        if look is None:
            img, mask = photograph(person, cam)
        else:
            img, mask = photograph(person, cam, background_image(look.background, w, h, 2 * seed + k))
            labels[view] = photo_labels(person, cam)
        ids = visible_points(head, view)
        px = cam.project(np.array([truth[i] for i in ids]))
        fdp.views[view] = ViewAnnotation(image=None, width=w, height=h,
                                         points={i: p for i, p in zip(ids, px)})
        photos[view], masks[view], cams[view] = img, mask, cam
    return PhotoPair(person, photos["front"], photos["side"], masks, cams, fdp, look, labels or None)


def hard_pair(seed: int, **kwargs) -> PhotoPair:
    """:func:`synthetic_pair` of the harder set: the person dressed by
    :func:`recon.evaluate.dressing.hard_look` (hair volume, a Fitzpatrick skin type, clothes,
    sometimes glasses, a busy background)."""
    return synthetic_pair(seed, look=hard_look(seed), **kwargs)


def perfect_detector(points: dict[str, np.ndarray], name: str = "perfect 2D detector"):
    """A stand-in for a 2D landmark detector on renders of a mesh whose true points are known.

    Parameters
    ----------
    points : dict of str to (3,) float
        The mesh's true feature points in the mesh file's own coordinates.
    name : str

    Returns
    -------
    callable
        ``detect(views) -> FdpFile`` for :func:`recon.mark.mark`: each point the
        catalogue says a front or a left-side photo shows, at the pixel where the renders'
        cameras see it (confidence 1). It reports what a perfect detector would, so that
        everything after detection can be measured on its own.
    """
    from mpeg4.catalogue import FEATURE_POINTS as FPS

    ids = list(points)
    file_pts = np.array([points[i] for i in ids], dtype=np.float64).reshape(-1, 3)

    def detect(views) -> FdpFile:
        m = views.frame
        world = file_pts @ m[:3, :3].T + m[:3, 3]
        fdp = FdpFile()
        for view in ("front", "side"):
            cam = views.cameras[view]
            px = cam.project(world)
            shown = (lambda fp: fp.front != "N") if view == "front" else \
                (lambda fp: fp.side_view != "N" and fp.side in ("C", "L"))
            keep = [k for k, i in enumerate(ids) if shown(FPS[i])
                    and -0.5 <= px[k, 0] <= cam.width - 0.5 and -0.5 <= px[k, 1] <= cam.height - 0.5]
            fdp.views[view] = ViewAnnotation(width=cam.width, height=cam.height,
                                             points={ids[k]: px[k] for k in keep},
                                             confidence={ids[k]: 1.0 for k in keep})
        return fdp

    detect.__name__ = name
    return detect


#: Axis conventions of mesh files in the wild: (up, forward) in the file's axes.
CONVENTIONS = (("+y", "+z"), ("+z", "-y"), ("+z", "+y"), ("+y", "-z"))


@dataclass
class MeshFile:
    """A re-meshed ICT identity written as a mesh from elsewhere, with the truth about it.

    Attributes
    ----------
    path : Path
    points : dict of str to (3,) float64
        True feature points (on the identity's original surface) in the file's coordinates.
    to_file : (4, 4) float64
        The similarity taking the identity's neutral frame (metres) to the file's coordinates.
    unit, up, forward : str
    tilt_deg : float
        Rotation applied on top of the axis convention, degrees.
    faces : int
        Triangles in the file (all parts).
    """

    path: Path
    points: dict
    to_file: np.ndarray
    unit: str
    up: str
    forward: str
    tilt_deg: float
    faces: int


def remeshed_identity(seed: int, folder, data: dict | None = None, fmt: str | None = None,
                      max_tilt_deg: float = 10.0, generic: Head | None = None) -> MeshFile:
    """An ICT identity as a user's head mesh would come: coarser and re-meshed, tilted, in
    another unit and axis convention, parts unnamed or merged.

    Each part is decimated by quadric edge collapse (fast-simplification, as trimesh calls
    it) to a random 25–55 % of its triangles, so that no vertex id or position of the
    original survives; then rotated by up to ``max_tilt_deg`` about a random axis, turned
    to a random convention of :data:`CONVENTIONS`, scaled to a random unit (m, cm, mm) and
    moved. ``fmt``: ``"ply"`` (all parts merged into one mesh), ``"obj"`` (one group per
    part, named ``mesh0``..., shuffled) or ``"glb"`` (likewise); by the seed when None.
    """
    import trimesh

    from mpeg4.catalogue import FEATURE_POINTS as FPS

    data = load_ict() if data is None else data
    head = identity_head(data, seed, generic)
    rng = np.random.default_rng(50_000 + seed)
    fmt = fmt or ("ply", "obj", "glb")[seed % 3]
    meshes = []
    for name, part in head.parts.items():
        ratio = rng.uniform(0.25, 0.55)
        m = trimesh.Trimesh(part.vertices, part.triangles, process=False)
        d = m.simplify_quadric_decimation(percent=1 - ratio, aggression=int(rng.integers(3, 8)))
        perm = rng.permutation(len(d.vertices))  # vertex order unrelated to the original's
        inv = np.argsort(perm)
        meshes.append(trimesh.Trimesh(d.vertices[perm], inv[d.faces], process=False))
    axis = rng.normal(size=3)
    tilt = float(rng.uniform(0, max_tilt_deg))
    from scipy.spatial.transform import Rotation

    r_tilt = Rotation.from_rotvec(np.radians(tilt) * axis / np.linalg.norm(axis)).as_matrix()
    up, forward = CONVENTIONS[int(rng.integers(len(CONVENTIONS)))]
    u = np.array({"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1),
                  "-z": (0, 0, -1)}[up], float)
    f = np.array({"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1),
                  "-z": (0, 0, -1)}[forward], float)
    conv = np.stack([np.cross(u, f), u, f]).T  # neutral (left, up, forward) -> file axes
    unit = ("m", "cm", "mm")[int(rng.integers(3))]
    scale = {"m": 1.0, "cm": 100.0, "mm": 1000.0}[unit]
    m = np.eye(4)
    m[:3, :3] = scale * conv @ r_tilt
    m[:3, 3] = rng.normal(0, 0.2, 3) * scale
    for mesh in meshes:
        mesh.vertices = mesh.vertices @ m[:3, :3].T + m[:3, 3]
    truth = {i: p @ m[:3, :3].T + m[:3, 3] for i, p in head.fp_positions().items() if i in FPS}
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"identity_{seed}.{fmt}"
    order = rng.permutation(len(meshes))
    if fmt == "ply":
        trimesh.util.concatenate([meshes[k] for k in order]).export(path)
    elif fmt == "obj":
        lines, offset = [], 0
        for j, k in enumerate(order):
            lines.append(f"o mesh{j}")
            lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in meshes[k].vertices]
            lines += [f"f {a} {b} {c}" for a, b, c in meshes[k].faces + offset + 1]
            offset += len(meshes[k].vertices)
        path.write_text("\n".join(lines) + "\n")
    else:
        scene = trimesh.Scene()
        for j, k in enumerate(order):
            scene.add_geometry(meshes[k], geom_name=f"mesh{j}", node_name=f"mesh{j}")
        path.write_bytes(scene.export(file_type="glb"))
    return MeshFile(path, truth, m, unit, up, forward, tilt, int(sum(len(x.faces) for x in meshes)))
