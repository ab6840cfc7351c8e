"""Imitation learning: from an image of a digit to the 301-point pen trajectory that writes it.

Modules, in the order the data flows:

- :mod:`ndp.il.synthetic`  the S-MNIST-equivalent generator (docs/smnist-spec.md)
- :mod:`ndp.il.data`       :class:`ndp.il.data.DigitData` schema, synthetic cache, Pendigits and
  ``.npz`` loaders, paper and writer-disjoint splits
- :mod:`ndp.il.models`     NDP, CNN and CNN-DMP on one MNIST-style CNN encoder
- :mod:`ndp.il.train`      trainer (checkpoints, resume, CSV + TensorBoard) and evaluation
- :mod:`ndp.il.metrics`    per-sample MSE in px^2, DTW, the prediction picture
- :mod:`ndp.il.realism`    features for class-realism checks with classifiers of real digits
- :mod:`ndp.il.cli`        ``ndp il train`` / ``ndp il eval``
- :mod:`ndp.il.demo`       :func:`ndp.il.demo.run_il_demo`, the short run of ``ndp demo``
"""
