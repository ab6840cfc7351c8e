"""Neural-network building blocks shared by RL and imitation learning.

- :class:`MLP`: fully connected network with orthogonal initialisation.
- :class:`MnistCNN`: the paper's MNIST-style convolutional encoder (28 x 28 image -> features).
"""

from ndp.nets.cnn import MnistCNN
from ndp.nets.mlp import MLP, activation_layer

__all__ = ["MLP", "MnistCNN", "activation_layer"]
