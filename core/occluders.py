"""People's arms and hands in front of the object: the default occluder detector (paper 3.2.3, Fig. 5).

The paper combines a human-parsing segmentation (PGN) with DensePose's arm and hand
parts. We use the offline models shipped in the mediapipe wheel for the same roles:
selfie segmentation gives the person's silhouette, the pose landmarks give the arms
(a band around shoulder-elbow-wrist-hand, intersected with the silhouette), and the
hand detector finds hands on their own, for close-ups that show a hand but no body.
The face detector vouches for a person the pose model misses (a face in profile, a
body cut by the frame or hidden behind the object).

mediapipe is optional (scripts/setup.sh installs it): it is imported on first use,
because importing it takes about a second, and without it the detector logs a warning
and finds nothing.
"""

from __future__ import annotations

import hashlib
import itertools
import logging
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import cv2
import numpy as np

from frontal3d.masks import mask_extent

log = logging.getLogger("frontal3d")

#: Long side (px) the models see; they work at 256 px internally, more only costs time.
DETECTION_SIDE = 512
#: Selfie-segmentation probability above which a pixel belongs to a person, and above which it surely does.
PERSON_PROBABILITY = 0.5
CONFIDENT_PERSON_PROBABILITY = 0.9
#: Share of the image that must be confidently (p > 0.9) a person before the pose model
#: runs: images without people skip its cost (about 1 s to load, 20 ms a call). Hands are
#: looked for on every image, as a close-up hand is often not segmented as a person.
MIN_CONFIDENT_PERSON_SHARE = 0.002
#: Pose landmarks with at least this visibility draw arm segments.
MIN_VISIBILITY = 0.5
#: Arm band width as a fraction of the shoulder-to-shoulder distance (or of the upper arm's length).
ARM_BAND_WIDTH = 0.45
#: Hands: the landmarks' hull is grown by this fraction of the hand's size (landmarks sit on the joints).
HAND_MARGIN = 0.15

#: With neither a pose nor a face, the segmenter alone vouches for a person when it is sure of
#: pixels farther than OFF_OBJECT_REACH of the object's size from it, together at least
#: OFF_OBJECT_SHARE of the object's area. On a plain guitar it fires on the body and spills a
#: few pixels past its edge (none that far on the shared renders); a person beside or behind
#: a guitar has most of a torso there (the cameraman in profile, whom pose and face miss).
#: It is as sure of some soft blobs in cluttered backgrounds: those become people too, and
#: only count where the placed template says they hide the object (occlusion.in_front).
OFF_OBJECT_REACH = 0.05
OFF_OBJECT_SHARE = 0.1
#: ... or, less sure, when its person pixels (p > 0.5) that far off the object add up to at
#: least OFF_OBJECT_BODY_SHARE of the object's area: a whole body beside or behind it in dark
#: clothes (the cameraman behind a guitar, p 0.5-0.9 over his coat). No soft blob on the
#: procedural backgrounds reaches half the object's area at p > 0.5 without being sure of it.
OFF_OBJECT_BODY_SHARE = 0.75

#: How far (fraction of the image's long side) from a found arm or hand the person's own
#: pixels off the object are added to it.
COMPLETION_REACH = 0.04

#: How far around the face detector's box (a share of its size; twice as far up) the person's pixels
#: are taken as the head: hair, ears and chin.
HEAD_REACH = 0.3

#: mediapipe pose landmark indices: the nose; per side: shoulder, elbow, wrist, then the hand points
#: (pinky, index, thumb) attached to the wrist.
_NOSE = 0
_ARM_CHAINS = ((11, 13, 15), (12, 14, 16))
_HAND_POINTS = {15: (17, 19, 21), 16: (18, 20, 22)}
#: The last image's selfie segmentation and pose (see :func:`_person_and_pose`).
_last_inference: dict[str, Any] = {}


@dataclass
class _Models:
    segmenter: Any
    pose: Any
    hands: Any
    faces: Any = None


def detect_arms_and_hands(image: np.ndarray, object_mask: np.ndarray | None = None) -> np.ndarray | None:
    """Bool mask (image-sized) of people's arms and hands, or None if there are none.

    With the object's mask, the person's pixels next to a found arm or hand and off the
    object are added (a sleeve wider than the arm band, what the hand holds).
    None too when mediapipe is not installed (with a logged warning), so a missing
    optional dependency degrades to "no occluders", never to a crash.
    """
    models = _load_models()
    if models is None:
        return None
    with _native_logs_silenced():
        return _detect(models, image, object_mask)


