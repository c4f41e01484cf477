"""Synthetic training photos rendered from a family's own templates (the paper trained on renders).

We have no photos to train on and cannot download weights, so, like the paper's 3.1.2,
we render the 3D models: each sample is a template with its shape perturbed (anisotropic
scale, mild bend), turned (within the frontal range for positives, 30-90 degrees away
for the frontal gate's negatives, plus an in-plane turn), painted per region with random
colours and procedural textures, lit from a random direction and composited over a
procedural background (on request with fine grain, or with blobs behind the object touching
its outline: the segmenter's hard cases). One sample depends only on ``(seed, index)``, so a data set is
reproducible and can be grown without changing its first samples.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np
import open3d as o3d

from frontal3d.errors import InputError
from frontal3d.family import Family, Template
from frontal3d.synth_people import person_layers

#: Largest |yaw| and |pitch| of a frontal (positive) sample, in degrees: the paper's ±10°.
FRONTAL_LIMIT_DEG = 10.0
#: Range of the larger of |yaw|, |pitch| of a non-frontal (negative) sample, in degrees.
TURNED_RANGE_DEG = (30.0, 90.0)
#: Largest in-plane turn, in degrees (photos are rarely held straight).
IN_PLANE_LIMIT_DEG = 20.0
#: Largest relative change of each axis' length.
SCALE_JITTER = 0.15
#: Largest bend: sideways offset of the ends, as a fraction of the object's length.
BEND_LIMIT = 0.06
#: Share of non-frontal samples.
NEGATIVE_FRACTION = 0.5
#: Fine grain (``grain`` share of the backgrounds): value-noise cells across the image and
#: largest relative amplitude (paper, fabric, a grainy wall; a segmenter that never saw it
#: takes grain for an object's texture).
GRAIN_CELLS = (32, 160)
GRAIN_AMPLITUDE = (0.05, 0.3)
#: Clutter behind the object (``clutter`` share of the samples): how many opaque soft blobs
#: touch its outline, and the chance that a blob takes one of the object's own colours (a
#: segmenter that only saw clutter away from the object joins a blob behind it to it).
CLUTTER_BLOBS = (2, 5)
CLUTTER_OWN_COLOUR = 0.5
#: Regions usually dark in photos (tyres, sound holes): painted dark most of the time.
DARK_REGIONS = ("hole", "wheels")
LABEL_COLUMNS = ("file", "family", "subtype", "frontal", "yaw", "pitch")


@dataclass
class Sample:
    """One synthetic photo with its object mask, region map (-1 outside) and labels."""

    image: np.ndarray
    mask: np.ndarray
    regions: np.ndarray
    subtype: str
    frontal: bool
    yaw: float
    pitch: float


def synthesize(family: Family, templates: dict[str, Template], count: int, out_dir: Path, seed: int = 0,
               resolution: int = 256, progress: Callable[[int], None] | None = None, grain: float = 0.0,
               clutter: float = 0.0, people: float = 0.0) -> Path:
    """Write ``count`` samples as images/, masks/, regions/ PNGs and labels.csv; returns the csv path.

    Subtypes take turns so every class is equally represented; region PNGs hold the
    region index + 1 (0 = background). ``grain``: the share of backgrounds that also get
    fine grain; ``clutter``: the share that get blobs touching the object; ``people``: the
    share with a procedural person behind or across it (:mod:`frontal3d.synth_people`; all
    0 by default, which draws nothing more: older data sets stay identical).
    """
    for folder in ("images", "masks", "regions"):
        (out_dir / folder).mkdir(parents=True, exist_ok=True)
    subtypes = list(templates)
    rows = []
    for index in range(count):
        subtype = subtypes[index % len(subtypes)]
        sample = render_sample(templates[subtype], np.random.default_rng([seed, index]), resolution, grain, clutter, people)
        name = f"{index:06d}.png"
        cv2.imwrite(str(out_dir / "images" / name), cv2.cvtColor(sample.image, cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(out_dir / "masks" / name), sample.mask.astype(np.uint8) * 255)
        cv2.imwrite(str(out_dir / "regions" / name), (sample.regions + 1).astype(np.uint8))
        rows.append((name, family.name, subtype, int(sample.frontal), round(sample.yaw, 2), round(sample.pitch, 2)))
        if progress:
            progress(1)
    labels = out_dir / "labels.csv"
    with labels.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(LABEL_COLUMNS)
        writer.writerows(rows)
    return labels


def render_sample(template: Template, rng: np.random.Generator, resolution: int, grain: float = 0.0, clutter: float = 0.0,
                  people: float = 0.0) -> Sample:
    """One randomized photo of ``template`` (see the module docstring for what varies)."""
    frontal = bool(rng.random() >= NEGATIVE_FRACTION)
    yaw, pitch = _view_angles(rng, frontal)
    vertices = _perturbed_vertices(np.asarray(template.mesh.vertices), rng)
    rotation = _rotation(yaw, pitch, rng.uniform(-IN_PLANE_LIMIT_DEG, IN_PLANE_LIMIT_DEG))
    vertices = vertices @ rotation.T
    faces = np.asarray(template.mesh.faces)
    face_ids, hit_points = _cast(vertices, faces, resolution, fill=rng.uniform(0.55, 0.9), rng=rng)
    mask = face_ids >= 0
    safe_ids = np.where(mask, face_ids, 0)
    regions = np.where(mask, template.face_regions[safe_ids], -1)
    normals = _face_normals(vertices[faces])[safe_ids]
    normals = np.where(normals[..., 2:3] < 0, -normals, normals)
    albedo = _paint(regions, hit_points, template.region_names, rng)
    light = _unit(np.array([rng.uniform(-0.7, 0.7), rng.uniform(-0.7, 0.7), 1.0]))
    shade = rng.uniform(0.1, 0.3) + rng.uniform(0.6, 0.9) * np.clip(normals @ light, 0.0, 1.0)
    rgb = np.clip(albedo * shade[..., None], 0, 255)
    background = _background(resolution, rng, grain)
    if clutter > 0 and rng.random() < clutter:
        background = _touching_blobs(background, mask, rgb, rng)
    image = np.where(mask[..., None], rgb, background)
    if people > 0 and rng.random() < people and mask.any():
        person = person_layers(mask, rgb, rng)
        image = np.where(mask[..., None], image, background * (1 - person.behind[..., None]) + person.colour * person.behind[..., None])
        image = image * (1 - person.front[..., None]) + person.colour * person.front[..., None]
        mask = mask & (person.front < 0.5)
        regions = np.where(mask, regions, -1)
    image = np.clip(image, 0, 255).astype(np.uint8)
    return Sample(image=image, mask=mask, regions=regions.astype(np.int32), subtype=template.subtype, frontal=frontal, yaw=yaw, pitch=pitch)


def _view_angles(rng: np.random.Generator, frontal: bool) -> tuple[float, float]:
    """(yaw, pitch) in degrees: both within ±10° when frontal, else one of them 30-90° away."""
    if frontal:
        yaw, pitch = rng.uniform(-FRONTAL_LIMIT_DEG, FRONTAL_LIMIT_DEG, size=2)
        return float(yaw), float(pitch)
    turned = rng.uniform(*TURNED_RANGE_DEG) * rng.choice([-1.0, 1.0])
    other = rng.uniform(-TURNED_RANGE_DEG[1], TURNED_RANGE_DEG[1]) * rng.uniform(0.0, 1.0) ** 2
    return (float(turned), float(other)) if rng.random() < 0.5 else (float(other), float(turned))


def _perturbed_vertices(vertices: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Centred, each axis scaled by up to ±15 %, the long image axis bent like a mild banana."""
    centred = vertices - (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    scaled = centred * rng.uniform(1 - SCALE_JITTER, 1 + SCALE_JITTER, size=3)
    extent = np.ptp(scaled, axis=0)
    along, across = (0, 1) if extent[0] >= extent[1] else (1, 0)
    position = scaled[:, along] / (extent[along] / 2)
    scaled[:, across] += rng.uniform(-BEND_LIMIT, BEND_LIMIT) * extent[along] * (position**2 - 1 / 3)
    return scaled


def _rotation(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Turn about image-up (yaw), then image-right (pitch), then the view axis (in-plane roll)."""
    yaw, pitch, roll = np.deg2rad([yaw_deg, pitch_deg, roll_deg])
    about_y = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    about_x = np.array([[1, 0, 0], [0, np.cos(pitch), -np.sin(pitch)], [0, np.sin(pitch), np.cos(pitch)]])
    about_z = np.array([[np.cos(roll), -np.sin(roll), 0], [np.sin(roll), np.cos(roll), 0], [0, 0, 1]])
    return about_z @ about_x @ about_y


def _cast(vertices: np.ndarray, faces: np.ndarray, resolution: int, fill: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Orthographic rays along -Z over a square view whose long side spans ``fill``, off-centre a little.

    Returns per pixel the hit face (-1 for none) and the hit point's (x, y) in units of the view's half-width.
    """
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    half_width = float(np.max(hi[:2] - lo[:2])) / 2 / fill
    slack = (1 - fill) * half_width
    centre = (lo[:2] + hi[:2]) / 2 + rng.uniform(-slack, slack, size=2) * 0.8
    steps = (np.arange(resolution) + 0.5) * 2 * half_width / resolution
    grid_x, grid_y = np.meshgrid(centre[0] - half_width + steps, centre[1] + half_width - steps)
    rays = np.zeros((resolution, resolution, 6), np.float32)
    rays[..., 0], rays[..., 1], rays[..., 2], rays[..., 5] = grid_x, grid_y, hi[2] + 1.0, -1.0
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32)))
    hits = scene.cast_rays(o3d.core.Tensor(rays))
    inside = np.isfinite(hits["t_hit"].numpy())
    face_ids = np.where(inside, hits["primitive_ids"].numpy().astype(np.int64), -1)
    points = np.stack([(grid_x - centre[0]) / half_width, (grid_y - centre[1]) / half_width], axis=-1)
    return face_ids, points


