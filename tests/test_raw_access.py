"""backends/raw.py: array access without wraparound reads and writes exactly the element
NumPy's indexing names, whatever the layout, dtype or index type, and nothing else."""
import numba
import numpy as np
import pytest
from numba.core.errors import TypingError

from bondem import bench
from bondem.backends import cpu, raw
from bondem.backends.raw import get, get2, get3, put, put3
from bondem.physics._registry import compile_functions


@numba.njit
def _copy_through(source, target, rows):
    """target[rows[k]] = source[rows[k]] + k through get and put."""
    for k in range(rows.shape[0]):
        put(target, rows[k], get(source, rows[k]) + k)


@numba.njit
def _pairs_sum(pairs, rows):
    total = 0
    for k in range(rows.shape[0]):
        total += get2(pairs, rows[k], 0) * 1000 + get2(pairs, rows[k], 1)
    return total


@numba.njit
def _rows_through(source, target, rows, columns):
    """target[rows[k], columns[k]] = 2 source[rows[k], columns[k]] through get3 and put3."""
    for k in range(rows.shape[0]):
        put3(target, rows[k], columns[k], 2.0 * get3(source, rows[k], columns[k]))


def test_get_and_put_address_the_element_numpy_names():
    rng = np.random.default_rng(11)
    source = rng.random(40)
    rows = rng.permutation(40)[:17].astype(np.int32)      # a narrower index type
    target = np.full(40, -1.0)
    _copy_through(source, target, rows)
    expected = np.full(40, -1.0)
    expected[rows] = source[rows] + np.arange(17)
    assert np.array_equal(target, expected)
    # a strided view (layout A): every third element, written through the view only
    base = np.zeros(120)
    view = base[::3]
    _copy_through(source, view, rows.astype(np.int64))
    assert np.array_equal(view[rows], source[rows] + np.arange(17))
    untouched = np.setdiff1d(np.arange(40), rows)
    assert not view[untouched].any() and not base[1::3].any() and not base[2::3].any()


def test_get_and_put_keep_booleans_as_bytes():
    flags = np.zeros(9, dtype=np.bool_)

    @numba.njit
    def flip(flags, i):
        put(flags, i, not get(flags, i))
        return get(flags, i)

    assert flip(flags, 4) and not flip(flags, 4) and flip(flags, 7)
    assert flags.tolist() == [False] * 7 + [True, False]


def test_get2_reads_rows_of_any_layout():
    rng = np.random.default_rng(5)
    pairs = rng.integers(0, 999, size=(30, 2))
    rows = rng.integers(0, 30, 12)
    expected = int((pairs[rows, 0] * 1000 + pairs[rows, 1]).sum())
    assert _pairs_sum(pairs, rows) == expected
    fortran = np.asfortranarray(pairs)
    assert _pairs_sum(fortran, rows) == expected
    assert _pairs_sum(pairs.T.copy().T, rows) == expected


def test_get3_and_put3_address_row_and_column_of_rows_of_three():
    rng = np.random.default_rng(8)
    source = rng.random((25, 3))
    target = np.zeros((25, 3))
    rows = rng.integers(0, 25, 20)
    columns = rng.integers(0, 3, 20)
    _rows_through(source, target, rows, columns)
    expected = np.zeros((25, 3))
    expected[rows, columns] = 2.0 * source[rows, columns]
    assert np.array_equal(target, expected)


def test_get3_refuses_arrays_that_are_not_c_contiguous():
    with pytest.raises(TypingError, match="C-contiguous"):
        _rows_through(np.asfortranarray(np.ones((4, 3))), np.zeros((4, 3)),
                      np.zeros(1, np.int64), np.zeros(1, np.int64))


def test_bond_kernel_refuses_vector_arrays_without_three_columns():
    """get3 and put3 count three values per row: the kernel checks the columns first."""
    model, state = bench.lattice_system(3)
    sim, _ = bench.make_simulation(model, state)
    law = next(law for law in sim.laws if isinstance(law, cpu.ElasticBonds))
    before = state.position.copy()
    particles = cpu.particles(state)._replace(velocity=np.zeros((model.n_particles, 4)))
    with pytest.raises(ValueError, match="3 columns"):
        cpu.elastic_bonds(law._bonds, law._materials, law._bond_state(model, state), particles,
                          law._box, state.time, 1e-7, None, True, None, law._scratch,
                          law._slots, law._slow, law._pending, law.loads)
    assert np.array_equal(state.position, before)


def test_row3_and_store3_move_whole_rows():
    rng = np.random.default_rng(2)
    a = rng.random((12, 3))
    b = np.zeros((12, 3))

    @numba.njit
    def move(a, b, rows):
        for k in range(rows.shape[0]):
            x, y, z = raw.row3(a, rows[k])
            raw.store3(b, rows[k], (x, -y, 2.0 * z))

    rows = np.array([7, 0, 11, 3])
    move(a, b, rows)
    expected = np.zeros((12, 3))
    expected[rows] = a[rows] * np.array([1.0, -1.0, 2.0])
    assert np.array_equal(b, expected)


def _row(a, i):
    return (a[i, 0], a[i, 1], a[i, 2])


def _first_of_row(a, i):
    return _row(a, i)[0]


def test_given_functions_replace_bodies_for_their_callers():
    """compile_functions' given: the callers compiled after see the given function."""
    @numba.njit
    def shifted(a, i):
        return (a[i, 1], a[i, 2], a[i, 0])

    plain = compile_functions([_row, _first_of_row], numba.njit)
    swapped = compile_functions([_row, _first_of_row], numba.njit, given={"_row": shifted})
    a = np.arange(12.0).reshape(4, 3)
    assert plain._first_of_row(a, 2) == 6.0
    assert swapped._first_of_row(a, 2) == 7.0 and swapped._row is shifted


def test_the_cpu_loops_read_rows_unchecked():
    assert cpu.L.row3 is raw.row3 and cpu.L.store3 is raw.store3
