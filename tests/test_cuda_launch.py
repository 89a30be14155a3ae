"""The GPU backend's prepared launches (backends/cuda_device.py) against numba-cuda's own
marshalling, on a stand-in kernel: the parameters a prepared launch passes must be, item for
item, those the plain launch would build from the same arguments, and any change of an array
or of a scalar's type must fall back to the plain launch. (The real kernels run prepared on
a GPU only: numba's simulator has no parameters; the device cases of test_gpu_sim.py cover
them there with BONDEM_CUDA_PREPARED_LAUNCH=1.)"""
import gc

import numpy as np
import pytest

from bondem.backends import cuda_device
from bondem.backends.cuda_device import PreparedLaunch


class DeviceArray:
    """A device array as the launch path sees one: the CUDA array interface and a pointer."""
    __cuda_array_interface__ = {}

    def __init__(self, pointer, size=6):
        self.pointer, self.size = pointer, size


def kind(value):
    if isinstance(value, tuple):
        return tuple(kind(v) for v in value)
    return "array" if isinstance(value, (DeviceArray, np.ndarray)) else type(value).__name__


class Overload:
    """numba-cuda's _Kernel for this module's purpose: argument types and _prepare_args
    (an array is 5 parameters, a scalar one tagged with its type, as ctypes values are)."""

    def __init__(self, argument_types):
        self.argument_types = argument_types

    def _prepare_args(self, ty, value, stream, retr, params):
        if isinstance(ty, tuple):
            for t, v in zip(ty, value):
                self._prepare_args(t, v, stream, retr, params)
        elif ty == "array":
            if isinstance(value, np.ndarray):      # a host array: copied, written back
                retr.append(lambda: None)
                value = DeviceArray(-1, value.size)
            params.extend([0, 0, value.size, 8, value.pointer])
        else:
            params.append((ty, value))


class Kernel:
    """A dispatcher: compiled overloads by argument types, the plain launch recorded."""

    def __init__(self):
        self.overloads, self.plain = {}, []

    def typeof_pyval(self, value):
        return kind(value)

    def __getitem__(self, config):
        def plain(*args):
            types = tuple(kind(a) for a in args)
            self.overloads.setdefault(types, Overload(types))
            self.plain.append((config, args))
        return plain


def marshalled(kernel, args):
    """The parameters of the plain launch of ``args`` (what numba-cuda passes)."""
    overload = kernel.overloads[tuple(kind(a) for a in args)]
    params = []
    overload._prepare_args(tuple(kind(a) for a in args), args, 0, [], params)
    return params


class Raw:
    def __init__(self):
        self.calls = []

    def __call__(self, grid, params):
        self.calls.append((grid, params))


def arguments(time=0.5, musen=False):
    bonds = (DeviceArray(100), DeviceArray(200, 9))
    particles = (DeviceArray(300), (DeviceArray(400), 2.5e-3))   # nested, a scalar inside
    return [bonds, particles, time, 3, musen, DeviceArray(500)]


def prepared(args):
    kernel = Kernel()
    kernel[1, 128](*args)
    raw = Raw()
    return kernel, PreparedLaunch.build(kernel, args, raw), raw


def test_prepared_parameters_are_the_plain_launch_ones():
    """Same arrays, new scalar values: the parameters are those numba-cuda would build."""
    args = arguments()
    kernel, launch, raw = prepared(args)
    assert launch is not None
    # 5 arrays x 5 parameters and 4 scalars; the scalars' slots are left open
    assert len(launch.params) == 29 and launch.params.count(None) == 4
    later = list(args)
    later[2], later[4] = 0.75, True
    later[1] = (args[1][0], (args[1][1][0], 1e-3))       # new tuple, same arrays
    assert launch.launch(7, later)
    assert raw.calls == [(7, marshalled(kernel, later))]
    assert marshalled(kernel, later) != marshalled(kernel, args)


