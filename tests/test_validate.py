"""The front end on its own: the only guard in front of the unchecked row accessors."""

import numpy as np
import pytest

from quatarray import _validate as V


def _copy_kernel(a, out):  # a plain-Python row kernel: out = a
    out[...] = a


def _add_kernel(a, b, out):
    out[...] = a + b


def _scale_kernel(a, t, out):
    out[...] = a * t[:, None]


class _Sub(np.ndarray):
    pass


class TestAsFloat:
    @pytest.mark.parametrize("dtype, expect", [
        (np.float32, np.float32), (np.float64, np.float64), (np.float16, np.float32),
        (">f4", np.float32), (">f8", np.float64), (np.int64, np.float64), (np.uint8, np.float64),
        (bool, np.float64), (np.longdouble, np.float64),
    ])
    def test_dtype_rules(self, dtype, expect):
        a = V.as_float(np.ones(3, dtype), "q")
        assert a.dtype == expect and a.dtype.isnative

    def test_no_copy_for_native_floats(self):
        a = np.ones((2, 4))
        assert V.as_float(a, "q") is a
        m = np.ones((2, 4)).view(_Sub)
        assert type(V.as_float(m, "q")) is np.ndarray and np.shares_memory(V.as_float(m, "q"), m)

    @pytest.mark.parametrize("bad", [np.ones(3, complex), np.array(["a"]), np.array([object()]), [1, "x"]])
    def test_refused_dtypes_name_the_argument(self, bad):
        with pytest.raises(TypeError, match="`q`"):
            V.as_float(bad, "q")

    def test_masked_refused(self):
        with pytest.raises(TypeError, match="masked array"):
            V.as_float(np.ma.masked_array([1.0, 2.0]), "v")

    def test_lists_become_float64_and_dtype_forces(self):
        assert V.as_float([1, 2], "t").dtype == np.float64
        assert V.as_float([1, 2], "t", dtype=np.float32).dtype == np.float32


class TestShapes:
    def test_check_core_message(self):
        with pytest.raises(ValueError, match=r"^Expected `q` to have shape \(\.\.\., 4\), got \(10, 3\)\.$"):
            V.check_core(np.zeros((10, 3)), "q", (4,))
        a = np.zeros((2, 3, 3))
        assert V.check_core(a, "m", (3, 3)) is a
        with pytest.raises(ValueError, match=r"\(\.\.\., 3, 3\)"):
            V.check_core(np.zeros(3), "m", (3, 3))

    def test_leading_broadcast_and_its_error(self):
        a, b = np.zeros((5, 1, 4)), np.zeros((3, 4))
        assert V.leading([a, b], [(4,), (4,)], ["p", "q"]) == (5, 3)
        with pytest.raises(ValueError, match=r"`p` \(2, 4\) and `q` \(3, 4\)"):
            V.leading([np.zeros((2, 4)), np.zeros((3, 4))], [(4,), (4,)], ["p", "q"])

    def test_flatten_views(self):
        a = np.arange(24.0).reshape(2, 3, 4)
        f = V.flatten(a, (2, 3), (4,))
        assert f.shape == (6, 4) and np.shares_memory(f, a)
        b = V.flatten(np.arange(4.0), (3,), (4,))
        assert b.shape == (3, 4) and b.strides[0] == 0

    @pytest.mark.parametrize("shape, expect", [(3, (3,)), ((2, 3), (2, 3)), (np.int64(4), (4,)), ((), ())])
    def test_leading_shape(self, shape, expect):
        assert V.leading_shape(shape, "n") == expect

    @pytest.mark.parametrize("bad, exc", [(-1, ValueError), (2.5, TypeError), (True, TypeError), ("3", TypeError)])
    def test_leading_shape_refused(self, bad, exc):
        with pytest.raises(exc, match="`n`"):
            V.leading_shape(bad, "n")


class TestWhere:
    def test_row_index_and_single(self):
        assert V.where(3, (10,)) == "row 3"
        assert V.where(5, (2, 3)) == "index (1, 2)"
        assert V.where(0, ()) == "the single input"

    def test_origin_counts_in_the_whole_array(self):
        with V.origin((100,)):
            assert V.where(3, (10,)) == "row 103"
        assert V.where(3, (10,)) == "row 3"