def _paint(regions: np.ndarray, points: np.ndarray, region_names: tuple[str, ...], rng: np.random.Generator) -> np.ndarray:
    """Per-pixel albedo: each region a random colour, plain, noisy or striped."""
    resolution = regions.shape[0]
    albedo = np.zeros(regions.shape + (3,), np.float64)
    for label, name in enumerate(region_names):
        inside = regions == label
        if not inside.any():
            continue
        dark = name in DARK_REGIONS and rng.random() < 0.8
        colour = random_colour(rng, dark)
        pattern = rng.integers(3)
        if pattern == 1:
            modulation = 1 + 0.25 * smooth_noise(resolution, rng, cells=rng.integers(4, 24))
        elif pattern == 2:
            direction = random_direction(rng)
            phase = points @ direction * rng.uniform(8, 40) + rng.uniform(0, 2 * np.pi)
            modulation = 1 + 0.2 * np.sign(np.sin(phase))
        else:
            modulation = np.ones(regions.shape)
        albedo[inside] = colour * modulation[inside][:, None]
    return albedo


def random_colour(rng: np.random.Generator, dark: bool) -> np.ndarray:
    """An RGB colour (0-255) of random hue; dark ones keep value below 60."""
    hue, saturation = rng.uniform(0, 180), rng.uniform(0, 255)
    value = rng.uniform(10, 60) if dark else rng.uniform(70, 255)
    hsv = np.array([[[hue, saturation, value]]], np.uint8)
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0].astype(np.float64)


