"""Camber network training (method.md §4 step 2): PyTorch fitting of the per-ski network.

Training needs PyTorch (``pip install 'skisnow[train]'``); torch is imported lazily inside the
fitting functions, so importing this package (and the service, and inference in
:mod:`solvers.camber`) does not import torch.

May import :mod:`skisnow.app.storage`, :mod:`skisnow.solvers` and the top-level modules of
``app/`` (settings, units, presets, errors); never ``api``, ``web`` or ``commands``.
"""
