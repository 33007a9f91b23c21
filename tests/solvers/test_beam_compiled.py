"""The compiled active-set loop of solvers.beam against the numpy reference loop.

Both loops visit the same active sets in the same order and solve the same KKT systems (the
contact sets and iteration counts are compared exactly), so the answers agree to rounding. Small
sets are solved by the LAPACK numba links, the reference by numpy's: on some processors the two
round the same system differently, by up to cond(KKT) × eps of the largest value (measured
4.6e-12 of the largest reaction on the identified ski-a, 150 kg at −100 mm, on this project's
CI machine of 2026-11-26, where an earlier machine gave bit-for-bit equality). The bound is
RTOL = 1e-10: far below any physical significance, far above the rounding.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from skisnow.app.storage.skis import identified_beam, read_ski
from skisnow.solvers.beam import (
    G_STANDARD,
    BeamFlexibility,
    BeamSki,
    _solve_beam_contact_reference,
    solve_beam_contact,
)

REPO = Path(__file__).resolve().parents[2]
LOADS_KG = (5.0, 40.0, 150.0)
POSITIONS_MM = (-300.0, -100.0, 100.0)
#: stiffest stage of the identification's continuation is ~1e-7 m/N (ℓ = 2 nodes)
COMPLIANCES = (0.0, 1e-7)
#: relative agreement of reactions, gaps and displacements (rounding of two LAPACK builds)
RTOL = 1e-10


def _beams(name: str) -> list[tuple[str, BeamSki]]:
    rec = read_ski(REPO / "tables" / "skis" / f"{name}.h5")
    out = [("beam", rec.beam)]
    ident = identified_beam(rec.identified)
    if ident is not None:
        out.append(("identified", ident))
    return out


def _assert_same(ref, new, label: str) -> None:
    assert new.converged == ref.converged, label
    assert new.iterations == ref.iterations, label
    assert new.message == ref.message, label
    np.testing.assert_array_equal(new.contact, ref.contact, err_msg=label)
    for field in ("reaction_n", "gap_m", "displacement_m"):
        a, b = getattr(ref, field), getattr(new, field)
        scale = max(float(np.abs(a).max()), 1e-300)
        assert np.abs(a - b).max() <= RTOL * scale, (label, field, np.abs(a - b).max() / scale)
    for field in ("force_residual", "moment_residual", "residual"):
        assert abs(getattr(new, field) - getattr(ref, field)) <= RTOL, (label, field)


@pytest.mark.parametrize("name", ["ski-a", "ski-b"])
def test_compiled_loop_matches_reference_on_demo_skis(name):
    for label, beam in _beams(name):
        flex = BeamFlexibility(beam)
        for compliance in COMPLIANCES:
            warm = None  # contacts of the previous case: a warm start, good or poor
            for kg in LOADS_KG:
                for pos_mm in POSITIONS_MM:
                    f, xf = kg * G_STANDARD, pos_mm * 1e-3
                    for start in (None, warm):
                        kw = dict(
                            flexibility=flex,
                            initial_contacts=start,
                            contact_compliance_m_per_n=compliance,
                        )
                        ref = _solve_beam_contact_reference(beam, f, xf, **kw)
                        new = solve_beam_contact(beam, f, xf, **kw)
                        assert ref.converged
                        tag = f"{name} {label} {kg} kg {pos_mm} mm s={compliance} {start is None}"
                        _assert_same(ref, new, tag)
                    warm = np.flatnonzero(ref.reaction_n > 0)


def test_compiled_loop_matches_reference_when_not_converged():
    """Running out of iterations gives the same unconverged state and message."""
    beam = _beams("ski-b")[0][1]
    flex = BeamFlexibility(beam)
    for max_it in (0, 1, 3):
        kw = dict(flexibility=flex, max_iterations=max_it)
        ref = _solve_beam_contact_reference(beam, 75 * G_STANDARD, 0.0, **kw)
        new = solve_beam_contact(beam, 75 * G_STANDARD, 0.0, **kw)
        assert not ref.converged
        _assert_same(ref, new, f"max_iterations={max_it}")


def test_flexibility_columns_are_the_transpose():
    beam = _beams("ski-a")[0][1]
    flex = BeamFlexibility(beam)
    cols = flex.columns
    assert cols.flags.c_contiguous
    np.testing.assert_array_equal(cols, flex.matrix.T)
    assert flex.columns is cols


class _StoredMatrix(BeamFlexibility):
    """A flexibility whose ``matrix`` is a C-contiguous copy: the form stored until 2026-11-29,
    when the matrix and its columns were both built (61 MB at 2001 nodes)."""

    @property
    def matrix(self) -> np.ndarray:
        return np.ascontiguousarray(self.columns.T)


@pytest.mark.parametrize("name", ["ski-a", "ski-b"])
def test_the_flexibility_stores_its_columns_only_and_answers_as_the_stored_matrix(name):
    """BeamFlexibility keeps the columns only (N² × 8 bytes), ``matrix`` a read-only transposed
    view of the same values; every contact solve (both compliances, a warm start, an
    unconverged one, the compiled loop and the reference loop on the view) gives the answer of
    a flexibility that stores the matrix C-contiguous, bit for bit."""
    for label, beam in _beams(name):
        flex = BeamFlexibility(beam)
        stored = _StoredMatrix(beam)
        n = beam.positions_m.size
        assert flex.columns.nbytes == n * n * 8
        assert [k for k, v in vars(flex).items() if isinstance(v, np.ndarray)] == ["_columns"]
        assert flex.matrix.base is flex.columns and not flex.matrix.flags.writeable
        np.testing.assert_array_equal(flex.matrix, stored.matrix)
        np.testing.assert_array_equal(flex.load_column(-0.123), stored.load_column(-0.123))
        for kg, mm, comp, it in (
            (40.0, -100.0, 0.0, 200),
            (150.0, 100.0, 1e-7, 200),
            (75, 0, 0, 2),
        ):
            kw = dict(contact_compliance_m_per_n=comp, max_iterations=it)
            a = solve_beam_contact(beam, kg * G_STANDARD, mm / 1e3, flexibility=stored, **kw)
            b = solve_beam_contact(beam, kg * G_STANDARD, mm / 1e3, flexibility=flex, **kw)
            warm = solve_beam_contact(
                beam,
                kg * G_STANDARD,
                mm / 1e3,
                flexibility=flex,
                initial_contacts=np.flatnonzero(a.contact),
                **kw,
            )
            assert b.iterations == a.iterations and b.converged == a.converged
            for field in ("reaction_n", "gap_m", "displacement_m"):
                np.testing.assert_array_equal(getattr(b, field), getattr(a, field))
            np.testing.assert_array_equal(warm.contact, a.contact)
        ref_stored = _solve_beam_contact_reference(beam, 40 * G_STANDARD, -0.1, flexibility=stored)
        ref_view = _solve_beam_contact_reference(beam, 40 * G_STANDARD, -0.1, flexibility=flex)
        np.testing.assert_array_equal(ref_view.contact, ref_stored.contact)
        _assert_same(ref_stored, ref_view, f"{name} {label} reference loop on the view")


@pytest.mark.parametrize("name", ["ski-a", "ski-c"])
@pytest.mark.parametrize("stride", [1, 2, 3])
def test_compiled_flexibility_is_the_reference_bit_for_bit(name, stride):
    """BeamFlexibility's compiled matrix (and its transpose, the contact solve's columns) is
    the numpy reference's bit for bit: the same sums in the same order, no fused multiply-add
    (numba leaves contraction off without fastmath). The identification's forward fits build
    one per evaluation (at 2001 nodes 0.3-1 s in numpy, ~0.05 s compiled); a beam that differs
    in the last bit can end a fit in another basin, so agreement to rounding is not enough.
    Design and identified beams, every node and the coarse stages' every 2nd and 3rd."""
    from skisnow.solvers.beam import _flexibility_reference

    for label, beam in _beams(name):
        b = BeamSki(
            beam.positions_m[::stride],
            beam.bending_stiffness_nm2[::stride],
            beam.unloaded_gap_m[::stride],
        )
        flex = BeamFlexibility(b)
        ref = _flexibility_reference(b.positions_m, b.bending_stiffness_nm2, b.spacing_m)
        np.testing.assert_array_equal(flex.matrix, ref, err_msg=f"{name} {label} {stride}")
        np.testing.assert_array_equal(flex.columns, ref.T, err_msg=f"{name} {label} {stride}")
        assert flex.columns.flags.c_contiguous