def smooth_noise(resolution: int, rng: np.random.Generator, cells: int) -> np.ndarray:
    """Value noise in [-1, 1]: a coarse random grid resized smoothly to the image."""
    coarse = rng.uniform(-1, 1, size=(int(cells), int(cells))).astype(np.float32)
    return cv2.resize(coarse, (resolution, resolution), interpolation=cv2.INTER_CUBIC).clip(-1, 1).astype(np.float64)


def _background(resolution: int, rng: np.random.Generator, grain: float = 0.0) -> np.ndarray:
    """A gradient between two random colours, with value noise and random soft blobs, and,
    for a ``grain`` share of them, fine grain on top (drawn last, so the rest is unchanged)."""
    background = random_gradient(resolution, rng)
    background *= 1 + 0.2 * smooth_noise(resolution, rng, cells=rng.integers(3, 32))[..., None]
    background = soft_blobs(background, rng, int(rng.integers(0, 6)))
    if grain > 0 and rng.random() < grain:
        amplitude = rng.uniform(*GRAIN_AMPLITUDE)
        background = np.clip(background * (1 + amplitude * smooth_noise(resolution, rng, cells=rng.integers(*GRAIN_CELLS))[..., None]), 0, 255)
    return background


def random_gradient(resolution: int, rng: np.random.Generator) -> np.ndarray:
    """A linear ramp between two random colours (the second dark one time in three), in a random direction."""
    start, end = random_colour(rng, False), random_colour(rng, rng.random() < 0.3)
    return linear_gradient(resolution, start, end, random_direction(rng))


def random_direction(rng: np.random.Generator) -> np.ndarray:
    """A unit 2D vector in a uniformly random direction."""
    return _unit(rng.normal(size=2))


