"""quatarray on Dask arrays: the top-level names, lazily, block by block.

For streams that no longer fit one machine's memory or time. Every function
here has the name and the arguments of its in-memory twin in :mod:`quatarray`
and takes Dask arrays chunked along the leading axes (the quaternion axis —
4, 3 or 3×3 — in one chunk; other chunkings are rechunked). Nothing is
computed until you call ``.compute()``, ``dask.compute`` or store the result.

Element-wise functions
    ``multiply``, ``conjugate``, ``inverse``, ``normalize``, ``norm``, ``dot``,
    ``exp``, ``log``, ``power``, ``canonical``, ``angle``, ``distance``,
    ``rotate``, every conversion (``as_matrix`` … ``from_su2``, ``as_euler``,
    ``from_euler``), ``lerp``, ``nlerp``, ``slerp``, ``double``, ``bisect``,
    ``bezier``: one task per block, calling the very same numba kernel as the
    in-memory function on that block, so the result is bitwise the in-memory
    one. Leading dimensions broadcast as in numpy (numpy arrays and Python
    scalars mix freely with Dask arrays); there is no ``out=``.
Scans and neighbours (exact whatever the chunking)
    ``cumprod`` (blocked scan: each chunk's running product, then each
    chunk's total carried across the borders), ``unflip`` (flip within
    chunks, then carry the sign across borders), ``integrate_angular_velocity``
    (each block from the identity, then the orientation carried block to
    block), ``angular_velocity`` and
    ``spline`` (each block sees the neighbouring keys across its borders;
    the key times and new times may be Dask arrays too, kept on the workers).
Batches and reductions
    ``align_vectors`` (problems chunked along the leading axes, each solved by
    the in-memory kernel: bitwise the in-memory result) and ``mean`` (each
    block's 4×4 sums Σ w q qᵀ/|q|², added across chunks, then one eigenvector
    per result: the in-memory mean to the order of the sums, within 1e-13 rad).
Files
    :func:`convert_file` and :func:`resample_file` stream ``.npy`` (and, with
    ``zarr`` installed, ``.zarr``) files through a scheduler: threads, a local
    cluster of worker processes, or a distributed scheduler's address. They
    back ``quatarray convert/resample --scheduler``.

Kernels run single-threaded inside a task (the scheduler supplies the
parallelism), and all task functions live in importable modules, so graphs
travel to worker processes by reference.

Modules
    :mod:`quatarray.dask.arrays` (element-wise factory, scans),
    :mod:`quatarray.dask.windows` (``spline``, ``angular_velocity``: rows
    across chunk borders) and :mod:`quatarray.dask.files` (the file jobs and
    the cluster set-up); this package re-exports their public names.

Examples
--------
>>> import dask.array as da, numpy as np, quatarray as qa, quatarray.dask as qd
>>> q = qa.random(1000, rng=1)
>>> lazy = qd.as_rotvec(da.from_array(q, chunks=(300, 4)))
>>> lazy.chunks
((300, 300, 300, 100), (3,))
>>> bool(np.array_equal(lazy.compute(), qa.as_rotvec(q)))
True
"""

try:
    import dask  # noqa: F401
    import dask.array  # noqa: F401
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ImportError(
        "quatarray.dask needs Dask; install the optional extra: pip install 'quatarray[dask]'"
    ) from exc

from . import arrays, files, windows
from .arrays import *  # noqa: F401,F403 - the element-wise twins, as_dask and the scans
from .files import convert_file, local_cluster, resample_file, scheduler_options
from .windows import angular_velocity, spline

__all__ = sorted(arrays.__all__ + windows.__all__ + files.__all__)
