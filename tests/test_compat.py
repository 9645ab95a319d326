"""quatarray._compat: the shims for the oldest numpy, pyarrow and scipy give what the
newer calls give (each old path forced here, and compared with the new one where
this environment has it)."""

import numpy as np
import pyarrow as pa
import pytest

from quatarray import _compat


def test_reshape_view_is_a_view_or_an_error(monkeypatch):
    a = np.arange(12.0).reshape(2, 6)
    for new in (True, False):
        monkeypatch.setattr(_compat, "_RESHAPE_COPY", new and _compat._RESHAPE_COPY)
        v = _compat.reshape_view(a, (3, 4))
        assert np.shares_memory(v, a) and v.shape == (3, 4)
        np.testing.assert_array_equal(v, a.reshape(3, 4))
        with pytest.raises(ValueError):
            _compat.reshape_view(a.T, (12,))


TABLE = pa.table({"t": [0.5, 1.0], "name with space": ["a b", "c"], "w": [1.0, -0.25]})


@pytest.mark.parametrize("include_header", [True, False])
def test_csv_header_written_by_hand_is_pyarrows(tmp_path, monkeypatch, include_header):
    """Before pyarrow 22 the header line is written by hand: the same bytes as
    ``quoting_header="none"`` (compared where this pyarrow has it)."""
    monkeypatch.setattr(_compat, "_QUOTING_HEADER", [])
    has_native = not _compat.csv_write_options(include_header=True)[1]
    outs = {}
    for native in (True, False) if has_native else (False,):
        monkeypatch.setattr(_compat, "_QUOTING_HEADER", [] if native else [False])
        path = tmp_path / f"{native}.csv"
        _compat.write_csv(TABLE, str(path), include_header=include_header, quoting_style="none")
        outs[native] = path.read_bytes()
    head = b"t,name with space,w\n" if include_header else b""
    assert outs[False] == head + b"0.5,a b,1\n1,c,-0.25\n"
    if has_native:
        assert outs[True] == outs[False]


def test_csv_write_options_stream(tmp_path, monkeypatch):
    import pyarrow.csv as pcsv

    monkeypatch.setattr(_compat, "_QUOTING_HEADER", [False])
    opts, by_hand = _compat.csv_write_options(include_header=True, delimiter=";", quoting_style="none")
    assert by_hand
    with open(tmp_path / "s.csv", "wb") as f:
        f.write(_compat.header_line(TABLE.schema.names, ";"))
        with pcsv.CSVWriter(f, TABLE.schema, write_options=opts) as w:
            w.write_table(TABLE)
    assert (tmp_path / "s.csv").read_bytes() == b"t;name with space;w\n0.5;a b;1\n1;c;-0.25\n"


def test_scipy_rotation_in_wxyz(monkeypatch):
    rng = np.random.default_rng(1)
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    v = rng.normal(size=3)
    got = []
    for new in (True, False):
        monkeypatch.setattr(_compat, "_SCALAR_FIRST", [] if new else [False])
        r = _compat.rotation_from_wxyz(q)
        got.append((r.apply(v), _compat.rotation_as_wxyz(r)))
        # (w, x, y, z) -> scipy's (x, y, z, w): the rotation of v about z by the angle of q
        np.testing.assert_allclose(r.as_quat(), np.roll(q, -1, axis=1), atol=1e-15)
    np.testing.assert_array_equal(got[0][0], got[1][0])
    np.testing.assert_array_equal(got[0][1], got[1][1])
