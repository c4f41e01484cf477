"""Synthetic occlusion benchmark (issue 7): occluders pasted over frontal renders.

Two protocols, as the issue states them:

* ``arms`` -- procedural forearms with a hand, in skin tones with a cylinder's shading,
  reach in from the image border over 10-30 % of the object; their mask is passed as the
  occluder mask (what a user painting the occluders would give).
* ``people`` -- people cut out of public-domain photos that ship inside installed packages
  (skimage's astronaut and cameraman, matplotlib's Grace Hopper) by the selfie segmenter,
  pasted either as a *guitarist* (the body behind the object, an arm-shaped stretch of the
  person in front of it) or as the *whole person* in front; no occluder mask is given, so
  the detectors must find them. Each composite is also run with its true occluder mask, to
  tell detection losses from reconstruction losses.

In both, the object's visible mask is given (the paper's protocol gives the mask), the
frontal gate is on (a rejected composite is counted, not scored), and each composite is
compared with the reconstruction of the same unoccluded render. ``occluder_pixels_left``
counts the texture pixels inside the object that are still the occluder's own pixels
(within a few grey levels of the composite there, and unlike the object's true colour);
the usual YCrCb skin rule cannot be used, since it takes in 92-99 % of these wooden guitars.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from frontal3d.errors import ConfigError, Frontal3DError, InputError, NotFrontalError
from frontal3d.evaluate import METRIC_KEYS, evaluate_pair, every_nth, load_mesh, load_render, write_csv
from frontal3d.masks import mask_extent
from frontal3d.progress import counter

#: Share of the object the occluder in front hides.
OCCLUDED_SHARE = (0.10, 0.30)
#: Random placements tried per composite before giving up on the share.
PLACEMENT_TRIES = 400
#: Skin tones (RGB, light to dark) the procedural arms are drawn in.
SKIN_TONES = ((241, 194, 167), (224, 172, 135), (198, 134, 98), (161, 102, 70), (110, 68, 45), (78, 50, 36))
#: A texture pixel within this many grey levels (every channel) of the occluder's pixel is the occluder's.
SAME_COLOUR = 6
#: ... provided the occluder there differs from the object's true colour by more than this.
DIFFERENT_COLOUR = 30
PEOPLE_MODES = ("guitarist", "whole person")
COMPOSITE_FIELDS = ("id", "composite", "occluder", "mode", "occluded_share", "rejected", "detected_fraction",
                    "occluder_pixels_left", "occluder_pixels_shown", *METRIC_KEYS, *(f"{k}_clean" for k in METRIC_KEYS), *(f"{k}_change" for k in METRIC_KEYS),
                    *(f"{k}_true_mask" for k in METRIC_KEYS), "subtype", "subtype_clean", "subtype_true_mask", "error")


@dataclass
class Cutout:
    """A person cut out of a photo: RGB pixels and their mask, cropped to the person."""

    name: str
    rgb: np.ndarray
    mask: np.ndarray


@dataclass
class Composite:
    """An occluded render: the image, the object's visible mask and the occluders in front."""

    image: np.ndarray
    visible: np.ndarray
    occluder: np.ndarray
    occluder_name: str
    mode: str

    def share(self, object_mask: np.ndarray) -> float:
        return float((self.occluder & object_mask).sum() / max(object_mask.sum(), 1))


# --------------------------------------------------------------------------- occluders


def arm_occluder(image: np.ndarray, object_mask: np.ndarray, rng: np.random.Generator) -> Composite:
    """A skin-toned forearm and hand from the image border over 10-30 % of the object."""
    height, width = object_mask.shape
    ys, xs = np.nonzero(object_mask)
    size = mask_extent(object_mask)
    for _ in range(PLACEMENT_TRIES):
        pick = rng.integers(len(ys))
        hand = np.array([xs[pick], ys[pick]], float)
        angle = rng.uniform(0, 2 * math.pi)
        direction = np.array([math.cos(angle), math.sin(angle)])
        elbow = hand + direction * 2.0 * max(height, width)
        arm_width = rng.uniform(0.08, 0.16) * size
        mask = _forearm(object_mask.shape, hand, elbow, arm_width, direction, rng)
        composite = Composite(image, object_mask & ~mask, mask, "procedural arm", "hand from the border")
        if OCCLUDED_SHARE[0] <= composite.share(object_mask) <= OCCLUDED_SHARE[1]:
            composite.image = _skin_paint(image, mask, hand, direction, arm_width, rng)
            return composite
    raise InputError("no arm placement hides 10-30 % of the object (is the object too small?)")


