"""flatten never ends in a traceback: solver failures fall back, or end in one line naming the mesh and the cause."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grid_mesh
from test_conformal_maps import check_subdivision

from workbench import sparse
from workbench.cli import main
from workbench.conformal.cetm import NewtonOptions
from workbench.conformal.flatten import DEFAULT_MIN_PRINT_MM, FlattenOptions, flatten
from workbench.mesh.io import format_obj


def grid_without_corner_triangle():
    # a 10 x 8 grid with one corner triangle removed: still a disc, but vertex 0 is
    # left with a single face (it was seen to diverge to NaN and end in a PARDISO traceback)
    P, F = grid_mesh(10, 8, np.random.default_rng(0), jitter=0.0)
    V = np.column_stack([P * [90.0, 70.0], np.zeros(len(P))])
    return V, F[1:]


def test_grid_without_its_corner_triangle_flattens():
    V, F = grid_without_corner_triangle()
    r = flatten(V, F)
    check_subdivision(r, V, F)
    assert r.newton.residual_rad <= 1e-9


def test_a_failing_factorisation_falls_back(monkeypatch):
    # the first backend reports a zero pivot (as PARDISO did, error -4): the solve goes
    # on with the portable backend and gives the same map
    V, F = grid_without_corner_triangle()
    ref = flatten(V, F)
    real = sparse.SPDSolver.__init__

    def failing(self, U, backend=None):
        if backend is None:
            raise RuntimeError("The Pardiso solver failed with error code -4")
        real(self, U, backend)

    monkeypatch.setattr(sparse.SPDSolver, "__init__", failing)
    r = flatten(V, F)
    np.testing.assert_allclose(r.uv, ref.uv, atol=1e-9 * ref.width_mm)


def test_when_every_factorisation_fails_one_line_names_the_mesh(monkeypatch, capsys, tmp_path):
    V, F = grid_without_corner_triangle()
    path = tmp_path / "g.obj"
    path.write_bytes(format_obj(V, F))

    def failing(self, U, backend=None):
        raise RuntimeError("zero pivot")

    monkeypatch.setattr(sparse.SPDSolver, "__init__", failing)
    out = tmp_path / "o"
    assert main(["flatten", str(path), "--out", str(out), "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "could not be factorised" in err[0]
    assert not out.exists()


def test_no_convergence_is_one_line(monkeypatch, capsys, tmp_path):
    V, F = grid_without_corner_triangle()
    path = tmp_path / "g.obj"
    path.write_bytes(format_obj(V, F))
    monkeypatch.setattr(
        "workbench.commands.flatten.FlattenOptions",
        lambda **kw: FlattenOptions(**kw, newton=NewtonOptions(max_iterations=1)),
    )
    out = tmp_path / "o"
    assert main(["flatten", str(path), "--out", str(out), "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and "did not converge in 1 Newton steps" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("unit", [1e-3, 1e3])
def test_solve_does_not_depend_on_the_unit(unit):
    V, F = grid_without_corner_triangle()
    # a grid has cocircular quads: which diagonal round-off picks may differ with the
    # unit, but the map does not (both diagonals give the same metric)
    # (the print resolution is physical: it scales with the part, the map does not)
    a = flatten(V, F)
    b = flatten(V * unit, F, FlattenOptions(min_print_mm=DEFAULT_MIN_PRINT_MM * unit))
    n = len(V)
    assert np.abs(b.uv[:n] / unit - a.uv[:n]).max() <= 1e-9 * a.width_mm