def detect_people(image: np.ndarray, object_mask: np.ndarray | None = None) -> np.ndarray | None:
    """Bool mask (image-sized) of every person the selfie segmenter sees, or None if there is none.

    The segmenter alone also fires on plain objects (a guitar's body), so a person needs a
    pose, or a face that is mostly the person's pixels off ``object_mask`` (the pose
    model misses people in profile, cut by the frame or half hidden behind the object), or
    failing both a large stretch of person the segmenter is sure of well off the object
    (see OFF_OBJECT_SHARE).
    Whether a person stands in front of the object or behind it is not decided here:
    the occlusion stage keeps the pixels that reach into the aligned template (a torso
    in front of a guitar) and drops the others (a guitarist's body behind it).
    """
    return detect_people_with_evidence(image, object_mask)[0]


def detect_people_with_evidence(image: np.ndarray, object_mask: np.ndarray | None = None) -> tuple[np.ndarray | None, str | None]:
    """:func:`detect_people`'s mask and what vouched for the person: "pose", "face" or
    "segmenter" (the segmenter alone, sure of pixels off the object), None with no person.
    The segmenter alone is as sure of some soft blobs in cluttered backgrounds, so callers
    trust it less (see pipeline._people_in_front)."""
    models = _load_models()
    if models is None:
        return None, None
    small, (height, width) = _detection_image(image)
    with _native_logs_silenced():
        probability, pose_result = _person_and_pose(models, small)
        if pose_result is None:
            return None, None
        person = probability > PERSON_PROBABILITY
        if pose_result.pose_landmarks is not None:
            evidence = "pose"
        elif _face_off_object(models, small, person, object_mask):
            evidence = "face"
        elif _sure_person_off_object(probability, object_mask):
            evidence = "segmenter"
        else:
            return None, None
    return cv2.resize(person.astype(np.uint8), (width, height), interpolation=cv2.INTER_NEAREST) > 0, evidence


def person_seen(image: np.ndarray) -> bool:
    """Whether a pose or a face shows a person, before any object is found (the segmenter
    alone does not count: it fires on plain guitar bodies and soft blobs)."""
    return detect_people_with_evidence(image)[1] is not None


def detect_faces(image: np.ndarray) -> np.ndarray | None:
    """Bool mask (image-sized) of people's faces, or None if there is none.

    A face is a face detector's box that holds the pose model's nose (the detector alone also
    fires on a guitar's body), with the person's pixels around it out to HEAD_REACH of its size
    (hair, ears, chin: the box stops at the brows and the mouth). No object is ever a face, so
    the segmentation cuts these (see :func:`frontal3d.stages.segment.without_faces`).
    """
    models = _load_models()
    if models is None or models.faces is None:
        return None
    small, (height, width) = _detection_image(image)
    with _native_logs_silenced():
        probability, pose_result = _person_and_pose(models, small)
        if pose_result is None or pose_result.pose_landmarks is None:
            return None
        nose = pose_result.pose_landmarks.landmark[_NOSE]
        if nose.visibility < MIN_VISIBILITY:
            return None
        detections = models.faces.process(small).detections or []
    person = probability > PERSON_PROBABILITY
    rows, columns = small.shape[:2]
    faces = np.zeros((rows, columns), bool)
    for face in detections:
        box = face.location_data.relative_bounding_box
        if not (box.xmin <= nose.x <= box.xmin + box.width and box.ymin <= nose.y <= box.ymin + box.height):
            continue
        x0, x1 = round(box.xmin * columns), round((box.xmin + box.width) * columns)
        y0, y1 = round(box.ymin * rows), round((box.ymin + box.height) * rows)
        reach_x, reach_y = round(HEAD_REACH * (x1 - x0)), round(HEAD_REACH * (y1 - y0))
        head = np.zeros_like(faces)
        head[max(0, y0 - 2 * reach_y) : y1 + reach_y, max(0, x0 - reach_x) : x1 + reach_x] = True
        faces[max(0, y0) : y1, max(0, x0) : x1] = True
        faces |= head & person
    if not faces.any():
        return None
    return cv2.resize(faces.astype(np.uint8), (width, height), interpolation=cv2.INTER_NEAREST) > 0


