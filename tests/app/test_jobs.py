"""quatarray.jobs: what a convert or resample job is, shared by the command line and
the Dask file jobs (the jobs end to end are tested through both, in test_cli.py and
test_dask_files.py)."""

import io

import numpy as np
import pytest

import quatarray as qa
from quatarray import jobs
from quatarray.io import DataError, UsageError


@pytest.mark.parametrize("to", ["quat", "xyzw", "matrix", "rotvec", "axis-angle", "euler:ZXY", "euler:xyz"])
def test_target_writes_into_out_what_it_returns(to):
    q = qa.normalize(qa.random(50, rng=1))
    fields, core, fn = jobs.target(to, degrees=False)
    ref = fn(q)
    assert ref.shape == (50,) + core and len(fields) == int(np.prod(core))
    out = np.empty((50,) + core)
    assert fn(q, out=out) is out
    assert np.array_equal(out, ref)


def test_target_refusals_name_the_option():
    with pytest.raises(UsageError, match="--degrees applies to rotvec, axis-angle and euler outputs, not matrix"):
        jobs.target("matrix", degrees=True)
    with pytest.raises(UsageError, match="--to polar: expected one of quat, xyzw"):
        jobs.target("polar", degrees=False)
    with pytest.raises(UsageError, match="--to euler:ZZX: SEQ is three axes"):
        jobs.target("euler:ZZX", degrees=False)


def test_gimbal_lock_counted_and_noted():
    _, _, fn = jobs.target("euler:ZYX", degrees=False)
    fn(qa.from_euler("ZYX", [[0.3, np.pi / 2, 0.1], [0.3, np.pi / 2, 0.2], [0.1, 0.2, 0.3]]))
    err = io.StringIO()
    jobs.gimbal_note("walk.npy", fn.locked, err)
    assert err.getvalue() == ("walk.npy: gimbal lock in 2 rows: the third angle was set to 0 there "
                              "(as scipy does)\n")
    err = io.StringIO()
    jobs.gimbal_note("walk.npy", 0, err)
    assert err.getvalue() == ""


@pytest.mark.parametrize("closed", [False, True])
def test_rate_times_in_pieces(closed):
    newt = jobs.new_times(rate=4.0)
    newt.t0 = 1.0
    assert newt.count(2.0, closed) == 4 + closed
    got = np.concatenate(list(newt.pieces(2.0, closed, size=3)))
    assert np.array_equal(got, 1.0 + np.arange(4 + closed) / 4.0)
    assert newt.count(2.0, closed) == 0  # handed out: nothing left up to 2.0


def test_rate_times_refusals():
    with pytest.raises(UsageError, match="--rate must be a positive number, got -1"):
        jobs.RateTimes(-1)
    newt = jobs.RateTimes(1e9)
    newt.t0 = 1.3e9
    with pytest.raises(UsageError, match="finer than the time resolution"):
        newt.count(1.3e9 + 1, True)


def test_file_times_inside_the_keys(tmp_path):
    np.save(tmp_path / "t.npy", np.array([0.5, 1.0, 2.5]))
    newt = jobs.new_times(times=str(tmp_path / "t.npy"))
    newt.t0 = 0.0
    assert np.array_equal(newt.upto(2.0, True), [0.5, 1.0])
    with pytest.raises(DataError, match=r"t\.npy: row 2: time 2\.5 is after the last key time 2\.0"):
        newt.finish(2.0)
    early = jobs.FileTimes(str(tmp_path / "t.npy"))
    early.t0 = 0.75
    with pytest.raises(DataError, match=r"row 0: time 0\.5 is before the first key time 0\.75"):
        early.count(2.0, True)


def test_new_times_needs_one_source():
    with pytest.raises(UsageError, match="exactly one of --rate and --times"):
        jobs.new_times()
    with pytest.raises(UsageError, match="exactly one of --rate and --times"):
        jobs.new_times(rate=2.0, times="t.npy")


def test_check_key_times():
    with pytest.raises(UsageError, match=r"^q\.npy: has no time column; give its sampling rate with --in-rate HZ "
                                         r"or its times with --in-times FILE$"):
        jobs.check_key_times("q.npy", False)
    with pytest.raises(UsageError, match=r"--in-rate HZ$"):  # a job without --in-times (--scheduler)
        jobs.check_key_times("q.npy", False, in_times_option=False)
    with pytest.raises(UsageError, match="--in-rate must be positive, got 0"):
        jobs.check_key_times("q.npy", False, in_rate=0)
    err = io.StringIO()
    jobs.check_key_times("s.csv", True, in_rate=100.0, err=err)
    assert err.getvalue() == "s.csv: has a time column; --in-rate ignored\n"
    jobs.check_key_times("s.csv", True, in_times="t.txt")  # no `err`: nothing said
