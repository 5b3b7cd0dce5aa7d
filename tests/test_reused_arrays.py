"""A solver's large result arrays are handed out again once nothing holds them, never while
anything does (kinegen.runtime.buffers): repeated solves touch no fresh pages and change no value."""

from __future__ import annotations

import gc
import sys
import threading

import numpy as np
from conftest import generated_system

from kinegen.runtime import Solver, SolverOptions, buffers
from kinegen.runtime.buffers import Reusable


def test_an_array_is_handed_out_again_only_once_nothing_else_holds_it():
    arrays = Reusable()
    first = arrays.empty((50, 7))
    address = first.ctypes.data
    view = first[3:9, ::2]  # a view holds its base
    del first
    second = arrays.empty((50, 7))
    assert second.ctypes.data != address  # the view still holds the first
    assert not np.shares_memory(second, view)
    del view
    third = arrays.empty((50, 7))
    assert third.ctypes.data == address  # nothing held the first: it comes back
    assert arrays.empty((50, 7)).ctypes.data not in (address, second.ctypes.data)  # both held: a new one
    assert arrays.empty((7, 50)).shape == (7, 50) and arrays.empty((50, 7), int).dtype == np.dtype(int)


def test_what_is_kept_stays_within_its_bound_and_the_oldest_goes_first(monkeypatch):
    monkeypatch.setattr(buffers, "KEPT_BYTES", 3 * 800)
    arrays = Reusable()
    held = [arrays.empty((100,)) for _ in range(5)]  # all five in use: three kept, the first two let go
    addresses = [a.ctypes.data for a in held]
    assert sum(a.nbytes for a in arrays._kept) <= buffers.KEPT_BYTES
    big = arrays.empty((1000,))  # larger than the bound: made, never kept
    assert all(a is not big for a in arrays._kept)
    del held, big
    assert arrays.empty((100,)).ctypes.data in addresses[2:]  # one of the three kept, now free


def test_repeated_solves_reuse_a_dropped_results_memory_never_a_held_ones_and_give_the_same_bits():
    system = generated_system("boom_quaternion", compiled=True)
    solver = Solver(system, SolverOptions(compiled=True))
    fresh = Solver(system, SolverOptions(compiled=True)).solve()
    first = solver.solve()
    second = solver.solve()  # the first is held: the second has memory of its own
    assert not np.shares_memory(first.q, second.q) and not np.shares_memory(first.inputs, second.inputs)
    for results in (first, second):
        for name in ("q", "v", "a", "inputs", "iterations", "residuals"):
            np.testing.assert_array_equal(getattr(results, name), getattr(fresh, name))
    address = first.q.ctypes.data
    del first
    gc.collect()
    third = solver.solve()
    assert third.q.ctypes.data == address  # the dropped first's arrays, reused
    for name in ("q", "v", "a", "inputs"):
        np.testing.assert_array_equal(getattr(third, name), getattr(fresh, name))
        np.testing.assert_array_equal(getattr(second, name), getattr(fresh, name))  # untouched by the third solve


def test_threads_sharing_one_never_get_the_same_array_at_once():
    arrays = Reusable()
    taken: list[list[bool]] = [[] for _ in range(4)]
    start = threading.Barrier(4)

    def take(k: int) -> None:
        start.wait()
        for _ in range(300):
            held = [arrays.empty((64,)) for _ in range(3)]  # held together
            for a in held:
                a.fill(k)
            # three distinct arrays, and no other thread wrote into them meanwhile
            taken[k].append(len({a.ctypes.data for a in held}) == 3 and all((a == k).all() for a in held))

    threads = [threading.Thread(target=take, args=(k,)) for k in range(4)]
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # threads switch every few bytecodes: a race would show
    try:
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    finally:
        sys.setswitchinterval(interval)
    assert all(len(flags) == 300 and all(flags) for flags in taken)