def _forearm(shape: tuple[int, int], hand: np.ndarray, elbow: np.ndarray, width: float, direction: np.ndarray,
             rng: np.random.Generator) -> np.ndarray:
    """A tapered band (wrist 70 % of the elbow's width), a palm and four fingers pointing away from the elbow."""
    normal = np.array([-direction[1], direction[0]])
    wrist = hand + direction * 0.45 * width
    quad = np.array([elbow + normal * width / 2, elbow - normal * width / 2, wrist - normal * 0.35 * width, wrist + normal * 0.35 * width])
    mask = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(mask, np.round(quad).astype(np.int32), 1)
    palm = hand - direction * 0.1 * width
    cv2.ellipse(mask, _px(palm), (max(1, round(0.45 * width)), max(1, round(0.4 * width))),
                math.degrees(math.atan2(direction[1], direction[0])), 0, 360, 1, -1)
    spread = rng.uniform(-0.2, 0.2)
    for offset in (-0.27, -0.09, 0.09, 0.27):
        base = palm - direction * 0.3 * width + normal * offset * width
        tip = base - (direction + normal * (offset + spread)) * rng.uniform(0.45, 0.7) * width
        cv2.line(mask, _px(base), _px(tip), 1, max(1, round(0.13 * width)))
    return mask > 0


def _skin_paint(image: np.ndarray, mask: np.ndarray, hand: np.ndarray, direction: np.ndarray, width: float,
                rng: np.random.Generator) -> np.ndarray:
    """The image with ``mask`` painted in a skin tone, lit like a cylinder along the arm, with a little grain."""
    tone = np.array(SKIN_TONES[rng.integers(len(SKIN_TONES))], float)
    rows, cols = np.nonzero(mask)
    normal = np.array([-direction[1], direction[0]])
    across = ((cols - hand[0]) * normal[0] + (rows - hand[1]) * normal[1]) / (0.5 * width)
    shade = 0.75 + 0.35 * np.sqrt(np.clip(1 - np.clip(across, -1, 1) ** 2, 0, 1))
    grain = rng.normal(0, 4, (len(rows), 3))
    out = image.copy()
    out[rows, cols] = np.clip(tone * shade[:, None] + grain, 0, 255).astype(np.uint8)
    return out


