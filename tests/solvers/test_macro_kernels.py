"""The macro solver's kernel transforms are built once per window shape and pixel size, not per
snow modulus (issue #29: every request has its own modulus, and rebuilding them cost ~1 ms per
solve)."""

from __future__ import annotations

import numpy as np
from skisnow.solvers import macro
from skisnow.solvers.elastic import NonPeriodicHalfSpace


def test_a_new_modulus_reuses_the_kernel_and_gives_the_exact_operator(monkeypatch):
    calls = []
    real = macro.love_rectangle_influence

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(macro, "love_rectangle_influence", counting)
    macro._halfspace.cache_clear()
    macro._unit_line_coupling.cache_clear()
    shape, dx, dy = (37, 6), 4e-3, 5.5e-3
    p = np.random.default_rng(0).uniform(0, 1e5, shape)
    for e in (1.1e8, 2.3e8, 4.7e8):
        op = macro._halfspace(shape, dx, dy, e)
        ref = NonPeriodicHalfSpace(shape, (dx, dy), e, workers=1)
        np.testing.assert_allclose(op.displacement(p), ref.displacement(p), rtol=1e-12, atol=0)
        assert op.self_compliance == np.float64(ref.self_compliance) or np.isclose(
            op.self_compliance, ref.self_compliance, rtol=1e-14
        )
    assert len(calls) == 1  # one kernel for three moduli
    assert macro._unit_line_coupling.cache_info().maxsize == macro.UNIT_KERNELS_MAX
