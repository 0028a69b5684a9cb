"""The plate's sparse pattern built from node pairs equals the textbook one built from every
element's DOF pairs (np.unique of (row, column), the construction it replaced)."""
import numpy as np
import pytest

from engine.plate.mesh import Mesh
from engine.plate.sparse import Pattern


def _dof_pair_pattern(mesh: Mesh):
    """(indptr, indices, position of each element entry) from the unique DOF pairs."""
    dofs = mesh.element_dofs
    rows = np.repeat(dofs, 80, axis=1).ravel()
    cols = np.tile(dofs, (1, 80)).ravel()
    ukey, inv = np.unique(rows.astype(np.int64) * mesh.n_dof + cols, return_inverse=True)
    r, c = np.divmod(ukey, mesh.n_dof)
    return np.searchsorted(r, np.arange(mesh.n_dof + 1)), c, inv.reshape(dofs.shape[0], -1)


@pytest.mark.parametrize("mesh", [Mesh.default(0.3, 0.2, 2e-3), Mesh.default(0.58, 0.215, 6e-3, n=5)])
def test_node_pair_pattern_equals_the_dof_pair_pattern(mesh):
    pat = Pattern.build(mesh)
    indptr, indices, pos = _dof_pair_pattern(mesh)
    assert np.array_equal(pat.indptr, indptr)
    assert np.array_equal(pat.indices, indices)
    assert np.array_equal(pat.elem_pos, pos)
    # every element entry scatters to its position: scatter @ (local index + 1) of one type
    # reproduces, at each position, the sum of the local indices landing there
    fr, fc = np.repeat(np.arange(mesh.n_dof), np.diff(indptr)) % 5, indices % 5
    assert np.array_equal(pat.cross, (fr < 2) != (fc < 2))
    assert pat.scatter.shape[0] == indices.size and pat.scatter.nnz == pos.size
    hit = np.zeros(indices.size)
    np.add.at(hit, pos.ravel(), 1.0)
    assert np.array_equal(np.asarray(pat.scatter.sum(axis=1)).ravel(), hit)