def people_cutouts() -> list[Cutout]:
    """The three public-domain portraits installed with the dependencies, cut out by the selfie segmenter."""
    import matplotlib.cbook
    import skimage.data
    from PIL import Image

    from frontal3d.occluders import detect_people

    photos = {
        "astronaut": skimage.data.astronaut(),
        "cameraman": np.repeat(skimage.data.camera()[..., None], 3, axis=2),
        "grace_hopper": np.asarray(Image.open(matplotlib.cbook.get_sample_data("grace_hopper.jpg")).convert("RGB")),
    }
    cutouts = []
    for name, photo in photos.items():
        person = detect_people(photo)
        if person is None:
            raise ConfigError("the people protocol needs the selfie segmenter: mediapipe is not installed (run scripts/setup.sh)")
        rows, cols = np.nonzero(person)
        window = np.s_[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
        cutouts.append(Cutout(name, photo[window].copy(), person[window].copy()))
    return cutouts


def paste_person(image: np.ndarray, object_mask: np.ndarray, cutout: Cutout, mode: str, rng: np.random.Generator) -> Composite:
    """The person over the render as a guitarist (body behind the object, an arm-shaped stretch
    of the person in front of it) or as the whole person in front, hiding 10-30 % of the object."""
    if mode not in PEOPLE_MODES:
        raise InputError(f"unknown people mode {mode!r} (one of {', '.join(PEOPLE_MODES)})")
    ys, xs = np.nonzero(object_mask)
    size = mask_extent(object_mask)
    for _ in range(PLACEMENT_TRIES):
        person_height = rng.uniform(0.5, 1.1) * size
        scale = person_height / cutout.mask.shape[0]
        if mode == "guitarist":
            # The object's lower part (a guitar's body) across the person's chest.
            body = np.array([np.median(xs[ys > np.percentile(ys, 60)]), np.percentile(ys, 80)])
            top_left = body - np.array([0.5 * cutout.mask.shape[1], 0.7 * cutout.mask.shape[0]]) * scale
            top_left += rng.normal(0, 0.08 * size, 2)
        else:
            pick = rng.integers(len(ys))
            top_left = np.array([xs[pick], ys[pick]]) - np.array([rng.uniform(0.2, 0.8) * cutout.mask.shape[1], rng.uniform(0.0, 0.6) * cutout.mask.shape[0]]) * scale
        rgb, person = _placed(cutout, scale, top_left, object_mask.shape)
        if not person.any():
            continue
        in_front = person & _arm_stretch(person, object_mask, rng) if mode == "guitarist" else person
        composite = Composite(image, object_mask & ~in_front, in_front, cutout.name, mode)
        if OCCLUDED_SHARE[0] <= composite.share(object_mask) <= OCCLUDED_SHARE[1]:
            out = image.copy()
            shown = in_front | (person & ~object_mask)
            out[shown] = rgb[shown]
            composite.image = out
            return composite
    raise InputError(f"no placement of {cutout.name} as {mode} hides 10-30 % of the object")


def _placed(cutout: Cutout, scale: float, top_left: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The cutout scaled and moved onto an image of ``shape``: (RGB, mask), clipped to the frame."""
    matrix = np.array([[scale, 0, top_left[0]], [0, scale, top_left[1]]], np.float64)
    size = (shape[1], shape[0])
    rgb = cv2.warpAffine(cutout.rgb, matrix, size, flags=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    mask = cv2.warpAffine(cutout.mask.astype(np.uint8), matrix, size, flags=cv2.INTER_NEAREST) > 0
    return rgb, mask


def _arm_stretch(person: np.ndarray, object_mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A forearm-wide band from the person's side, off the object at chest height, to a point on
    the object's lower part (a strumming arm); the person's pixels in it are in front."""
    ys, xs = np.nonzero(object_mask)
    size = mask_extent(object_mask)
    lower = ys > np.percentile(ys, rng.uniform(50, 75))
    pick = rng.integers(lower.sum())
    target = np.array([xs[lower][pick], ys[lower][pick]])
    prow, pcol = np.nonzero(person & ~object_mask)
    if len(prow) == 0:
        return np.zeros_like(person)
    # The side: person pixels beside the object, below the person's top third.
    beside = (prow > np.percentile(prow, 35)) & (np.abs(pcol - target[0]) > 0.5 * np.abs(pcol - target[0]).max())
    choices = np.flatnonzero(beside) if beside.any() else np.arange(len(prow))
    start = np.array([pcol, prow]).T[rng.choice(choices)]
    band = np.zeros(object_mask.shape, np.uint8)
    cv2.line(band, _px(start), _px(target), 1, max(2, round(rng.uniform(0.08, 0.14) * size)))
    cv2.circle(band, _px(target), max(2, round(0.07 * size)), 1, -1)
    return band > 0


def _px(point: np.ndarray) -> tuple[int, int]:
    return round(float(point[0])), round(float(point[1]))


# --------------------------------------------------------------------------- scoring


def occluder_texels(atlas: np.ndarray, composite: np.ndarray, clean: np.ndarray, occluder: np.ndarray, object_mask: np.ndarray,
                    synthesized: np.ndarray | None = None) -> np.ndarray:
    """The atlas front half's texels (h, w bool) inside the object that are still the occluder's own pixels.

    The atlas's front half is the photo's crop (inpainted under the found occluders); it is
    located in ``composite`` by template matching (on the texels taken from the photo when
    ``synthesized`` is given: the made-up ones, the background bled over most of all, pulled
    the match 13 px off on psb_m634), and a pixel counts when it lies on the
    true occluder inside the object, matches the composite there to SAME_COLOUR and the
    composite there is unlike the object's true colour (``clean``) by DIFFERENT_COLOUR.
    ``synthesized`` (the front half's texels the texture stage made up, see
    ``TexturedMesh.front_synthesized``) are no longer the photo's pixel there: such a texel
    counts only when no visible pixel of the object has its colour either (to SAME_COLOUR),
    since a dark wood the inpainting copied may match a dark skin tone by chance, while
    skin smeared in from outside the object matches nothing the object shows.
    """
    front = np.ascontiguousarray(atlas[:, : atlas.shape[1] // 2, :3])
    if front.shape[0] > composite.shape[0] or front.shape[1] > composite.shape[1]:
        return np.zeros(front.shape[:2], bool)
    known = None
    if synthesized is not None and synthesized.shape == front.shape[:2] and not synthesized.all():
        known = np.repeat(~synthesized[..., None], 3, axis=2).astype(np.float32)
    scores = cv2.matchTemplate(composite[..., :3].astype(np.float32), front.astype(np.float32), cv2.TM_SQDIFF, mask=known)
    _, _, (x0, y0), _ = cv2.minMaxLoc(scores)
    window = np.s_[y0 : y0 + front.shape[0], x0 : x0 + front.shape[1]]
    shown = composite[window][..., :3].astype(int)
    same = np.abs(front.astype(int) - shown).max(axis=2) <= SAME_COLOUR
    unlike = np.abs(shown - clean[window][..., :3].astype(int)).max(axis=2) > DIFFERENT_COLOUR
    left = same & unlike & occluder[window] & object_mask[window]
    if known is not None:
        made_up = left & synthesized
        seen_colours = composite[object_mask & ~occluder][..., :3].astype(int)
        explained = np.array([_colour_shown(colour, seen_colours) for colour in front[made_up].astype(int)], bool)
        left[made_up] = ~explained
    return left


def _colour_shown(colour: np.ndarray, colours: np.ndarray) -> bool:
    """Whether any of ``colours`` (n x 3) is within SAME_COLOUR of ``colour`` in every channel."""
    return bool(len(colours)) and bool((np.abs(colours - colour).max(axis=1) <= SAME_COLOUR).any())


def _reconstruct(plugins: Any, family: str, image: np.ndarray, mask: np.ndarray, occluder: np.ndarray | None, settings: dict[str, Any]):
    from frontal3d.pipeline import reconstruct

    return reconstruct(image, family, mask=mask, occluder_mask=occluder, plugins=plugins, **settings)


def selected_composites(kind: str, paths: list[Path], renders_dir: Path, per_object: int, seed: int, every: int = 1,
                        offset: int = 0) -> Iterator[tuple[Path, np.ndarray, np.ndarray, int, Composite]]:
    """(mesh path, render, mask, index, composite) for the ``per_object`` composites of each selected mesh.

    The placements of the meshes left out are still drawn, so a mesh meets the same composites
    in a slice as in the whole run: one seed gives one benchmark, and its halves add up to it.
    """
    selected = set(every_nth(paths, every, offset))
    cutouts = people_cutouts() if kind == "people" else []
    rng = np.random.default_rng(seed)
    for number, path in enumerate(paths):
        image, mask, _camera = load_render(renders_dir, path.stem)
        for index, composite in enumerate(_composites(kind, image, mask, number * per_object, per_object, rng, cutouts)):
            if path in selected:
                yield path, image, mask, index, composite


def _composites(kind: str, image: np.ndarray, mask: np.ndarray, first: int, count: int, rng: np.random.Generator,
                cutouts: list[Cutout]) -> Iterator[Composite]:
    """``count`` composites; for people, the n-th of the whole run (from ``first``) cycles through
    every photo in both modes, so each pair turns up equally often over the renders."""
    for index in range(first, first + count):
        if kind == "arms":
            yield arm_occluder(image, mask, rng)
        else:
            cutout = cutouts[index % len(cutouts)]
            mode = PEOPLE_MODES[(index % len(cutouts) + index // len(cutouts)) % len(PEOPLE_MODES)]
            yield paste_person(image, mask, cutout, mode, rng)


def run_occlusion_evaluation(family: str, meshes_dir: Path, renders_dir: Path, kind: str, plugins: Any, out_dir: Path,
                             seed: int = 0, per_object: int = 5, limit: int | None = None,
                             settings: dict[str, Any] | None = None, progress: bool = True,
                             every: int = 1, offset: int = 0, segment: bool = False) -> list[dict]:
    """Score every render of ``renders_dir`` under ``per_object`` composites of ``kind`` (arms|people).

    ``every`` and ``offset`` score only every ``every``-th mesh of the sorted listing from
    ``offset`` (a tuning half and a held-out half), each under the composites the whole run
    gives it (:func:`selected_composites`). ``segment`` gives no object mask: each composite,
    and its clean render, is segmented as ``reconstruct`` segments a photo (what a user with a
    guitarist's photo and no mask gets). Writes ``composites.csv`` (one row per composite),
    ``summary.csv`` and the composites themselves (``images/<id>_<n>.png`` and
    ``_occluder.png``, and the detected run's ``_sheet.png``: see
    :func:`~frontal3d.stages.occlusion.occlusion_sheet`) into ``out_dir``.
    """
    if kind not in ("arms", "people"):
        raise InputError(f"unknown occluders {kind!r} (arms or people)")
    settings = dict(settings or {})
    paths = sorted(Path(meshes_dir).glob("*.glb"))[:limit]
    if not paths:
        raise InputError(f"no *.glb meshes in {meshes_dir}")
    scored = len(every_nth(paths, every, offset))
    out_dir = Path(out_dir)
    (out_dir / "images").mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    bar = counter(scored * per_object, "composite", f"occluded {family} ({kind})", progress)
    gt, clean = None, None
    for path, image, mask, index, composite in selected_composites(kind, paths, Path(renders_dir), per_object, seed, every, offset):
        if index == 0:
            gt = load_mesh(path)
            clean_result = _reconstruct(plugins, family, image, None if segment else mask, None, settings)
            clean = {**_scores(clean_result, gt), "subtype": _subtype(clean_result)}
        rows.append(_composite_row(plugins, family, path.stem, index, composite, image, mask, gt, clean, kind, settings, out_dir, segment))
        bar.update(1)
    bar.close()
    write_csv(out_dir / "composites.csv", COMPOSITE_FIELDS, rows)
    summary = summarize(rows)
    write_csv(out_dir / "summary.csv", tuple(summary[0]), summary)
    return rows


def _composite_row(plugins, family, mesh_id, index, composite: Composite, image, mask, gt, clean, kind, settings, out_dir,
                   segment: bool = False) -> dict:
    name = f"{mesh_id}_{index}"
    visible = None if segment else composite.visible
    cv2.imwrite(str(out_dir / "images" / f"{name}.png"), composite.image[..., ::-1])
    cv2.imwrite(str(out_dir / "images" / f"{name}_occluder.png"), composite.occluder.astype(np.uint8) * 255)
    row: dict[str, Any] = {"id": mesh_id, "composite": name, "occluder": composite.occluder_name, "mode": composite.mode,
                           "occluded_share": round(composite.share(mask), 4), "rejected": "", "error": ""}
    given = composite.occluder if kind == "arms" else None
    try:
        result = _reconstruct(plugins, family, composite.image, visible, given, settings)
        if "occlusion_sheet" in result.maps:  # who was judged in front, and what was rebuilt
            cv2.imwrite(str(out_dir / "images" / f"{name}_sheet.png"), result.maps["occlusion_sheet"][..., ::-1])
        row.update(_scores(result, gt, clean))
        row["subtype"], row["subtype_clean"] = _subtype(result), clean["subtype"]
        row["detected_fraction"] = result.report.get("occlusion", {}).get("occluded_fraction", 0.0)
        # Located and judged once; counted over the whole front half and on the model only
        # (``front_shown``: the rest pads the rim with the nearest silhouette colour, which next
        # to an outline left unrebuilt may be a blend with the occluder).
        left = occluder_texels(result.textured.atlas, composite.image, image, composite.occluder, mask, result.textured.front_synthesized)
        row["occluder_pixels_left"] = int(np.count_nonzero(left))
        row["occluder_pixels_shown"] = int(np.count_nonzero(left & result.textured.front_shown))
    except NotFrontalError as exc:
        row["rejected"] = str(exc).splitlines()[0]
    except Frontal3DError as exc:
        row["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0]
    if kind == "people":
        try:
            truth_result = _reconstruct(plugins, family, composite.image, visible, composite.occluder, settings)
            truth = _scores(truth_result, gt)
            row.update({f"{k}_true_mask": truth[k] for k in METRIC_KEYS})
            row["subtype_true_mask"] = _subtype(truth_result)
        except Frontal3DError:
            pass  # rejected even with the true mask: no reference for this composite
    return row


def _subtype(result) -> str:
    """The subtype the classifier chain picked (a flip against the clean render is what costs most)."""
    return next((d["label"] for d in result.report.get("decisions", []) if d["name"] == "subtype"), "")


def _scores(result, gt, clean: dict | None = None) -> dict[str, float]:
    metrics = evaluate_pair(result.mesh, gt)
    scores = {key: metrics[key] for key in METRIC_KEYS}
    if clean is not None:
        scores.update({f"{key}_clean": clean[key] for key in METRIC_KEYS})
        scores.update({f"{key}_change": metrics[key] / clean[key] - 1.0 for key in METRIC_KEYS})
    return scores


def summarize(rows: list[dict]) -> list[dict]:
    """Per occluder mode and overall: counts, the change of each metric's mean against the
    same renders' unoccluded means (paired), for the detected run and the true-mask reference,
    and how many composites got another subtype than their unoccluded render (the costliest
    failure: a classical guitar rebuilt as a thin electric one loses half its volume)."""
    groups: dict[str, list[dict]] = {"all": rows}
    for row in rows:
        groups.setdefault(row["mode"], []).append(row)
    summary = []
    for group, members in groups.items():
        scored = [r for r in members if "iou" in r]
        line: dict[str, Any] = {"group": group, "n": len(members), "scored": len(scored),
                                "rejected": sum(bool(r["rejected"]) for r in members),
                                "occluded_share_mean": _mean([r["occluded_share"] for r in members]),
                                "occluder_pixels_left": sum(r.get("occluder_pixels_left", 0) for r in scored),
                                "occluder_pixels_shown": sum(r.get("occluder_pixels_shown", 0) for r in scored)}
        for key in METRIC_KEYS:
            line[f"{key}_change"] = _mean([r[key] for r in scored]) / _mean([r[f"{key}_clean"] for r in scored]) - 1.0 if scored else float("nan")
        line["subtype_changed"] = sum(_subtype_changed(r, "subtype") for r in scored)
        referenced = [r for r in scored if "iou_true_mask" in r]
        line["true_mask_scored"] = len(referenced)
        line["subtype_changed_true_mask"] = sum(_subtype_changed(r, "subtype_true_mask") for r in referenced)
        for key in METRIC_KEYS:
            line[f"{key}_change_true_mask"] = (_mean([r[f"{key}_true_mask"] for r in referenced]) / _mean([r[f"{key}_clean"] for r in referenced]) - 1.0) if referenced else float("nan")
        summary.append(line)
    return summary


def summary_lines(summary: list[dict]) -> list[str]:
    """The summary as text: change of the means in %, IoU / Chamfer-L1 / F."""
    lines = []
    for line in summary:
        changes = " / ".join(f"{100 * line[f'{k}_change']:+.1f}" for k in METRIC_KEYS)
        text = (f"{line['group']:<14} n={line['n']:<3} scored={line['scored']:<3} rejected={line['rejected']:<3} "
                f"share={100 * line['occluded_share_mean']:.0f}%  change IoU/CD/F: {changes} %  occluder pixels left: {line['occluder_pixels_left']} "
                f"(on the model: {line['occluder_pixels_shown']})  subtype changed: {line['subtype_changed']}")
        if line["true_mask_scored"]:
            text += ("  true mask: " + " / ".join(f"{100 * line[f'{k}_change_true_mask']:+.1f}" for k in METRIC_KEYS)
                     + f" % (n={line['true_mask_scored']}, subtype changed: {line['subtype_changed_true_mask']})")
        lines.append(text)
    return lines


def _subtype_changed(row: dict, key: str) -> bool:
    """Whether the composite's ``key`` subtype is known and differs from its unoccluded render's."""
    return bool(row.get(key)) and bool(row.get("subtype_clean")) and row[key] != row["subtype_clean"]


def _mean(values: list[float]) -> float:
    return statistics.fmean(values) if values else float("nan")