def test_changed_array_or_scalar_type_falls_back():
    args = arguments()
    _, launch, raw = prepared(args)
    replaced = list(args)
    replaced[5] = DeviceArray(500)                       # same pointer, another array object
    assert not launch.launch(1, replaced)
    nested = list(args)
    nested[1] = (args[1][0], (DeviceArray(400), 2.5e-3))
    assert not launch.launch(1, nested)
    retyped = list(args)
    retyped[2] = 1                                       # int for float: another overload
    assert not launch.launch(1, retyped)
    assert not launch.launch(1, args[:-1])               # a leaf fewer
    assert raw.calls == []
    assert launch.launch(1, args) and len(raw.calls) == 1


def test_freed_array_never_matches():
    """A prepared launch holds its arrays weakly: a finished simulation's arrays are freed,
    and a new array at the same Python id cannot take their parameters."""
    args = arguments()
    kernel, launch, raw = prepared(args)
    kernel.plain.clear()                                 # the plain launch's record
    del args[5]
    gc.collect()
    assert launch.arrays[-1][1]() is None
    fresh = DeviceArray(900)
    assert not launch.launch(1, args + [fresh]) and raw.calls == []


@pytest.mark.parametrize("leaf", [np.zeros(3), "text", None])
def test_host_arrays_and_other_leaves_are_not_prepared(leaf):
    args = arguments()
    args[5] = leaf
    kernel = Kernel()
    kernel[1, 128](*args)
    assert PreparedLaunch.build(kernel, args, Raw()) is None


def test_uncompiled_or_foreign_kernel_is_not_prepared():
    args = arguments()
    assert PreparedLaunch.build(Kernel(), args, Raw()) is None           # no overload
    assert PreparedLaunch.build(object(), args, Raw()) is None           # no internals


def test_launch_uses_the_prepared_form_and_gives_up_on_thrashing(monkeypatch):
    """launch(): plain first (it compiles), prepared from then on while the arrays stay;
    a kernel whose arrays change at most launches goes back to plain launches for good."""
    raw = Raw()
    monkeypatch.setattr(cuda_device, "PREPARED_LAUNCH", True)
    monkeypatch.setattr(cuda_device, "_raw_launch", lambda overload: raw)
    monkeypatch.setattr(cuda_device, "_prepared", {})
    steady, args = Kernel(), arguments()
    for step in range(10):
        cuda_device.launch(steady, 300, *args[:2], 0.1 * step, 3, False, args[5])
    assert len(steady.plain) == 1 and len(raw.calls) == 9
    assert [grid for grid, _ in raw.calls] == [cuda_device.blocks(300)] * 9
    assert cuda_device._prepared[steady].hits == 9

    thrashing = Kernel()
    for step in range(12):
        cuda_device.launch(thrashing, 10, *arguments())   # new arrays every launch
    assert len(thrashing.plain) == 12
    assert cuda_device._prepared[thrashing] is None       # given up after 4 builds
    calls = len(raw.calls)
    cuda_device.launch(thrashing, 10, *arguments())
    assert len(raw.calls) == calls and len(thrashing.plain) == 13

    # new arrays every second launch: one prepared launch per preparation is too few
    halves = Kernel()
    for step in range(12):
        if step % 2 == 0:
            args = arguments()
        cuda_device.launch(halves, 10, *args)
    assert cuda_device._prepared[halves] is None and len(halves.plain) == 8
    # every fourth: three per preparation are still too few
    fourths = Kernel()
    for step in range(24):
        if step % 4 == 0:
            args = arguments()
        cuda_device.launch(fourths, 10, *args)
    assert cuda_device._prepared[fourths] is None
    # every fifth: four per preparation are enough
    fifths = Kernel()
    for step in range(30):
        if step % 5 == 0:
            args = arguments()
        cuda_device.launch(fifths, 10, *args)
    assert cuda_device._prepared[fifths].hits == 24 and len(fifths.plain) == 6


def test_off_by_default_and_under_the_simulator(monkeypatch):
    """Unless asked for, every launch is numba-cuda's own."""
    monkeypatch.setattr(cuda_device, "_prepared", {})
    if cuda_device.PREPARED_LAUNCH:
        pytest.skip("BONDEM_CUDA_PREPARED_LAUNCH=1 here")
    kernel, args = Kernel(), arguments()
    for _ in range(3):
        cuda_device.launch(kernel, 5, *args)
    assert len(kernel.plain) == 3 and cuda_device._prepared == {}
