"""Camber network training (docs/physics.md §4 step 2): fitting the per-ski network in PyTorch.

- :mod:`.data`: training data checks, the split by load case, arrays from a ski file (numpy).
- :mod:`.model`: the network in torch (layers, forward pass, smoother) and the fold of an
  ensemble into one MLP of the stored schema.
- :mod:`.fit`: :func:`~.fit.train_camber_network`, the recipe (loss, Adam then L-BFGS, early
  stopping, determinism).
- :mod:`.check`: accuracy of a network: held-out metrics, beam truth, contact area (macro BEM).
- :mod:`.files`: the ``network`` group of a ski's HDF5 file (atomic write, read).

Training needs PyTorch (``pip install 'skisnow[train]'``); torch is imported lazily inside the
fitting functions, so importing this package (and the service, and inference in
:mod:`solvers.camber`) does not import torch (tests/training/test_training_imports.py).

May import :mod:`skisnow.app.storage`, :mod:`skisnow.solvers` and the top-level modules of
``app/`` (settings, units, presets, errors); never ``api``, ``web``, ``jobs`` or ``commands``.
The command ``skisnow train-camber`` is :mod:`skisnow.app.commands.train_camber`.
"""
