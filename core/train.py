"""Training the learned models on data made by ``frontal3d synth``.

The frontal gate and subtype classifier (:class:`CompactResNet`, or :class:`ResNet18` on
request, loaded by :mod:`frontal3d.learned`) and the dense object and region segmenters (:class:`TinyUNet`,
loaded by :mod:`frontal3d.learned_dense`). CPU-only and small on purpose: the inputs are
computed once and held in memory, and a fixed share of the samples is held out (never
trained on) to report accuracy or IoU after every epoch.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import cv2
import numpy as np
import torch
from torch import nn
from torch.nn import functional

from frontal3d.errors import ConfigError, InputError
from frontal3d.family import Family
from frontal3d.learned import (
    ARCHITECTURE, CLASSIFIER_TASKS, DENSE_ARCHITECTURE, DENSE_TASKS, FORMAT_VERSION, GATE_CLASSES, INPUT_SIZE,
    RESNET18_ARCHITECTURE, WIDTHS, crop_square, cut_square, object_crop, to_tensor,
)
from frontal3d.learned_dense import DENSE_INPUT_SIZE, DENSE_WIDTHS, SEGMENTER_CLASSES, dense_probabilities, family_region_names, letterbox, regions_input
from frontal3d.progress import counter
from frontal3d.synth import read_family_labels, read_sample, read_sample_regions

#: Share of the samples held out for the accuracy report.
HOLD_OUT = 0.15
BATCH_SIZE = 64
#: The dense networks keep a full-resolution activation per layer: smaller batches.
DENSE_BATCH_SIZE = 32
LEARNING_RATE = 2e-3


class _ResidualBlock(nn.Module):
    """Two 3x3 convolutions with a (strided 1x1) shortcut, as in ResNet-18's basic block."""

    def __init__(self, in_channels: int, out_channels: int, stride: int):
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(in_channels, out_channels, 3, stride, 1, bias=False), nn.BatchNorm2d(out_channels), nn.ReLU(inplace=True),
            nn.Conv2d(out_channels, out_channels, 3, 1, 1, bias=False), nn.BatchNorm2d(out_channels),
        )
        self.shortcut = nn.Sequential(nn.Conv2d(in_channels, out_channels, 1, stride, bias=False), nn.BatchNorm2d(out_channels))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.body(x) + self.shortcut(x))


class CompactResNet(nn.Module):
    """A ResNet-like classifier small enough to train on two CPU cores in minutes."""

    def __init__(self, num_classes: int, widths: tuple[int, ...] = WIDTHS):
        super().__init__()
        self.stem = nn.Sequential(nn.Conv2d(3, widths[0], 5, 2, 2, bias=False), nn.BatchNorm2d(widths[0]), nn.ReLU(inplace=True))
        stages, channels = [], widths[0]
        for width in widths:
            stages.append(_ResidualBlock(channels, width, stride=2))
            channels = width
        self.stages = nn.Sequential(*stages)
        self.head = nn.Linear(channels, num_classes)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.stages(self.stem(x)).mean(dim=(2, 3)))


#: Channel widths of ResNet-18's four stages.
RESNET18_WIDTHS = (64, 128, 256, 512)


