"""Typed, frozen configs of an imitation run (torch-free: the command line parses them fast).

:class:`TrainConfig` holds a :class:`DataConfig` and a :class:`ModelConfig`; every field has a
docstring, which is its ``--help`` text in ``ndp il train`` (tyro, :mod:`ndp.runs.cli`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Annotated, Any

from ndp.checks import check_int, plain_numbers
from ndp.runs.cli import HIDDEN, cli

if TYPE_CHECKING:
    from ndp.dmp import DMPConfig

MODEL_KINDS = ("ndp", "cnn", "cnn-dmp")
PAPER_HEAD = (100, 200, 128, 64)
"""The hidden widths of the 2021 release's imitation head: the CNN trunk's 200 features, then an
MLP 100-200-128-64 with ReLU, then the output layer (../shared/docs/ndp-method.md section 5)."""
NETWORKS = ("default", "paper")
"""``ModelConfig.network`` presets: 'default' (a linear head on the 200 trunk features) and
'paper' (the release's NDP imitation network: :data:`PAPER_HEAD`, outputs scaled x1000, N 30,
a_z 25; the other settings are already the release's)."""


@dataclass(frozen=True)
class ModelConfig:
    """Settings of an image-to-trajectory model."""

    kind: Annotated[str, cli(name="model")] = "ndp"
    """Model: 'ndp' (CNN -> (g, w) -> DMP layer), 'cnn' (direct regression of the points) or
    'cnn-dmp' (regression of least-squares DMP parameters)."""
    n_basis: int = 30
    """N, DMP basis functions per coordinate (DMP models)."""
    a_z: float = 25.0
    """DMP spring constant alpha_z (b_z = a_z / 4)."""
    steps: int = 300
    """k, DMP integration steps = trajectory points - 1."""
    feat_dim: int = 200
    """Width of the CNN encoder's last fully connected layer."""
    head_hidden: tuple[int, ...] = field(default_factory=tuple)
    """Hidden widths of the MLP head between the encoder and the outputs (empty: linear)."""
    network: str = "default"
    """A named network: 'default' (the head as head_hidden says; linear when empty) or 'paper'
    (the 2021 release's imitation network: head 100-200-128-64 with ReLU, for any model kind, so
    that NDP, CNN and CNN-DMP can be compared at equal capacity; head_hidden must then be left
    empty or equal)."""
    image_size: int = 28
    """Images are resized to this side before the encoder (the paper: 40 -> 28)."""
    frame: Annotated[float, HIDDEN] = 40.0
    """Side of the pixel frame of the trajectories (goal / point output scaling); taken from
    the data set, not an option."""
    forcing_param: str = "amplitude"
    """DMP forcing output: 'amplitude' (a = w (g - y0)) or 'weights' (w directly)."""
    amp_scale: float = 1000.0
    """Scale of the forcing-amplitude outputs (pixels / s^2)."""
    weight_scale: float = 100.0
    """Scale of the raw weight outputs when forcing_param == 'weights'."""
    fit_ridge: float = 1e-3
    """Ridge of the least-squares DMP fit that makes CNN-DMP's parameter targets."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        if self.kind not in MODEL_KINDS:
            raise ValueError(f"model: expected one of {', '.join(MODEL_KINDS)}, got {self.kind!r}")
        if self.forcing_param not in ("amplitude", "weights"):
            raise ValueError(
                f"forcing_param: expected 'amplitude' or 'weights', got {self.forcing_param!r}"
            )
        for name in ("n_basis", "steps", "feat_dim", "image_size"):
            v = getattr(self, name)
            check_int(name, v, 1)
        for name in ("a_z", "frame", "amp_scale", "weight_scale"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0):
                raise ValueError(f"{name}: expected a number > 0, got {v!r}")
        if any(int(h) < 1 for h in self.head_hidden):
            raise ValueError(f"head_hidden: expected positive widths, got {self.head_hidden!r}")
        object.__setattr__(self, "head_hidden", tuple(int(h) for h in self.head_hidden))
        if self.network not in NETWORKS:
            raise ValueError(
                f"network: expected one of {', '.join(NETWORKS)}, got {self.network!r}"
            )
        if self.network == "paper":
            if self.head_hidden not in ((), PAPER_HEAD):
                raise ValueError(
                    f"head_hidden: the 'paper' network's head is {list(PAPER_HEAD)}; got "
                    f"{list(self.head_hidden)} (give one or the other)"
                )
            object.__setattr__(self, "head_hidden", PAPER_HEAD)

    @property
    def n_points(self) -> int:
        """Trajectory points, steps + 1."""
        return self.steps + 1

    def dmp_config(self) -> DMPConfig:
        """The DMP integrator settings (tau = 1, dt = 1 / steps); amplitude outputs use the
        unscaled forcing term (``scale_by_goal=False``)."""
        from ndp.dmp import DMPConfig

        return DMPConfig(
            n_basis=self.n_basis,
            a_z=self.a_z,
            steps=self.steps,
            scale_by_goal=self.forcing_param != "amplitude",
        )

    def as_dict(self) -> dict[str, Any]:
        """Plain-dict form (JSON-serialisable)."""
        d = asdict(self)
        d["head_hidden"] = list(self.head_hidden)
        return d


@dataclass(frozen=True)
class DataConfig:
    """Which data set and which split."""

    source: Annotated[str, cli(name="data")] = "synthetic"
    """'synthetic', 'pendigits' or a path to a user's .npz file (images [n, H, W],
    trajectories [n, T, 2])."""
    data_dir: str = "data"
    """Cache folder of the synthetic set."""
    n_samples: int = 20000
    """Synthetic set size (the split uses its first n_train + n_test samples)."""
    data_seed: int = 0
    """Seed of the synthetic generator."""
    pendigits_path: str = ""
    """UNIPEN file of Pendigits ('' = ../shared/data/pendigits/pendigits-train)."""
    split: str = "auto"
    """'paper' (shuffle the first n_train + n_test), 'writer' (writer-disjoint), 'auto' (writer
    for Pendigits, paper otherwise) or 'all' (every sample: train on a whole file without a test
    part, or score every sample of a file with ``ndp il eval``)."""
    n_train: int = 10000
    """Training samples of the paper split."""
    n_test: int = 2000
    """Test samples of the paper split."""
    test_fraction: float = 0.2
    """Fraction of writers (writer split) or samples (npz without n_train) held out."""
    split_seed: int = 0
    """Seed of the train / test shuffle."""
    resample: bool = False
    """Resample .npz trajectories of another length to 301 points instead of refusing."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        if self.split not in SPLITS:
            raise ValueError(f"split: expected one of {', '.join(SPLITS)}, got {self.split!r}")
        for name in ("n_samples", "n_train", "n_test"):
            v = getattr(self, name)
            check_int(name, v, 1)
        if not (isinstance(self.test_fraction, (int, float)) and 0 < self.test_fraction < 1):
            raise ValueError(
                f"test_fraction: expected a number in (0, 1), got {self.test_fraction!r}"
            )