def linear_gradient(resolution: int, start: np.ndarray, end: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """A square image ramping from colour ``start`` to ``end`` along the unit 2D ``direction``."""
    axis = np.linspace(-1, 1, resolution)
    ramp = (np.add.outer(axis * direction[1], axis * direction[0]) / np.sqrt(2) + 1) / 2
    return start * (1 - ramp[..., None]) + end * ramp[..., None]


def soft_blobs(background: np.ndarray, rng: np.random.Generator, count: int, opacity: float = 1.0) -> np.ndarray:
    """``background`` (square) with ``count`` random ellipses of random colours blended in with soft edges."""
    resolution = background.shape[0]
    blobs = np.zeros((resolution, resolution, 3), np.float32)
    weight = np.zeros((resolution, resolution), np.float32)
    for _ in range(count):
        centre = tuple(int(v) for v in rng.integers(0, resolution, size=2))
        axes = tuple(int(v) for v in rng.integers(resolution // 20, resolution // 4, size=2))
        spot = np.zeros((resolution, resolution), np.float32)
        cv2.ellipse(spot, centre, axes, float(rng.uniform(0, 180)), 0, 360, 1.0, -1)
        blobs[spot > 0] = random_colour(rng, rng.random() < 0.3)
        weight = np.maximum(weight, spot)
    weight = opacity * cv2.GaussianBlur(weight, (0, 0), max(1.0, resolution / 100))[..., None]
    return np.clip(background * (1 - weight) + blobs * weight, 0, 255)


def _touching_blobs(background: np.ndarray, mask: np.ndarray, rgb: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``background`` with opaque soft blobs centred near the object's outline, so they pass behind it,
    half of them in one of the object's own colours (the mask benchmark's hard case: a blob
    joining the object in the photo)."""
    resolution = background.shape[0]
    outline = np.argwhere(mask & ~cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool))
    if len(outline) == 0:
        return background
    blobs = np.zeros_like(background, dtype=np.float32)
    weight = np.zeros((resolution, resolution), np.float32)
    for _ in range(int(rng.integers(*CLUTTER_BLOBS))):
        row, col = outline[rng.integers(len(outline))]
        axes = tuple(int(v) for v in rng.integers(resolution // 20, resolution // 5, size=2))
        spot = np.zeros((resolution, resolution), np.float32)
        cv2.ellipse(spot, (int(col), int(row)), axes, float(rng.uniform(0, 180)), 0, 360, 1.0, -1)
        if rng.random() < CLUTTER_OWN_COLOUR:
            own = rgb[mask][rng.integers(int(mask.sum()))]
            colour = np.clip(own * rng.uniform(0.85, 1.15), 0, 255)
        else:
            colour = random_colour(rng, rng.random() < 0.3)
        blobs[spot > 0] = colour
        weight = np.maximum(weight, spot)
    weight = cv2.GaussianBlur(weight, (0, 0), max(1.0, resolution / 100))[..., None]
    return np.clip(background * (1 - weight) + blobs * weight, 0, 255)


def _face_normals(triangles: np.ndarray) -> np.ndarray:
    """Unit normal per triangle, one row per face.

    Degenerate triangles get a zero normal instead of being dropped (as
    ``trimesh.triangles.normals`` does), so the rows stay aligned with the face ids.
    """
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(cross, axis=1, keepdims=True)
    return np.divide(cross, length, out=np.zeros_like(cross), where=length > 0)


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def read_labels(data_dir: Path) -> list[dict[str, str]]:
    """The rows of ``data_dir/labels.csv`` as dicts (see :data:`LABEL_COLUMNS`)."""
    with (data_dir / "labels.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def read_family_labels(data_dir: Path) -> tuple[list[dict[str, str]], list[str]]:
    """labels.csv's rows and its one family name (a data set of several families is refused)."""
    if not (data_dir / "labels.csv").is_file():
        raise InputError(f"{data_dir}: no labels.csv (make the data with `frontal3d synth`)")
    rows = read_labels(data_dir)
    families = sorted({row["family"] for row in rows})
    if len(families) != 1:
        raise InputError(f"{data_dir}/labels.csv: expected samples of one family, found {', '.join(families) or 'none'}")
    return rows, families


def read_labels_of(data_dir: Path, family: str) -> list[dict[str, str]]:
    """labels.csv's rows, refused unless they are all samples of ``family`` (benchmarks judge one family)."""
    rows, families = read_family_labels(data_dir)
    if families[0] != family:
        raise InputError(f"{data_dir} holds {families[0]} samples, not {family}")
    return rows


def read_sample(data_dir: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """One sample's RGB image and object mask."""
    image = cv2.imread(str(data_dir / "images" / name), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(data_dir / "masks" / name), cv2.IMREAD_GRAYSCALE)
    if image is None or mask is None:
        raise InputError(f"{data_dir}: cannot read images/{name} or masks/{name}")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB), mask > 0


def read_sample_regions(data_dir: Path, name: str) -> np.ndarray:
    """One sample's region map in its subtype's region indices, -1 outside the object."""
    regions = cv2.imread(str(data_dir / "regions" / name), cv2.IMREAD_GRAYSCALE)
    if regions is None:
        raise InputError(f"{data_dir}: cannot read regions/{name}")
    return regions.astype(np.int64) - 1
