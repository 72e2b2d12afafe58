"""The learned models behind the automatic feature points: MediaPipe's face mesh and
selfie segmentation, run offline from the models inside the ``mediapipe`` wheel.

The face mesh [1]_ gives 468 surface landmarks of a face seen roughly from the front, plus
10 iris landmarks [2]_ (centre and four rim points per eye); the selfie segmentation gives a
person/background probability per pixel. Both run on the CPU in tens of milliseconds.

``mediapipe`` 0.10.14 to 0.10.21 carry these models in their wheel (later releases fetch
them from the internet, which this tool never does). It is installed by ``install.sh``
without its declared dependencies (see the project README): the two graphs used here need
none of jax, the GUI OpenCV or sounddevice, and give the same numbers with NumPy 1.26 and 2.x.

References
----------
.. [1] Y. Kartynnik, A. Ablavatski, I. Grishchenko, M. Grundmann, "Real-time facial surface
   geometry from monocular video on mobile GPUs", CVPR Workshops (2019).
.. [2] A. Ablavatski, A. Vakunov, I. Grishchenko, K. Raveendran, M. Zhdanovich, "Real-time
   pupil tracking from monocular video for digital puppetry", CVPR Workshops (2020).
"""

from __future__ import annotations

import functools
import os
import threading

import numpy as np

__all__ = ["MEDIAPIPE_VERSIONS", "MediapipeMissing", "mediapipe_available", "face_landmarks", "face_keypoints",
           "person_mask", "N_LANDMARKS"]

#: mediapipe releases whose wheel carries the face mesh, iris and segmentation models.
MEDIAPIPE_VERSIONS = ("0.10.14", "0.10.21")
#: Face mesh landmarks with the iris refinement: 468 surface points, then 468–472 and
#: 473–477 (centre first) for the irises.
N_LANDMARKS = 478

# A solution object is a running graph: not safe to share between threads.
_lock = threading.Lock()


class MediapipeMissing(ImportError):
    """``mediapipe`` is not installed (or is a release without the bundled models)."""


def _fix() -> str:
    return ('run "bash install.sh", or: pip install --no-deps "mediapipe==0.10.21" '
            'absl-py attrs flatbuffers "protobuf>=4.25.3,<5" matplotlib')


@functools.lru_cache(maxsize=1)
def _mediapipe():
    os.environ.setdefault("GLOG_minloglevel", "2")  # the graphs' start-up chatter
    try:
        import mediapipe as mp
    except ImportError as e:
        raise MediapipeMissing(f"automatic feature points need mediapipe ({e}); {_fix()}") from None
    if not hasattr(mp, "solutions") or not hasattr(mp.solutions, "face_mesh"):
        raise MediapipeMissing(f"mediapipe {getattr(mp, '__version__', '?')} has no bundled face mesh; "
                               f"install one of {', '.join(MEDIAPIPE_VERSIONS)}: {_fix()}")
    return mp


def mediapipe_available() -> bool:
    """True when :func:`face_landmarks` can run."""
    try:
        _mediapipe()
    except MediapipeMissing:
        return False
    return True


@functools.lru_cache(maxsize=1)
def _face_mesh():
    return _mediapipe().solutions.face_mesh.FaceMesh(static_image_mode=True, refine_landmarks=True,
                                                     max_num_faces=2, min_detection_confidence=0.5)


@functools.lru_cache(maxsize=1)
def _face_detector():
    # The full-range model: it also finds faces turned to a profile, with both ear tragions.
    return _mediapipe().solutions.face_detection.FaceDetection(model_selection=1, min_detection_confidence=0.3)


@functools.lru_cache(maxsize=1)
def _segmenter():
    return _mediapipe().solutions.selfie_segmentation.SelfieSegmentation(model_selection=0)


def _rgb(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {image.shape} {image.dtype}")
    return np.ascontiguousarray(image)


def face_landmarks(image: np.ndarray) -> list[np.ndarray]:
    """The faces the face mesh finds, largest first.

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo.

    Returns
    -------
    list of (478, 3) float64
        Per face: x, y in pixels (x right, y down, the top-left pixel's centre at 0.5 - 0.5
        = 0) and z, a relative depth in the same pixel scale (smaller is nearer the
        camera, 0 at the face's centre). Empty when no face is found.
    """
    image = _rgb(image)
    h, w = image.shape[:2]
    with _lock:
        result = _face_mesh().process(image)
    faces = []
    for face in result.multi_face_landmarks or ():
        lm = np.array([(p.x, p.y, p.z) for p in face.landmark], dtype=np.float64)
        # MediaPipe's normalised coordinates put the image's left edge at 0: pixel centres
        # are half a pixel in.
        faces.append(np.c_[lm[:, 0] * w - 0.5, lm[:, 1] * h - 0.5, lm[:, 2] * w])
    faces.sort(key=lambda f: -np.ptp(f[:, 0]) * np.ptp(f[:, 1]))
    return faces


def face_keypoints(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The most confident face of MediaPipe's face detector (BlazeFace, full range).

    Parameters
    ----------
    image : (H, W, 3) uint8
        RGB photo.

    Returns
    -------
    keypoints : (6, 2) float64
        Pixels (x right, y down) of the right eye, left eye, nose tip, mouth centre, right
        ear tragion and left ear tragion (the face's own sides).
    box : (4,) float64
        x, y, width, height of the face, pixels.
    score : float
        The detector's confidence in [0, 1].

    None when no face is found.
    """
    image = _rgb(image)
    h, w = image.shape[:2]
    with _lock:
        result = _face_detector().process(image)
    if not result.detections:
        return None
    best = max(result.detections, key=lambda d: d.score[0])
    loc = best.location_data
    kp = np.array([(k.x * w - 0.5, k.y * h - 0.5) for k in loc.relative_keypoints], dtype=np.float64)
    b = loc.relative_bounding_box
    return kp, np.array([b.xmin * w, b.ymin * h, b.width * w, b.height * h]), float(best.score[0])


def person_mask(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 in [0, 1]: the selfie segmentation's probability of the person."""
    image = _rgb(image)
    with _lock:
        mask = _segmenter().process(image).segmentation_mask
    return np.clip(np.asarray(mask, dtype=np.float32), 0.0, 1.0)
