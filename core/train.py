"""Training the learned frontal gate and subtype classifier on data made by ``frontal3d synth``.

CPU-only and small on purpose: the crops are computed once and held in memory, the
network is :class:`CompactResNet` (defined here, loaded by :mod:`frontal3d.learned`),
and a fixed share of the samples is held out (never trained on) to report accuracy.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import cv2
import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from frontal3d.errors import ConfigError, InputError
from frontal3d.learned import ARCHITECTURE, FORMAT_VERSION, GATE_CLASSES, INPUT_SIZE, TASKS, WIDTHS, object_crop, to_tensor
from frontal3d.synth import read_labels

#: Share of the samples held out for the accuracy report.
HOLD_OUT = 0.15
BATCH_SIZE = 64
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


def save_checkpoint(path: Path, model: CompactResNet, task: str, family: str, classes: list[str], reference_crop: np.ndarray, extra: dict[str, Any] | None = None) -> None:
    """Write a checkpoint (layout: :mod:`frontal3d.learned`) with ``reference_crop``'s probabilities as the reference."""
    model.eval()
    with torch.no_grad():
        probabilities = torch.softmax(model(to_tensor(reference_crop[None])), dim=1)[0]
    checkpoint = {
        "format_version": FORMAT_VERSION,
        "task": task,
        "family": family,
        "classes": list(classes),
        "input_size": int(reference_crop.shape[0]),
        "architecture": ARCHITECTURE,
        "widths": list(WIDTHS),
        "state_dict": model.state_dict(),
        "reference_input": torch.from_numpy(np.ascontiguousarray(reference_crop)),
        "reference_probabilities": probabilities.tolist(),
        "training": dict(extra or {}),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(checkpoint, path)


@dataclass
class Dataset:
    """Crops (N x S x S x 3 uint8), class indices and class names of one task."""

    family: str
    classes: list[str]
    crops: np.ndarray
    targets: np.ndarray


@dataclass
class TrainingResult:
    """Held-out accuracy after each epoch, and the sample counts."""

    train_count: int
    held_out_count: int
    held_out_accuracy: list[float] = field(default_factory=list)


def load_dataset(data_dir: Path, task: str, size: int = INPUT_SIZE) -> Dataset:
    """Read a ``frontal3d synth`` folder as one task's crops: every sample for the gate, frontal ones for subtypes.

    The subtype classifier runs only after the gate accepted, so it learns from frontal views.
    """
    if task not in TASKS:
        raise ConfigError(f"unknown task {task!r} (tasks: {', '.join(TASKS)})")
    if not (data_dir / "labels.csv").is_file():
        raise InputError(f"{data_dir}: no labels.csv (make the data with `frontal3d synth`)")
    rows = read_labels(data_dir)
    families = sorted({row["family"] for row in rows})
    if len(families) != 1:
        raise InputError(f"{data_dir}/labels.csv: expected samples of one family, found {', '.join(families) or 'none'}")
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


def _crop(data_dir: Path, name: str, size: int) -> np.ndarray:
    image = cv2.imread(str(data_dir / "images" / name), cv2.IMREAD_COLOR)
    mask = cv2.imread(str(data_dir / "masks" / name), cv2.IMREAD_GRAYSCALE)
    if image is None or mask is None:
        raise InputError(f"{data_dir}: cannot read images/{name} or masks/{name}")
    return object_crop(cv2.cvtColor(image, cv2.COLOR_BGR2RGB), mask > 0, size)


def train(dataset: Dataset, task: str, out: Path, epochs: int = 8, seed: int = 0,
          log: Callable[[str], None] = print, show_progress: bool | None = None) -> TrainingResult:
    """Train a :class:`CompactResNet` on ``dataset``, print held-out accuracy per epoch, write the checkpoint to ``out``."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(dataset.targets))
    held_count = max(1, int(round(HOLD_OUT * len(order))))
    held, kept = order[:held_count], order[held_count:]
    model = CompactResNet(len(dataset.classes))
    optimiser = torch.optim.AdamW(model.parameters(), lr=LEARNING_RATE, weight_decay=1e-4)
    steps = max(1, epochs * int(np.ceil(len(kept) / BATCH_SIZE)))
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimiser, max_lr=LEARNING_RATE, total_steps=steps)
    loss_of = nn.CrossEntropyLoss(label_smoothing=0.05)
    result = TrainingResult(train_count=len(kept), held_out_count=len(held))
    show = sys.stderr.isatty() if show_progress is None else show_progress
    for epoch in range(1, epochs + 1):
        model.train()
        rng.shuffle(kept)
        batches = [kept[i : i + BATCH_SIZE] for i in range(0, len(kept), BATCH_SIZE)]
        bar = tqdm(batches, desc=f"epoch {epoch}/{epochs}", unit="batch", file=sys.stderr, disable=not show, leave=False)
        for batch in bar:
            inputs = _augment(to_tensor(dataset.crops[batch]), rng)
            loss = loss_of(model(inputs), torch.from_numpy(dataset.targets[batch]))
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
            bar.set_postfix(loss=f"{loss.item():.3f}")
        accuracy = evaluate(model, dataset.crops[held], dataset.targets[held])
        result.held_out_accuracy.append(accuracy)
        log(f"epoch {epoch}/{epochs}: held-out accuracy {accuracy:.3f} ({len(held)} samples)")
    training = {"epochs": epochs, "seed": seed, "train_samples": len(kept), "held_out_samples": len(held),
                "held_out_accuracy": result.held_out_accuracy[-1] if result.held_out_accuracy else None}
    save_checkpoint(out, model, task, dataset.family, dataset.classes, dataset.crops[held[0]], training)
    return result


def _augment(inputs: torch.Tensor, rng: np.random.Generator) -> torch.Tensor:
    """Mirror half the batch left-right and jitter brightness: a photo's object may face either way."""
    flip = torch.from_numpy(rng.random(len(inputs)) < 0.5)
    inputs = torch.where(flip[:, None, None, None], inputs.flip(3), inputs)
    gain = torch.from_numpy(rng.uniform(0.75, 1.25, size=(len(inputs), 1, 1, 1))).float()
    return (inputs * gain).clamp(0.0, 1.0)


def evaluate(model: nn.Module, crops: np.ndarray, targets: np.ndarray) -> float:
    """Share of ``crops`` whose most probable class is the target."""
    model.eval()
    correct = 0
    with torch.no_grad():
        for start in range(0, len(crops), 256):
            predicted = model(to_tensor(crops[start : start + 256])).argmax(dim=1).numpy()
            correct += int((predicted == targets[start : start + 256]).sum())
    return correct / max(1, len(crops))