SPLITS = ("auto", "paper", "writer", "all")
"""Train / test split kinds of :class:`DataConfig`."""
VAL_SPLITS = ("auto", "samples", "writers")
"""How ``TrainConfig.val_split`` holds out the validation split."""

SAFE_ON_RESUME = ("epochs", "progress", "threads", "tensorboard", "eval_every")
"""TrainConfig fields a resume may change (``epochs`` extends the run); the others are refused."""


@dataclass(frozen=True)
class TrainConfig:
    """Everything that defines a training run (saved as config.json in the run directory)."""

    run_dir: Annotated[str, cli(aliases=("--out",))] = "runs/il"
    """Output folder of the run."""
    data: DataConfig = field(default_factory=DataConfig)
    """Data set and split."""
    model: ModelConfig = field(default_factory=ModelConfig)
    """Model settings."""
    epochs: int = 71
    """Passes over the training split."""
    batch_size: int = 100
    """Samples per Adam step."""
    lr: float = 1e-3
    """Adam learning rate."""
    seed: int = 0
    """Seed of initialisation and batch order."""
    threads: int = 0
    """torch CPU threads (0: leave torch's default)."""
    device: str = "cpu"
    """torch device of the model and the data ('cpu', 'cuda', 'cuda:1', ...)."""
    progress: bool = True
    """Show a tqdm progress bar."""
    tensorboard: bool = True
    """Write TensorBoard event files besides the CSV."""
    eval_every: int = 1
    """Evaluate the test MSE every this many epochs (0: only at the end)."""
    max_train_batches: int = 0
    """Stop each epoch after this many batches (0: all; for smoke tests)."""
    val_fraction: float = 0.0
    """Fraction of the training split held out as a validation split (drawn with
    ``data.split_seed``: the same samples for every model, seed and learning rate); 0: none
    (the paper protocol). With it, every epoch logs ``val/mse_px2``, the lowest one's weights
    are kept in ``best.pt`` (``ndp il eval`` scores them), and the last row's test MSE is the
    best checkpoint's."""
    val_split: str = "auto"
    """How the validation split is held out: 'samples' (a random ``val_fraction`` of the
    training samples), 'writers' (a random ``val_fraction`` of the training writers with all
    their samples; needs writer ids), 'auto' (writers when the test split is writer-disjoint,
    as on Pendigits, so that selection and early stopping score unseen writers like the test;
    else samples). A config saved before this option reads as what it ran with ('samples' over a
    writer-disjoint test split, else 'auto')."""
    patience: int = 0
    """Stop after this many epochs without a lower validation MSE (0: train all ``epochs``,
    which is then the maximum); needs ``val_fraction`` > 0."""
    encoder_init: str = ""
    """Pretraining option: a run directory / checkpoint whose CNN encoder weights initialise
    this model's encoder ('' = train from scratch)."""

    def __post_init__(self) -> None:
        plain_numbers(self)
        if isinstance(self.data, dict):
            object.__setattr__(self, "data", DataConfig(**self.data))
        if isinstance(self.model, dict):
            object.__setattr__(self, "model", ModelConfig(**self.model))
        for name, low in (("epochs", 1), ("batch_size", 1), ("threads", 0), ("seed", 0)):
            v = getattr(self, name)
            check_int(name, v, low)
        for name in ("eval_every", "max_train_batches"):
            v = getattr(self, name)
            check_int(name, v, 0)
        if not (isinstance(self.lr, (int, float)) and math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr: expected a finite number > 0, got {self.lr!r}")
        if not (isinstance(self.val_fraction, (int, float)) and 0 <= self.val_fraction < 1):
            raise ValueError(
                f"val_fraction: expected a number in [0, 1), got {self.val_fraction!r}"
            )
        if self.val_split not in VAL_SPLITS:
            raise ValueError(
                f"val_split: expected one of {', '.join(VAL_SPLITS)}, got {self.val_split!r}"
            )
        check_int("patience", self.patience, 0)
        if self.patience > 0 and self.val_fraction == 0:
            raise ValueError("patience: early stopping needs a validation split (--val-fraction)")
        if not self.run_dir:
            raise ValueError("run_dir: expected a directory, got ''")
        import torch

        try:
            torch.device(self.device)
        except RuntimeError:
            raise ValueError(
                f"device: expected a torch device such as 'cpu' or 'cuda', got {self.device!r}"
            ) from None

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable form."""
        d = dataclasses.asdict(self)
        d["model"] = self.model.as_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrainConfig:
        """Inverse of :meth:`as_dict` (unknown keys raise ValueError)."""
        d = dict(d)
        if "val_split" not in d:
            # Saved before the option, when validation always drew samples: that is 'auto'
            # except over a writer-disjoint test split, where 'auto' now holds out writers.
            data = d.get("data", {})
            writer = data.get("split") == "writer" or (
                data.get("split", "auto") == "auto" and data.get("source") == "pendigits"
            )
            d["val_split"] = "samples" if writer else "auto"
        try:
            d["data"] = DataConfig(**d.get("data", {}))
            d["model"] = ModelConfig(**d.get("model", {}))
            return cls(**d)
        except TypeError as exc:
            raise ValueError(f"config: {exc}") from None


def data_task_name(data: dict[str, object]) -> str:
    """The task name of an imitation run in tables and run.json, from its ``data`` config (as
    in config.json): ``synthetic`` (the paper's 10,000 training digits), ``synthetic-<n>``
    (another training size), else the source (``pendigits``, ``npz``)."""
    src = str(data.get("source", "synthetic"))
    if src == "synthetic" and data.get("split") in ("paper", "auto"):
        n = int(str(data.get("n_train", 10000)))
        return "synthetic" if n == 10000 else f"synthetic-{n}"
    return src
