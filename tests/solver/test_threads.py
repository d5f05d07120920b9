"""Tests of solver/threads.py: a solve's products on one BLAS thread, this thread's count given back after."""

import threading

import numpy as np
import pytest

from solver import SensorGrid, loads
from solver.inverse import DenseSolver
from solver.threads import local_libraries, one_blas_thread


def counts():
    # this thread's count in each library (reading it means setting it: set it back at once)
    setters = local_libraries()
    seen = [setter(1) for setter in setters]
    for setter, count in zip(setters, seen, strict=True):
        setter(count)
    return seen


@pytest.fixture
def two_threads():
    # two BLAS threads for this thread around each test, whatever it had
    setters = local_libraries()
    assert setters, "numpy's and scipy's OpenBLAS have per-thread counts (0.3.27 and later)"
    before = [setter(2) for setter in setters]
    yield
    for setter, count in zip(setters, before, strict=True):
        setter(count)


def test_one_thread_inside_and_the_count_given_back(two_threads):
    with one_blas_thread():
        assert set(counts()) == {1}
        with one_blas_thread():
            assert set(counts()) == {1}
        assert set(counts()) == {1}  # the outer block's count is still the block's
    assert set(counts()) == {2}
    with pytest.raises(RuntimeError, match="inside"):
        with one_blas_thread():
            raise RuntimeError("inside")
    assert set(counts()) == {2}


def test_other_threads_keep_their_count(two_threads):
    inside, done, errors, seen = threading.Event(), threading.Event(), [], []

    def other():
        try:
            inside.wait(5)
            before = [setter(3) for setter in local_libraries()]
            seen.append(counts())
            for setter, count in zip(local_libraries(), before, strict=True):
                setter(count)
        except BaseException as error:  # pragma: no cover - reported below
            errors.append(error)
        finally:
            done.set()

    thread = threading.Thread(target=other)
    thread.start()
    with one_blas_thread():
        inside.set()
        done.wait(5)
        assert set(counts()) == {1}  # the other thread's 3 did not reach this one
    thread.join(5)
    assert not errors and seen and set(seen[0]) == {3}  # nor this block's 1 that one


def test_a_solve_runs_its_products_on_one_thread(two_threads, monkeypatch):
    grid = SensorGrid.regular(10, 10, 1.5e-3, 1.5e-3)
    r = DenseSolver(grid)
    frame = loads.simulate(grid, loads.hertz((0.0, 0.0), 3e-3, 1.0, shear_ratio=0.2))
    during = []
    choose = r.efficiency.choose

    def watched(*args, **kwargs):
        during.append(set(counts()))
        return choose(*args, **kwargs)
    monkeypatch.setattr(r.efficiency, "choose", watched)
    r.solve(frame.stress)
    r.solve(np.asarray(frame.stress) * 1.01, shear_ratio=0.1, shear_direction=0.0)
    assert during == [{1}, {1}]
    assert set(counts()) == {2}
