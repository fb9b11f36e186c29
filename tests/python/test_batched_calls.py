"""Per-call dynamics with a leading batch axis and ``out=``: a batch equals its rows called one
by one, bit for bit; shared 1-D arguments broadcast; ``out`` is written and returned; bad shapes
and bad rows name themselves."""

from __future__ import annotations

import numpy as np
import pytest

import orbitflex
from orbitflex import ModelError

B = 9


@pytest.fixture(scope="module")
def robot():
    return orbitflex.models.space_arm()


@pytest.fixture(scope="module")
def rows(robot):
    rng = np.random.default_rng(11)
    n = robot.dof
    return dict(q=rng.uniform(-2, 2, (B, n)), base_twist=rng.normal(size=(B, 6)), qd=rng.normal(size=(B, n)),
                tau=rng.normal(size=(B, n)), base_wrench=rng.normal(size=(B, 6)), ee_wrench=rng.normal(size=(B, 6)),
                base_acc=rng.normal(size=(B, 6)), qdd=rng.normal(size=(B, n)))


CALLS = {
    "forward_dynamics": ("q", "base_twist", "qd", "tau", "base_wrench", "ee_wrench"),
    "inverse_dynamics": ("q", "base_twist", "qd", "base_acc", "qdd", "ee_wrench"),
    "bias_forces": ("q", "base_twist", "qd"),
    "mass_matrix": ("q",),
}


@pytest.mark.parametrize("name", CALLS)
@pytest.mark.parametrize("method", ["recursive", "operator"])
def test_batch_equals_rows_one_by_one(robot, rows, name, method):
    f = getattr(robot, name)
    args = [rows[a] for a in CALLS[name]]
    batch = f(*args, method=method)
    assert batch.shape[0] == B
    for b in range(B):
        one = f(*[a[b] for a in args], method=method)
        np.testing.assert_array_equal(batch[b], one)


@pytest.mark.parametrize("name", ["forward_dynamics", "inverse_dynamics", "bias_forces"])
def test_one_dimensional_arguments_are_shared_by_every_row(robot, rows, name):
    f = getattr(robot, name)
    names = CALLS[name]
    for shared in names[1:]:
        args = [rows[a][0] if a == shared else rows[a] for a in names]
        batch = f(*args)
        for b in (0, 4, B - 1):
            np.testing.assert_array_equal(batch[b], f(*[a if a.ndim == 1 else a[b] for a in args]))


def test_list_of_lists_and_a_single_row(robot, rows):
    q = rows["q"][:2]
    np.testing.assert_array_equal(robot.mass_matrix(q.tolist()), robot.mass_matrix(q))
    one = robot.mass_matrix(q[:1])
    assert one.shape == (1, 13, 13)
    np.testing.assert_array_equal(one[0], robot.mass_matrix(q[0]))
    empty = robot.mass_matrix(np.zeros((0, 7)))
    assert empty.shape == (0, 13, 13)


def test_out_is_written_and_returned(robot, rows):
    out = np.full((B, 13), np.nan)
    got = robot.forward_dynamics(rows["q"], rows["base_twist"], rows["qd"], rows["tau"], out=out)
    assert got is out
    np.testing.assert_array_equal(out, robot.forward_dynamics(rows["q"], rows["base_twist"], rows["qd"], rows["tau"]))
    single = np.full(13, np.nan)
    got = robot.inverse_dynamics(rows["q"][0], rows["base_twist"][0], rows["qd"][0], rows["base_acc"][0],
                                 rows["qdd"][0], out=single)
    assert got is single
    np.testing.assert_array_equal(single, robot.inverse_dynamics(rows["q"][0], rows["base_twist"][0], rows["qd"][0],
                                                                 rows["base_acc"][0], rows["qdd"][0]))
    m = np.empty((13, 13))
    assert robot.mass_matrix(rows["q"][1], out=m) is m
    np.testing.assert_array_equal(m, robot.mass_matrix(rows["q"][1]))
    c = np.empty((B, 13))
    assert robot.bias_forces(rows["q"], rows["base_twist"], rows["qd"], out=c) is c
    np.testing.assert_array_equal(c[3], robot.bias_forces(rows["q"][3], rows["base_twist"][3], rows["qd"][3]))


