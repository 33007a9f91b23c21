"""The KKT solve of the compiled beam contact loop (``solvers.beam._kkt_solve``) on every Python
the project claims (issue #31).

numba 0.68 cannot compile a ``try`` written inside a ``numba.objmode`` block on Python 3.12 and
3.13 ("POP_BLOCK peephole failed"), so every beam contact solve (``skisnow solve``, the service)
failed there. The kernel now calls a plain-Python helper from that block. These tests compile and
run both paths of the kernel (numba's LAPACK for small active sets, numpy's in object mode for
large ones) and the singular case of each; CI runs them on 3.11, 3.12 and 3.13
(``scripts/ci_python_versions.sh``). The last test keeps the pattern out of every compiled
kernel, whatever the Python running the tests.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from skisnow.solvers import beam as B
from test_beam_compiled import _assert_same, _beams

REPO = Path(__file__).resolve().parents[2]
N_NODES = 40


def _system(seed: int = 3):
    """A well-posed KKT system of N_NODES nodes: symmetric positive definite flexibility [m/N],
    unloaded gap and load deflection [m], lever arms [m], load 400 N."""
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((N_NODES, N_NODES))
    g_mat = (a @ a.T / N_NODES + np.eye(N_NODES)) * 1e-6
    c = rng.uniform(0.0, 1e-3, N_NODES)
    xs = np.linspace(-0.9, 0.9, N_NODES)
    g_load = rng.uniform(-1e-4, 0.0, N_NODES)
    return g_mat, c, xs, g_load, 400.0


@pytest.mark.parametrize("compliance", [0.0, 1e-7])
def test_large_set_is_numpys_solve_bit_for_bit(compliance):
    """More than _COMPILED_SOLVE_MAX_NODES nodes: the object-mode path, numpy's solve of the
    reference loop's KKT system, identical to the last bit."""
    g_mat, c, xs, g_load, load_n = _system()
    idx = np.arange(3, N_NODES, 2, dtype=np.int64)
    assert idx.size > B._COMPILED_SOLVE_MAX_NODES
    r, a, b, ok = B._kkt_solve(g_mat, c, xs, g_load, load_n, compliance, idx)
    kkt, rhs = B._kkt_system(g_mat, c, xs, g_load, load_n, compliance, idx)
    sol = np.linalg.solve(kkt, rhs)
    assert ok
    np.testing.assert_array_equal(r, sol[: idx.size])
    assert (a, b) == (sol[-2], sol[-1])


def test_small_set_matches_numpys_solve():
    """At most _COMPILED_SOLVE_MAX_NODES nodes: numba's LAPACK (gesv, as numpy's), which may
    round differently: within 1e-12 of the largest value (cond(KKT) ~1e3 here, a few ulps)."""
    g_mat, c, xs, g_load, load_n = _system()
    idx = np.array([2, 9, 17, 30, 38], dtype=np.int64)
    r, a, b, ok = B._kkt_solve(g_mat, c, xs, g_load, load_n, 0.0, idx)
    kkt, rhs = B._kkt_system(g_mat, c, xs, g_load, load_n, 0.0, idx)
    sol = np.linalg.solve(kkt, rhs)
    assert ok
    got = np.concatenate([r, [a, b]])
    assert np.abs(got - sol).max() <= 1e-12 * np.abs(sol).max()


@pytest.mark.parametrize("m", [5, 20], ids=["compiled-lapack", "object-mode-numpy"])
def test_singular_kkt_is_reported_not_raised(m):
    """All lever arms zero: the moment row of the KKT matrix is zero (exactly singular). Either
    path returns ``ok`` False and the right-hand side, which sends the caller to the reference
    loop (least squares there); the LinAlgError never escapes the kernel. (The former ``try``
    inside the object-mode block did not catch it even on Python 3.11: the LinAlgError of a
    singular large set reached the caller.)"""
    g_mat, c, _, g_load, load_n = _system()
    xs = np.zeros(N_NODES)
    idx = np.arange(m, dtype=np.int64)
    r, a, b, ok = B._kkt_solve(g_mat, c, xs, g_load, load_n, 0.0, idx)
    assert not ok
    assert (a, b) == (0.0, 0.0)
    np.testing.assert_array_equal(r, -c[idx] - g_load[idx])


def test_public_solve_runs_the_object_mode_path_and_matches_the_reference(monkeypatch):
    """A contact set of ~120 nodes (soft contact, 40 kg on demo ski A): the compiled loop goes
    through the object-mode helper and gives the reference loop's answer."""
    calls = []
    helper = B._numpy_kkt_solve

    def counted(kkt, rhs):
        calls.append(kkt.shape[0] - 2)
        return helper(kkt, rhs)

    # the object-mode block looks the helper up in the module at run time
    monkeypatch.setattr(B, "_numpy_kkt_solve", counted)
    beam = _beams("ski-a")[0][1]
    flex = B.BeamFlexibility(beam)
    kw = dict(flexibility=flex, contact_compliance_m_per_n=1e-6)
    new = B.solve_beam_contact(beam, 40 * B.G_STANDARD, -0.1, **kw)
    assert calls and max(calls) > B._COMPILED_SOLVE_MAX_NODES
    ref = B._solve_beam_contact_reference(beam, 40 * B.G_STANDARD, -0.1, **kw)
    assert ref.converged and new.contact.sum() > B._COMPILED_SOLVE_MAX_NODES
    _assert_same(ref, new, "ski-a 40 kg -100 mm s=1e-6")


def _compiled_kernels(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            decorators = [ast.unparse(d) for d in node.decorator_list]
            if any("jit" in d for d in decorators):
                yield node


def test_no_try_inside_an_objmode_block_of_any_compiled_kernel():
    """numba 0.68 on Python 3.12/3.13 fails to compile a ``try`` inside ``numba.objmode``
    ("POP_BLOCK peephole failed"); the exception handling belongs in a plain-Python helper
    called from the block. Every numba kernel of solvers/ and app/ is checked."""
    found, kernels = [], 0
    for path in sorted([*(REPO / "solvers").rglob("*.py"), *(REPO / "app").rglob("*.py")]):
        text = path.read_text()
        if "numba" not in text:
            continue
        for fn in _compiled_kernels(ast.parse(text, str(path))):
            kernels += 1
            for node in ast.walk(fn):
                if isinstance(node, ast.With) and any(
                    "objmode" in ast.unparse(item.context_expr) for item in node.items
                ):
                    found += [
                        f"{path.relative_to(REPO)}:{t.lineno} in {fn.name}"
                        for t in ast.walk(node)
                        if isinstance(t, ast.Try | ast.TryStar)
                    ]
    assert kernels >= 30  # the scan saw the kernels (solvers/beam, flexible, macro, ...)
    assert found == [], "move the try/except into a plain-Python helper:\n" + "\n".join(found)