def _face_off_object(models: _Models, small: np.ndarray, person: np.ndarray, object_mask: np.ndarray | None) -> bool:
    """Whether a detected face's box is mostly the person's pixels off the object (a guitar's
    body the face detector takes for a face is on the object; a neck across a face is not most of it)."""
    if models.faces is None:
        return False
    off_object = np.ones_like(person) if object_mask is None else ~(
        cv2.resize(np.asarray(object_mask, np.uint8), person.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0)
    height, width = person.shape
    for face in models.faces.process(small).detections or []:
        box = face.location_data.relative_bounding_box
        x0, y0 = max(0, round(box.xmin * width)), max(0, round(box.ymin * height))
        x1, y1 = min(width, round((box.xmin + box.width) * width)), min(height, round((box.ymin + box.height) * height))
        if x1 > x0 and y1 > y0 and (person & off_object)[y0:y1, x0:x1].mean() > 0.5:
            return True
    return False


def _sure_person_off_object(probability: np.ndarray, object_mask: np.ndarray | None) -> bool:
    """Whether the segmenter is sure of enough person pixels well away from the object
    (OFF_OBJECT_SHARE), or sees a whole body there (OFF_OBJECT_BODY_SHARE)."""
    if object_mask is None:
        return False
    height, width = probability.shape
    on_object = cv2.resize(np.asarray(object_mask, np.uint8), (width, height), interpolation=cv2.INTER_NEAREST) > 0
    rows, cols = np.nonzero(on_object)
    if len(rows) == 0:
        return False
    reach = max(1, round(OFF_OBJECT_REACH * mask_extent(on_object)))
    near = cv2.dilate(on_object.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2)) > 0
    return (np.count_nonzero((probability > CONFIDENT_PERSON_PROBABILITY) & ~near) >= OFF_OBJECT_SHARE * len(rows)
            or np.count_nonzero((probability > PERSON_PROBABILITY) & ~near) >= OFF_OBJECT_BODY_SHARE * len(rows))


def _detection_image(image: np.ndarray) -> tuple[np.ndarray, tuple[int, int]]:
    """The RGB image at most DETECTION_SIDE on its long side, and the original (height, width)."""
    rgb = np.ascontiguousarray(image[..., :3], dtype=np.uint8)
    height, width = rgb.shape[:2]
    scale = min(1.0, DETECTION_SIDE / max(height, width))
    small = cv2.resize(rgb, (max(1, round(width * scale)), max(1, round(height * scale))), interpolation=cv2.INTER_AREA) if scale < 1.0 else rgb
    return small, (height, width)


def _person_and_pose(models: _Models, small: np.ndarray) -> tuple[np.ndarray, Any | None]:
    """Selfie-segmentation probability and, when a person is confidently there, the pose.

    Both detectors ask for these on the same image; the last answer is kept so the
    models run once per image.
    """
    key = hashlib.sha1(small.tobytes()).hexdigest() + str(small.shape)
    if _last_inference.get("models") is not models or _last_inference.get("key") != key:
        probability = models.segmenter.process(small).segmentation_mask
        confident = (probability > CONFIDENT_PERSON_PROBABILITY).mean() >= MIN_CONFIDENT_PERSON_SHARE
        _last_inference.update(models=models, key=key, answer=(probability, models.pose.process(small) if confident else None))
    return _last_inference["answer"]


def _detect(models: _Models, image: np.ndarray, object_mask: np.ndarray | None = None) -> np.ndarray | None:
    small, (height, width) = _detection_image(image)
    probability, pose_result = _person_and_pose(models, small)
    person = probability > PERSON_PROBABILITY
    found = _hand_mask(models.hands.process(small), person)
    if pose_result is not None:
        found |= _arm_band(pose_result, small.shape[:2]) & person
    if not found.any():
        return None
    if object_mask is not None:
        off_object = ~(cv2.resize(np.asarray(object_mask, np.uint8), found.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0)
        reach = max(1, round(COMPLETION_REACH * max(found.shape)))
        near = cv2.dilate(found.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * reach + 1,) * 2)) > 0
        found |= near & person & off_object
    return cv2.resize(found.astype(np.uint8), (width, height), interpolation=cv2.INTER_NEAREST) > 0