@pytest.mark.parametrize("out,message", [
    (np.empty((B, 12)), r"out: expected shape \(9, 13\), given shape \(9, 12\)"),
    (np.empty((B, 13), dtype=np.float32), r"out: expected a float64 numpy array of shape \(9, 13\), given ndarray"),
    (np.empty((13, B)).T, r"out: expected a C-contiguous, aligned, writeable array"),
    ([0.0] * 13, r"out: expected a float64 numpy array of shape \(9, 13\), given list"),
])
def test_bad_out_is_refused(robot, rows, out, message):
    with pytest.raises(ModelError, match=message):
        robot.bias_forces(rows["q"], rows["base_twist"], rows["qd"], out=out)
    readonly = np.empty(13)
    readonly.flags.writeable = False
    with pytest.raises(ModelError, match=r"out: expected a C-contiguous, aligned, writeable array"):
        robot.bias_forces(rows["q"][0], rows["base_twist"][0], rows["qd"][0], out=readonly)


def misaligned(shape):
    """A C-contiguous float64 array whose data starts one byte off an 8-byte boundary."""
    raw = np.zeros(int(np.prod(shape)) * 8 + 8, dtype=np.uint8)
    start = 1 if raw.ctypes.data % 8 == 0 else 9 - raw.ctypes.data % 8
    a = raw[start:start + int(np.prod(shape)) * 8].view(np.float64).reshape(shape)
    assert not a.flags.aligned and a.flags.c_contiguous
    return a


def test_misaligned_arrays_are_read_safely_and_refused_as_out(robot, rows):
    q = misaligned((B, 7))
    q[...] = rows["q"]
    np.testing.assert_array_equal(robot.mass_matrix(q), robot.mass_matrix(rows["q"]))
    q1 = misaligned((7,))
    q1[...] = rows["q"][0]
    np.testing.assert_array_equal(robot.mass_matrix(q1), robot.mass_matrix(rows["q"][0]))
    with pytest.raises(ModelError, match=r"out: expected a C-contiguous, aligned, writeable array"):
        robot.bias_forces(rows["q"], rows["base_twist"], rows["qd"], out=misaligned((B, 13)))


def test_an_input_given_as_out_too(robot, rows):
    """The arguments are read before the result is written."""
    buf = np.zeros((B, 13))
    buf[:, :7] = rows["q"]
    expected = robot.bias_forces(buf[:, :7].copy(), rows["base_twist"], rows["qd"])
    q_view = buf[:, :7].copy()
    robot.bias_forces(q_view, rows["base_twist"], rows["qd"], out=buf)
    np.testing.assert_array_equal(buf, expected)


def test_bad_rows_and_shapes_name_themselves(robot, rows):
    q = rows["q"].copy()
    q[5, 2] = np.nan
    with pytest.raises(ModelError, match=r"^q \(row 5\): element 2 is not finite \(NaN\)"):
        robot.forward_dynamics(q, rows["base_twist"], rows["qd"], rows["tau"])
    with pytest.raises(ModelError, match=r"^qd: expected 9 rows \(as q\) or one vector for every row, given shape \(8, 7\)"):
        robot.bias_forces(rows["q"], rows["base_twist"], rows["qd"][:8])
    with pytest.raises(ModelError, match=r"^tau: expected shape \(7,\) or \(9, 7\), given shape \(9, 6\)"):
        robot.forward_dynamics(rows["q"], rows["base_twist"], rows["qd"], rows["tau"][:, :6])
    with pytest.raises(ModelError, match=r"^q: expected shape \(7,\) or \(1, 7\), given shape \(1, 1, 7\)"):
        robot.mass_matrix(rows["q"][None, :1])