def test_compiled_double_integral_is_the_reference_bit_for_bit():
    """solvers.beam_fit.double_integral (per case and evaluation of a forward fit: the
    deflection of each stiffness hat's moment; the variable-projection start's columns, with
    the spacings per interval) runs compiled for float64 rows and a float spacing or the
    (N − 1,) spacings, bit-identical to the numpy reference; other inputs run the reference
    itself."""
    from skisnow.solvers.beam_fit import _double_integral_reference, double_integral

    rng = np.random.default_rng(11)
    for shape in ((39, 2001), (2001,), (3, 1001), (1, 2), (2,)):
        kappa = rng.normal(size=shape) * 1e-3
        for dx in (1e-3, 2.0000000000000018e-3, 3e-3):
            got, ref = double_integral(kappa, dx), _double_integral_reference(kappa, dx)
            assert got.shape == ref.shape
            np.testing.assert_array_equal(got, ref, err_msg=f"{shape} {dx}")
    strided = rng.normal(size=(2001, 39)).T  # not C-contiguous
    got, ref = double_integral(strided, 1e-3), _double_integral_reference(strided, 1e-3)
    np.testing.assert_array_equal(got, ref)
    assert got.strides == ref.strides
    for spacings in (np.full(2000, 1e-3), np.diff(np.linspace(-0.9, 1.1, 2001))):
        got, ref = double_integral(strided, spacings), _double_integral_reference(strided, spacings)
        np.testing.assert_array_equal(got, ref)
        # the reference's layout too (a product with a transposed array rounds differently)
        assert got.strides == ref.strides
    for shape in ((39, 1001), (1001,), (1, 2)):
        kappa = rng.normal(size=shape) * 1e-3
        spacings = 1e-3 * (1.0 + 0.1 * rng.random(shape[-1] - 1))  # uneven
        got, ref = double_integral(kappa, spacings), _double_integral_reference(kappa, spacings)
        np.testing.assert_array_equal(got, ref, err_msg=f"{shape} uneven")
    kappa3 = rng.normal(size=(2, 3, 11))  # three dimensions: the reference itself
    np.testing.assert_array_equal(
        double_integral(kappa3, 1e-3), _double_integral_reference(kappa3, 1e-3)
    )


def test_compiled_flat_supports_are_the_reference():
    """solvers.beam.flat_supports (the unloaded ski's two supports on the flat; every forward
    fit evaluation calls it) compiled names the nodes the Python reference names: design and
    identified cambers, the same with 3 µm noise, rough random cambers, a flat one, short skis."""
    from skisnow.solvers.beam import _flat_supports_reference, flat_supports

    rng = np.random.default_rng(5)
    cambers = []
    for name in ("ski-a", "ski-b"):
        for _, beam in _beams(name):
            cambers.append((beam.positions_m, beam.unloaded_gap_m))
            cambers.append((beam.positions_m, beam.unloaded_gap_m + rng.normal(0, 3e-6, 2001)))
    x = cambers[0][0]
    cambers += [(x, rng.normal(0.0, 1e-3, x.size)) for _ in range(20)]
    cambers += [(x[:n], rng.normal(0.0, 1.0, n)) for n in (2, 3, 4, 7, 50)]
    cambers.append((x, np.zeros_like(x)))
    for xs, c in cambers:
        got = flat_supports(xs, c)
        assert got == _flat_supports_reference(xs, c)
        assert all(type(i) is int for i in got)