@contextmanager
def _native_logs_silenced() -> Iterator[None]:
    """Mute what mediapipe's C++ core writes to stderr (TensorFlow Lite and glog chatter
    on every model load and inference), which would bury frontal3d's own messages."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(devnull)
        os.close(saved)


@lru_cache(maxsize=1)
def _load_models() -> _Models | None:
    """The four mediapipe solutions, built once per process; None if mediapipe is missing."""
    try:
        from mediapipe.python.solutions import face_detection, hands, pose, selfie_segmentation
    except ImportError as exc:
        log.warning("occluder detection is off: mediapipe is not installed (%s); run scripts/setup.sh", exc)
        return None
    with _native_logs_silenced():
        models = _Models(
            segmenter=selfie_segmentation.SelfieSegmentation(model_selection=0),
            # Other complexities download their model at run time; 1 ships in the wheel.
            pose=pose.Pose(static_image_mode=True, model_complexity=1),
            hands=hands.Hands(static_image_mode=True, max_num_hands=4),
            # The full-range model finds the small faces of people a few metres off.
            faces=face_detection.FaceDetection(model_selection=1),
        )
        # The graphs open their inference calculators on worker threads after construction,
        # each logging a warning through absl (which no environment variable silences); one
        # run of each waits for that while stderr is still muted.
        blank = np.zeros((64, 64, 3), np.uint8)
        for model in (models.segmenter, models.pose, models.hands, models.faces):
            model.process(blank)
    return models


def _arm_band(pose_result: Any, shape: tuple[int, int]) -> np.ndarray:
    """Thick lines along each visible arm chain (shoulder-elbow-wrist-hand points)."""
    band = np.zeros(shape, np.uint8)
    if pose_result.pose_landmarks is None:
        return band > 0
    landmarks = pose_result.pose_landmarks.landmark
    points = np.array([(lm.x * shape[1], lm.y * shape[0]) for lm in landmarks])
    visible = np.array([lm.visibility > MIN_VISIBILITY for lm in landmarks])
    width = _arm_width(points, visible)
    for chain in _ARM_CHAINS:
        segments = list(itertools.pairwise(chain)) + [(chain[-1], tip) for tip in _HAND_POINTS[chain[-1]]]
        for start, end in segments:
            if visible[start] and visible[end]:
                cv2.line(band, _pixel(points[start]), _pixel(points[end]), 1, thickness=width)
    return band > 0


def _arm_width(points: np.ndarray, visible: np.ndarray) -> int:
    """Band thickness from the body's size: shoulder width, else the longest visible upper arm."""
    if visible[11] and visible[12]:
        reference = np.linalg.norm(points[11] - points[12])
    else:
        upper_arms = [np.linalg.norm(points[s] - points[e]) for s, e, _ in _ARM_CHAINS if visible[s] and visible[e]]
        reference = max(upper_arms, default=0.0)
    return max(3, round(ARM_BAND_WIDTH * reference))


def _hand_mask(hands_result: Any, person: np.ndarray) -> np.ndarray:
    """Each detected hand's landmark hull, grown to the hand's outline.

    Cut to the person's silhouette where the silhouette covers the hand; a lone hand
    in a close-up is often missed by the person segmenter, and then the hull stands alone.
    """
    found = np.zeros(person.shape, bool)
    for hand in hands_result.multi_hand_landmarks or []:
        points = np.array([(lm.x * person.shape[1], lm.y * person.shape[0]) for lm in hand.landmark])
        hull = np.zeros(person.shape, np.uint8)
        cv2.fillConvexPoly(hull, cv2.convexHull(np.round(points).astype(np.int32)), 1)
        margin = max(1, round(HAND_MARGIN * np.ptp(points, axis=0).max()))
        grown = cv2.dilate(hull, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin + 1, 2 * margin + 1))) > 0
        on_person = grown & person
        found |= on_person if on_person.sum() > 0.5 * hull.sum() else grown
    return found


def _pixel(point: np.ndarray) -> tuple[int, int]:
    return round(point[0]), round(point[1])
