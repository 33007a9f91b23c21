"""Evidence: the benchmarks of ``skisnow bench`` and the report ``skisnow report paper-case``.

One module per stage: :mod:`.micro` (micro solver against the FFT floor), :mod:`.peers`
(work-precision against peer solvers), :mod:`.macro` (macro solve, bending ski, identification),
:mod:`.loadtest` (rendering of ``scripts/loadtest.py`` stages), ``accuracy_*`` (error against a
converged reference versus time) and ``paper_case*`` (the published 2 skis × 2 grinds study).
:mod:`.writer` is the one place that writes ``docs/`` and ``docs/bench/`` (never into
``site-packages``: :func:`app.storage.common.docs_dir`).

May import: :mod:`app.service`, :mod:`app.storage`, the top-level modules of ``app`` and
:mod:`solvers`. Imported by the ``bench`` and ``report`` commands (:mod:`app.commands`) and
``scripts/loadtest.py``; stage modules never import the writer, so the writer can import every
stage's renderer without a circle.
"""