class _BasicBlock(nn.Module):
    """torchvision's ResNet basic block, with its module names (conv1, bn1, conv2, bn2, downsample)."""

    def __init__(self, in_channels: int, out_channels: int, stride: int):
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, out_channels, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(out_channels)
        self.conv2 = nn.Conv2d(out_channels, out_channels, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(out_channels)
        self.downsample = (nn.Sequential(nn.Conv2d(in_channels, out_channels, 1, stride, bias=False), nn.BatchNorm2d(out_channels))
                           if stride != 1 or in_channels != out_channels else None)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = self.bn2(self.conv2(torch.relu(self.bn1(self.conv1(x)))))
        return torch.relu(out + (x if self.downsample is None else self.downsample(x)))


class ResNet18(nn.Module):
    """ResNet-18 (He et al. 2016) in torchvision's layout and module names, so a state dict of
    ``torchvision.models.resnet18(num_classes=N)`` loads into it and back. Written out here
    because the torchvision wheels built for torch 2.13 need CUDA's libraries, which the CPU
    build of torch does not ship; trained from scratch (11 M parameters, 45 MB)."""

    def __init__(self, num_classes: int, widths: tuple[int, ...] = RESNET18_WIDTHS):
        super().__init__()
        self.conv1 = nn.Conv2d(3, widths[0], 7, 2, 3, bias=False)
        self.bn1 = nn.BatchNorm2d(widths[0])
        channels = widths[0]
        for index, width in enumerate(widths, start=1):
            stride = 1 if index == 1 else 2
            setattr(self, f"layer{index}", nn.Sequential(_BasicBlock(channels, width, stride), _BasicBlock(width, width, 1)))
            channels = width
        self.fc = nn.Linear(channels, num_classes)
        self.depth = len(widths)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = functional.max_pool2d(torch.relu(self.bn1(self.conv1(x))), 3, 2, 1)
        for index in range(1, self.depth + 1):
            x = getattr(self, f"layer{index}")(x)
        return self.fc(x.mean(dim=(2, 3)))


#: Channel widths each classifier architecture is built with.
CLASSIFIER_WIDTHS = {ARCHITECTURE: WIDTHS, RESNET18_ARCHITECTURE: RESNET18_WIDTHS}


def classifier_network(architecture: str, num_classes: int, widths: tuple[int, ...] | None = None) -> nn.Module:
    """A fresh classifier of ``architecture`` (a :data:`CLASSIFIER_ARCHITECTURES` value)."""
    network = ResNet18 if architecture == RESNET18_ARCHITECTURE else CompactResNet
    return network(num_classes, widths or CLASSIFIER_WIDTHS[architecture])


def _conv_block(in_channels: int, out_channels: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(in_channels, out_channels, 3, 1, 1, bias=False), nn.BatchNorm2d(out_channels), nn.ReLU(inplace=True),
        nn.Conv2d(out_channels, out_channels, 3, 1, 1, bias=False), nn.BatchNorm2d(out_channels), nn.ReLU(inplace=True),
    )


class TinyUNet(nn.Module):
    """A four-level U-Net (about 0.23 M parameters): per-pixel class logits at the input's resolution."""

    def __init__(self, in_channels: int, num_classes: int, widths: tuple[int, ...] = DENSE_WIDTHS):
        super().__init__()
        self.down = nn.ModuleList(_conv_block(c_in, c_out) for c_in, c_out in zip((in_channels,) + widths[:-1], widths))
        self.up = nn.ModuleList(_conv_block(widths[i + 1] + widths[i], widths[i]) for i in reversed(range(len(widths) - 1)))
        self.head = nn.Conv2d(widths[0], num_classes, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        for level, block in enumerate(self.down):
            x = block(functional.max_pool2d(x, 2) if level else x)
            skips.append(x)
        for block, skip in zip(self.up, reversed(skips[:-1])):
            x = functional.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            x = block(torch.cat([x, skip], dim=1))
        return self.head(x)


def save_checkpoint(path: Path, model: nn.Module, task: str, family: str, classes: list[str], reference_input: np.ndarray,
                    extra: dict[str, Any] | None = None, architecture: str = ARCHITECTURE) -> None:
    """Write a checkpoint (layout: :mod:`frontal3d.learned`) with ``reference_input``'s output as the reference.
    ``architecture`` is the classifier's (dense tasks have one)."""
    dense = task in DENSE_TASKS
    if dense:
        reference = torch.from_numpy(dense_probabilities(model, reference_input[None])[0].astype(np.float32))
    else:
        model.eval()
        with torch.no_grad():
            reference = torch.softmax(model(to_tensor(reference_input[None])), dim=1)[0].tolist()
    checkpoint = {
        "format_version": FORMAT_VERSION,
        "task": task,
        "family": family,
        "classes": list(classes),
        "input_size": int(reference_input.shape[0]),
        "architecture": DENSE_ARCHITECTURE if dense else architecture,
        "widths": list(DENSE_WIDTHS if dense else CLASSIFIER_WIDTHS[architecture]),
        "state_dict": model.state_dict(),
        "reference_input": torch.from_numpy(np.ascontiguousarray(reference_input)),
        "reference_probabilities": reference,
        "training": dict(extra or {}),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(checkpoint, path)


@dataclass
class Dataset:
    """Network inputs (N x S x S x C uint8), targets and class names of one task.

    Targets are class indices: one per sample for the classifiers, one per pixel
    (N x S x S, -1 = not scored) for the dense tasks.
    """

    family: str
    classes: list[str]
    crops: np.ndarray
    targets: np.ndarray


@dataclass
class TrainingResult:
    """Held-out score after each epoch (accuracy for classifiers, mean IoU for dense tasks), and the sample counts."""

    train_count: int
    held_out_count: int
    held_out_accuracy: list[float] = field(default_factory=list)
    metric: str = "accuracy"


def load_dataset(data_dir: Path, task: str, size: int = INPUT_SIZE) -> Dataset:
    """Read a ``frontal3d synth`` folder as one task's crops: every sample for the gate, frontal ones for subtypes.

    The subtype classifier runs only after the gate accepted, so it learns from frontal views.
    """
    if task not in CLASSIFIER_TASKS:
        raise ConfigError(f"unknown task {task!r} (tasks: {', '.join(CLASSIFIER_TASKS)})")
    rows, families = read_family_labels(data_dir)
    if task == "subtype":
        rows = [row for row in rows if row["frontal"] == "1"]
        classes = sorted({row["subtype"] for row in rows})
        targets = [classes.index(row["subtype"]) for row in rows]
    else:
        classes = list(GATE_CLASSES)
        targets = [int(row["frontal"]) for row in rows]
    if len(classes) < 2 or len(rows) < 2:
        raise InputError(f"{data_dir}: the {task} task needs at least two classes, found {', '.join(classes) or 'none'}")
    crops = np.stack([_crop(data_dir, row["file"], size) for row in rows])
    return Dataset(family=families[0], classes=classes, crops=crops, targets=np.asarray(targets, np.int64))


def single_folder(data_dirs: Sequence[Path], task: str) -> Path:
    """The one folder every task but the segmenter trains on (its labels and classes are one family's)."""
    if len(data_dirs) != 1:
        raise ConfigError(f"the {task} task trains on one family's folder; give one --data")
    return data_dirs[0]


def load_dense_dataset(data_dirs: Sequence[Path], task: str, family_of: Callable[[str], Family], size: int = DENSE_INPUT_SIZE) -> Dataset:
    """Read ``frontal3d synth`` folders for a dense task, every sample (frontal or turned).

    ``family_of`` looks up the family labels.csv names; the model is the first folder's
    family's. ``segmenter``: the letterboxed photo and its object mask, from any number of
    folders of any families (where an object ends is the same question for every family; the
    car segmenter, trained so, does better over clutter: families/car/weights/README.md).
    ``regions``: one folder; the object crop plus mask and its region
    map, relabelled from each subtype's region indices to the family's region set
    (:func:`frontal3d.learned_dense.family_region_names`).
    """
    if task not in DENSE_TASKS:
        raise ConfigError(f"unknown task {task!r} (tasks: {', '.join(DENSE_TASKS)})")
    if task != "segmenter":
        data_dirs = [single_folder(data_dirs, task)]
    labelled = [(data_dir, *read_family_labels(data_dir)) for data_dir in data_dirs]
    samples = [(data_dir, row) for data_dir, rows, _families in labelled for row in rows]
    family = family_of(labelled[0][2][0])
    classes = list(SEGMENTER_CLASSES) if task == "segmenter" else family_region_names(family)
    # per subtype: its region index -> index in the family's region set (background, -1, stays -1)
    relabel = {} if task == "segmenter" else {
        subtype: np.array([classes.index(name) for name in family.regions[subtype]] + [-1]) for subtype in family.subtypes
    }
    inputs, targets = [], []
    for data_dir, row in samples:
        image, mask = read_sample(data_dir, row["file"])
        if task == "segmenter":
            inputs.append(letterbox(image, size)[0])
            targets.append((letterbox(mask.astype(np.uint8) * 255, size)[0] > 127).astype(np.int64))
        else:
            regions = read_sample_regions(data_dir, row["file"])
            crop = regions_input(image, mask, size)
            crop_regions = cv2.resize(cut_square(regions + 1, *crop_square(mask)).astype(np.uint8), (size, size), interpolation=cv2.INTER_NEAREST)
            inputs.append(crop)
            targets.append(relabel[row["subtype"]][crop_regions.astype(np.int64) - 1])
    return Dataset(family=family.name, classes=classes, crops=np.stack(inputs), targets=np.stack(targets))


def _crop(data_dir: Path, name: str, size: int) -> np.ndarray:
    return object_crop(*read_sample(data_dir, name), size)


def train(dataset: Dataset, task: str, out: Path, epochs: int = 8, seed: int = 0,
          log: Callable[[str], None] = print, show_progress: bool | None = None, architecture: str = ARCHITECTURE) -> TrainingResult:
    """Train the task's network on ``dataset``, print the held-out score per epoch, write the checkpoint to ``out``.

    Classifiers (:class:`CompactResNet`, or :class:`ResNet18` with ``architecture``) report accuracy; dense tasks (:class:`TinyUNet`)
    report IoU pooled over the held-out pixels: the object's for the segmenter, the mean
    over regions for the region model.
    """
    dense = task in DENSE_TASKS
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(dataset.targets))
    held_count = max(1, int(round(HOLD_OUT * len(order))))
    held, kept = order[:held_count], order[held_count:]
    scored_classes = [SEGMENTER_CLASSES.index("object")] if task == "segmenter" else list(range(len(dataset.classes)))
    if dense:
        model: nn.Module = TinyUNet(dataset.crops.shape[-1], len(dataset.classes))
        loss_of = nn.CrossEntropyLoss(ignore_index=-1)
        metric = "IoU" if task == "segmenter" else "mean region IoU"
    else:
        model = classifier_network(architecture, len(dataset.classes))
        loss_of = nn.CrossEntropyLoss(label_smoothing=0.05)
        metric = "accuracy"
    batch_size = DENSE_BATCH_SIZE if dense else BATCH_SIZE
    optimiser = torch.optim.AdamW(model.parameters(), lr=LEARNING_RATE, weight_decay=1e-4)
    steps = max(1, epochs * int(np.ceil(len(kept) / batch_size)))
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimiser, max_lr=LEARNING_RATE, total_steps=steps)
    result = TrainingResult(train_count=len(kept), held_out_count=len(held), metric=metric)
    for epoch in range(1, epochs + 1):
        model.train()
        rng.shuffle(kept)
        batches = [kept[i : i + batch_size] for i in range(0, len(kept), batch_size)]
        bar = counter(len(batches), "batch", f"epoch {epoch}/{epochs}", show_progress)
        for batch in batches:
            inputs, targets = _augment(to_tensor(dataset.crops[batch]), torch.from_numpy(dataset.targets[batch]), rng)
            loss = loss_of(model(inputs), targets)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
            bar.set_postfix(loss=f"{loss.item():.3f}")
            bar.update(1)
        bar.close()
        inputs, targets = dataset.crops[held], dataset.targets[held]
        result.held_out_accuracy.append(held_out_iou(model, inputs, targets, scored_classes) if dense else evaluate(model, inputs, targets))
        log(f"epoch {epoch}/{epochs}: held-out {metric} {result.held_out_accuracy[-1]:.3f} ({len(held)} samples)")
    training = {"epochs": epochs, "seed": seed, "train_samples": len(kept), "held_out_samples": len(held),
                f"held_out_{metric.replace(' ', '_')}": result.held_out_accuracy[-1] if result.held_out_accuracy else None}
    save_checkpoint(out, model, task, dataset.family, dataset.classes, dataset.crops[held[0]], training, architecture)
    return result


def _augment(inputs: torch.Tensor, targets: torch.Tensor, rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Mirror half the batch left-right (per-pixel targets too) and jitter the colours' brightness: a photo's object may face either way."""
    flip = torch.from_numpy(rng.random(len(inputs)) < 0.5)
    inputs = torch.where(flip[:, None, None, None], inputs.flip(3), inputs)
    if targets.ndim == 3:
        targets = torch.where(flip[:, None, None], targets.flip(2), targets)
    gain = torch.from_numpy(rng.uniform(0.75, 1.25, size=(len(inputs), 1, 1, 1))).float()
    colours = (inputs[:, :3] * gain).clamp(0.0, 1.0)
    return torch.cat([colours, inputs[:, 3:]], dim=1), targets


def evaluate(model: nn.Module, crops: np.ndarray, targets: np.ndarray) -> float:
    """Share of ``crops`` whose most probable class is the target."""
    model.eval()
    correct = 0
    with torch.no_grad():
        for start in range(0, len(crops), 256):
            predicted = model(to_tensor(crops[start : start + 256])).argmax(dim=1).numpy()
            correct += int((predicted == targets[start : start + 256]).sum())
    return correct / max(1, len(crops))


def held_out_iou(model: nn.Module, inputs: np.ndarray, targets: np.ndarray, classes: list[int]) -> float:
    """Mean over ``classes`` (those present) of each class's IoU pooled over all scored pixels (target >= 0)."""
    model.eval()
    intersections, unions = np.zeros(len(classes)), np.zeros(len(classes))
    with torch.no_grad():
        for start in range(0, len(inputs), 64):
            predicted = model(to_tensor(inputs[start : start + 64])).argmax(dim=1).numpy()
            truth = targets[start : start + 64]
            scored = truth >= 0
            for i, label in enumerate(classes):
                predicted_label, true_label = (predicted == label) & scored, truth == label
                intersections[i] += (predicted_label & true_label).sum()
                unions[i] += (predicted_label | true_label).sum()
    present = unions > 0
    return float((intersections[present] / unions[present]).mean()) if present.any() else 0.0
