"""The MNIST-style convolutional encoder of the paper's imitation experiment.

Architecture (ndp-method.md section 5): conv 20 5x5 -> ReLU -> max-pool 2 -> conv 50 5x5 -> ReLU
-> max-pool 2 -> flatten (50 x 4 x 4 = 800) -> fc 800 -> ``out_dim`` (200) -> ReLU.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


class MnistCNN(nn.Module):
    """Image encoder for 28 x 28 single-channel images.

    Inputs of another size are bilinearly resized to ``image_size`` first, so a 40 x 40 digit
    image can be fed directly (the paper resizes 40 x 40 to 28 x 28).

    Args:
        out_dim: feature size of the last fully connected layer (200 in the paper).
        image_size: side length the convolutions expect (28).
        in_channels: image channels (1).

    Shapes:
        forward: ``images`` [B, H, W] or [B, C, H, W] -> features [B, out_dim].
    """

    def __init__(self, out_dim: int = 200, image_size: int = 28, in_channels: int = 1) -> None:
        super().__init__()
        if image_size < 16:
            raise ValueError(f"image_size must be >= 16 for two 5x5 convs and pools: {image_size}")
        self.out_dim = int(out_dim)
        self.image_size = int(image_size)
        self.in_channels = int(in_channels)
        self.conv1 = nn.Conv2d(in_channels, 20, kernel_size=5)
        self.conv2 = nn.Conv2d(20, 50, kernel_size=5)
        side = ((image_size - 4) // 2 - 4) // 2
        self.flat_dim = 50 * side * side
        self.fc = nn.Linear(self.flat_dim, self.out_dim)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        """Encode ``images`` [B, H, W] or [B, C, H, W] (values about [0, 1]) to [B, out_dim]."""
        x = images
        if x.dim() == 3:
            x = x.unsqueeze(1)
        if x.dim() != 4 or x.shape[1] != self.in_channels:
            raise ValueError(
                f"expected images [B, H, W] or [B, {self.in_channels}, H, W], got {tuple(x.shape)}"
            )
        if x.shape[-2:] != (self.image_size, self.image_size):
            x = F.interpolate(
                x, size=(self.image_size, self.image_size), mode="bilinear", align_corners=False
            )
        x = F.max_pool2d(F.relu(self.conv1(x)), 2)
        x = F.max_pool2d(F.relu(self.conv2(x)), 2)
        x = x.flatten(1)
        return F.relu(self.fc(x))
