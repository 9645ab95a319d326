"""Reading and writing rotation streams, chunk by chunk.

Kept apart from the command line (:mod:`quatarray.app.cli`) so the readers and
writers can be used on their own::

    from quatarray import io
    reader = io.open_stream("walk.bvh")            # format from extension/header
    with io.open_writer("walk.csv", ["qw", "qx", "qy", "qz"], time=True, pos=True) as w:
        for chunk in reader:
            w.write(chunk.data, chunk.t, chunk.pos)

Formats: npy (memory-mapped, one chunk mapped at a time), csv with named
columns, TUM, EuRoC, KITTI poses, parquet (via pyarrow) and BVH; whole BVH clips (every joint) with
:func:`read_bvh` and :func:`write_bvh`.

Modules: ``readers`` (:func:`open_stream`, :func:`read_times`) over
``arrays`` (npy, zarr), ``text`` (csv, TUM, EuRoC, KITTI, parquet) and
``bvh`` (one joint, or whole clips); ``streams`` (:class:`Chunk`, the
``Reader`` base, chunk iterators re-cut, timed or paired); ``clean`` (row
checks); ``writers`` (stream outputs) and ``targets`` (block-by-block
outputs of the Dask file jobs); ``formats`` and ``errors``.
"""

from .bvh import read_bvh, sample_path, write_bvh
from .clean import Cleaner
from .errors import DataError, OutputError, UsageError
from .formats import FORMATS, output_format
from .readers import DEFAULT_CHUNK, open_stream, read_times
from .streams import Chunk, concat, rechunk
from .writers import Writer, check_output, open_writer, output_mode

__all__ = [
    "Chunk", "Cleaner", "DataError", "OutputError", "UsageError", "Writer", "FORMATS", "DEFAULT_CHUNK",
    "open_stream", "read_times", "read_bvh", "write_bvh", "sample_path", "open_writer", "check_output", "output_mode",
    "output_format", "concat", "rechunk",
]