class TestOut:
    def test_check_out(self):
        out = np.empty((2, 4))
        assert V.check_out(out, (2, 4), np.float64) is out
        with pytest.raises(ValueError, match=r"shape \(2, 4\) and dtype float32"):
            V.check_out(out, (2, 4), np.float32)
        with pytest.raises(ValueError, match="numpy array"):
            V.check_out([[0.0] * 4] * 2, (2, 4), np.float64)
        ro = np.empty((2, 4))
        ro.flags.writeable = False
        with pytest.raises(ValueError, match="read-only"):
            V.check_out(ro, (2, 4), np.float64)


class TestElementwise:
    def test_dtype_rule_and_weak_scalars(self):
        a32 = np.ones((3, 4), np.float32)
        r = V.elementwise(_add_kernel, [(a32, "p", (4,)), (a32, "q", (4,))], [(4,)])
        assert r.dtype == np.float32
        r = V.elementwise(_scale_kernel, [(a32, "p", (4,)), (0.5, "t", ())], [(4,)])
        assert r.dtype == np.float32  # a Python scalar never upcasts
        r = V.elementwise(_add_kernel, [(a32, "p", (4,)), (np.ones(4), "q", (4,))], [(4,)])
        assert r.dtype == np.float64

    def test_shapes_and_scalars(self):
        r = V.elementwise(_copy_kernel, [(np.arange(4.0), "q", (4,))], [(4,)])
        assert r.shape == (4,)
        r = V.elementwise(_copy_kernel, [(np.zeros((2, 3, 4)), "q", (4,))], [(4,)])
        assert r.shape == (2, 3, 4)
        with pytest.raises(ValueError, match="`q`"):
            V.elementwise(_copy_kernel, [(np.zeros((2, 3)), "q", (4,))], [(4,)])

    def test_out_aliasing_input_and_overlap(self):
        a = np.arange(12.0).reshape(3, 4)
        res = V.elementwise(_add_kernel, [(a, "p", (4,)), (a, "q", (4,))], [(4,)], out=a)
        assert res is a and np.array_equal(a, 2 * np.arange(12.0).reshape(3, 4))
        # an input that only overlaps `out` is copied first
        b = np.arange(20.0)
        src, dst = b[:12].reshape(3, 4), b[4:16].reshape(3, 4)
        expect = src.copy()
        V.elementwise(_copy_kernel, [(src, "q", (4,))], [(4,)], out=dst)
        assert np.array_equal(dst, expect)

    def test_out_subclass_filled_through_its_ndarray_view(self):
        out = np.zeros((2, 4)).view(_Sub)
        res = V.elementwise(_copy_kernel, [(np.ones((2, 4)), "q", (4,))], [(4,)], out=out)
        assert res is out and np.all(out == 1)

    def test_out_only_for_single_results(self):
        with pytest.raises(ValueError, match="single result"):
            V.elementwise(_copy_kernel, [(np.ones(4), "q", (4,))], [(4,), (3,)], out=np.empty(4))


class TestTimes:
    def test_key_times(self):
        t = V.key_times([0.0, 1.0, 2.0], k=3)
        assert t.shape == (3,)
        with pytest.raises(ValueError, match=r"times\[2\] = 1\.0 after times\[1\] = 1\.0"):
            V.key_times([0.0, 1.0, 1.0])
        with pytest.raises(ValueError, match=r"shape \(4,\)"):
            V.key_times([0.0, 1.0, 2.0], k=4)
        with pytest.raises(TypeError, match="real dtype"):
            V.key_times(np.array(["a", "b"]))

    def test_nan_is_not_increasing(self):
        assert V.first_not_increasing(np.array([0.0, np.nan, 2.0])) == 0

    def test_key_array(self):
        assert V.key_array(np.zeros((2, 4))).shape == (2, 4)
        with pytest.raises(ValueError, match="at least 2 keys"):
            V.key_array(np.zeros((1, 4)))
        with pytest.raises(ValueError, match=r"\(K, 4\)"):
            V.key_array(np.zeros((2, 2, 4)))

    @pytest.mark.parametrize("bad", [3, 1.0, True, -1, "1"])
    def test_spline_order(self, bad):
        with pytest.raises(ValueError, match="`order`"):
            V.spline_order(bad)
        assert V.spline_order(np.int64(2)) == 2

    def test_as_times_keeps_integers(self):
        assert V.as_times(np.array([1, 2], np.int64), "t").dtype == np.int64
        with pytest.raises(TypeError, match="`t`"):
            V.as_times(np.array([True]), "t")
