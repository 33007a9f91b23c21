"""Number lists of the JSON answers: values rounded to significant digits exactly as formatting
them as text does, ``None`` where not finite (:func:`finite_list`). Imports numpy only."""

from __future__ import annotations

import numpy as np

__all__ = ["finite_list"]


def finite_list(a: np.ndarray, scale: float = 1.0, digits: int = 6) -> list[float | None]:
    """``a · scale`` rounded to ``digits`` significant digits, ``None`` where not finite (after
    scaling, so that an overflow never reaches the JSON encoder as inf): for
    every value exactly ``float(f"{v:.{digits}g}")`` (tests/service/test_service_rounding.py),
    without
    formatting every value as text (the answer's distributions hold a few thousand values).

    The decimal ``m · 10^k`` (``m`` an integer of ``digits`` digits) is rounded to the nearest
    float in one correctly rounded multiplication or division by the exact power ``10^|k|``
    (|k| ≤ 22), which is what parsing its text does. Where ``m`` itself is uncertain (the scaled
    value within 1e-6 of a rounding tie, or a magnitude outside that range) the value is
    formatted as text."""
    v = np.asarray(a, dtype=float).ravel() * scale
    out = v.copy()
    finite = np.isfinite(v)
    nonzero = finite & (v != 0)
    slow = np.zeros(v.shape, dtype=bool)
    if nonzero.any():
        w = v[nonzero]
        k = np.floor(np.log10(np.abs(w))).astype(int) - (digits - 1)
        ok = (np.abs(k) <= 22) & (digits <= 15)
        kk = np.where(ok, k, 0)
        up = np.power(10.0, np.abs(kk))
        r = np.where(kk >= 0, w / up, w * up)  # w / 10^k (exact power)
        m = np.rint(r)
        tie = np.abs(np.abs(r - np.floor(r)) - 0.5) < 1e-6
        ok &= ~tie & (np.abs(m) < 10.0 ** (digits + 1))
        out[nonzero] = np.where(kk >= 0, m * up, m / up)
        slow[np.flatnonzero(nonzero)[~ok]] = True
    spec = f".{digits}g"
    for i in np.flatnonzero(slow):
        out[i] = float(format(float(v[i]), spec))
    values = out.tolist()
    if finite.all():
        return values
    return [x if f else None for x, f in zip(values, finite.tolist(), strict=True)]
